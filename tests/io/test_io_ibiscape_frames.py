"""CARLA left-handed -> our right-handed frame, with files built like the IBISCape scripts."""

from __future__ import annotations

import numpy as np

from ibiscape_eval.core.rotations import matrix_from_quat
from ibiscape_eval.io import read_ibiscape_groundtruth
from ibiscape_eval.io.ibiscape import IBISCAPE_HEADER


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def carla_matrix(yaw, pitch, roll):
    """CARLA's Transform.get_matrix() rotation block (angles in radians)."""
    cy, sy, cp, sp, cr, sr = (np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch),
                              np.cos(roll), np.sin(roll))
    return np.array([[cp * cy, cy * sp * sr - sy * cr, -(cy * sp * cr + sy * sr)],
                     [sy * cp, sy * sp * sr + cy * cr, cy * sr - sy * sp * cr],
                     [sp, -cp * sr, cp * cr]])


def scripts_quaternion(yaw, pitch, roll):
    """The acquisition scripts' euler_to_quaternion(yaw, pitch, roll) -> (w, x, y, z)."""
    qx = (np.sin(roll / 2) * np.cos(pitch / 2) * np.cos(yaw / 2)
          - np.cos(roll / 2) * np.sin(pitch / 2) * np.sin(yaw / 2))
    qy = (np.cos(roll / 2) * np.sin(pitch / 2) * np.cos(yaw / 2)
          + np.sin(roll / 2) * np.cos(pitch / 2) * np.sin(yaw / 2))
    qz = (np.cos(roll / 2) * np.cos(pitch / 2) * np.sin(yaw / 2)
          - np.sin(roll / 2) * np.sin(pitch / 2) * np.cos(yaw / 2))
    qw = (np.cos(roll / 2) * np.cos(pitch / 2) * np.cos(yaw / 2)
          + np.sin(roll / 2) * np.sin(pitch / 2) * np.sin(yaw / 2))
    q = np.array([qw, qx, qy, qz])
    return q / np.linalg.norm(q)


def write_like_scripts(path, t_s, pos, vel, acc, ypr_deg, angvel_deg_s):
    rows = [IBISCAPE_HEADER + "\r\n"]
    for t, p, v, a, (y, pi, r), w in zip(t_s, pos, vel, acc, ypr_deg, angvel_deg_s,
                                         strict=True):
        q = scripts_quaternion(np.radians(y), np.radians(pi), np.radians(r))
        vals = [*p, *v, *a, *q, *np.radians(w)]
        rows.append("%f," % (t * 1e9) + ",".join("%21.21f" % x for x in vals) + " \n")  # noqa: UP031 (the scripts' own format)
    path.write_text("".join(rows))


def test_carla_matrix_is_yaw_negpitch_negroll():
    y, p, r = 0.3, -0.2, 0.4
    np.testing.assert_allclose(carla_matrix(y, p, r), _rz(y) @ _ry(-p) @ _rx(-r), atol=1e-15)


def _drive(tmp_path, yaw_deg, pitch_deg, roll_deg=0.0):
    """A car driving forward (body +x) at 10 m/s with constant CARLA angles."""
    n = 5
    t = 1.0 + 0.05 * np.arange(n)
    R_c = carla_matrix(*np.radians([yaw_deg, pitch_deg, roll_deg]))
    vel = np.tile(10.0 * R_c[:, 0], (n, 1))
    pos = (t - t[0])[:, None] * vel
    p = tmp_path / "groundtruth_sync.csv"
    write_like_scripts(p, t, pos, vel, np.zeros((n, 3)), [(yaw_deg, pitch_deg, roll_deg)] * n,
                       np.zeros((n, 3)))
    return read_ibiscape_groundtruth(p), R_c


def test_yaw_plus_90_drives_along_minus_y(tmp_path):
    gt, _ = _drive(tmp_path, 90.0, 0.0)
    R = matrix_from_quat(gt.trajectory.quat_xyzw)
    np.testing.assert_allclose(R[:, :, 0], [[0, -1, 0]] * 5, atol=1e-9)
    np.testing.assert_allclose(gt.vel_m_s, [[0, -10, 0]] * 5, atol=1e-9)
    assert gt.trajectory.stamps_ns[0] == 1_000_000_000


def test_pitch_nose_up_stays_nose_up(tmp_path):
    gt, _ = _drive(tmp_path, 30.0, 10.0)
    R = matrix_from_quat(gt.trajectory.quat_xyzw)
    assert (R[:, 2, 0] > 0.17).all()  # body x points up: sin(10 deg) = 0.1736
    # the body x axis points along the converted velocity
    v = gt.vel_m_s / np.linalg.norm(gt.vel_m_s, axis=1, keepdims=True)
    np.testing.assert_allclose(R[:, :, 0], v, atol=1e-9)


def test_orientation_equals_mirrored_true_carla_rotation(tmp_path):
    S = np.diag([1.0, -1.0, 1.0])
    for ypr in [(30.0, 10.0, 5.0), (-120.0, -7.0, 20.0), (179.0, 45.0, -60.0)]:
        gt, R_c = _drive(tmp_path, *ypr)
        R = matrix_from_quat(gt.trajectory.quat_xyzw)[0]
        np.testing.assert_allclose(R, S @ R_c @ S, atol=1e-9)
        assert np.isclose(np.linalg.det(R), 1.0)


def test_angular_rate_matches_converted_orientation(tmp_path):
    """w = -S w_c: compare with vee(dR/dt R^T) of the converted orientations."""
    n = 401
    t = np.linspace(0.0, 2.0, n)
    yaw = 40 * np.sin(1.3 * t) + 20
    pitch = 8 * np.sin(0.7 * t + 0.3)
    roll = 5 * np.cos(1.1 * t)
    R_c = np.array([carla_matrix(*np.radians(a)) for a in zip(yaw, pitch, roll, strict=True)])
    dR = np.gradient(R_c, t, axis=0)
    W = dR @ np.swapaxes(R_c, 1, 2)  # [w_c]x in CARLA's coordinates (deg -> rad already)
    w_c = np.stack((W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]), axis=1)
    p = tmp_path / "groundtruth_sync.csv"
    write_like_scripts(p, t + 10.0, np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)),
                       np.stack((yaw, pitch, roll), axis=1), np.degrees(w_c))
    gt = read_ibiscape_groundtruth(p)
    R = matrix_from_quat(gt.trajectory.quat_xyzw)
    Wo = np.gradient(R, t, axis=0) @ np.swapaxes(R, 1, 2)
    w_ours = np.stack((Wo[:, 2, 1], Wo[:, 0, 2], Wo[:, 1, 0]), axis=1)
    inner = slice(2, -2)
    np.testing.assert_allclose(gt.angvel_rad_s[inner], w_ours[inner], atol=2e-4)
    # and a right turn in CARLA (yaw rate > 0) is clockwise (w_z < 0) for us
    assert np.sign(gt.angvel_rad_s[0, 2]) == -np.sign(w_c[0, 2])
