"""Batched rotation and transform helpers against scipy's Rotation (an independent implementation)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from ibiscape_eval.core import rotations as rot
from ibiscape_eval.core.transforms import (
    invert_transforms,
    matrices_from_pose,
    pose_from_matrices,
    transform_points,
)

RNG = np.random.default_rng(7)


def random_quats(n: int) -> np.ndarray:
    return rot.quat_normalize(Rotation.random(n, random_state=3).as_quat())


def same_rotation(q1: np.ndarray, q2: np.ndarray, atol: float = 1e-12) -> bool:
    return bool(np.all(np.abs(np.abs(np.sum(q1 * q2, axis=-1)) - 1.0) < atol))


def test_matrix_roundtrip_matches_scipy() -> None:
    q = random_quats(500)
    R = rot.matrix_from_quat(q)
    np.testing.assert_allclose(R, Rotation.from_quat(q).as_matrix(), atol=1e-14)
    assert same_rotation(rot.quat_from_matrix(R), q)


def test_quat_from_matrix_near_pi_rotations() -> None:
    # Near 180 degrees the trace branch is ill-conditioned; Shepperd's selection must still work.
    axes = RNG.normal(size=(200, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    rv = axes * (np.pi - RNG.uniform(0, 1e-7, size=(200, 1)))
    R = Rotation.from_rotvec(rv).as_matrix()
    q = rot.quat_from_matrix(R)
    np.testing.assert_allclose(rot.matrix_from_quat(q), R, atol=1e-12)


def test_multiply_conjugate_rotate() -> None:
    a, b = random_quats(100), random_quats(100)[::-1]
    np.testing.assert_allclose(
        rot.matrix_from_quat(rot.quat_multiply(a, b)),
        Rotation.from_quat(a).as_matrix() @ Rotation.from_quat(b).as_matrix(),
        atol=1e-13,
    )
    ident = rot.quat_multiply(a, rot.quat_conjugate(a))
    np.testing.assert_allclose(np.abs(ident[:, 3]), 1.0, atol=1e-14)
    v = RNG.normal(size=(100, 3))
    np.testing.assert_allclose(rot.quat_rotate(a, v), Rotation.from_quat(a).apply(v), atol=1e-13)


def test_angle_and_rotvec() -> None:
    q = random_quats(300)
    ref = Rotation.from_quat(q)
    np.testing.assert_allclose(rot.angle_rad_from_quat(q), ref.magnitude(), atol=1e-12)
    np.testing.assert_allclose(rot.rotvec_from_quat(q), ref.as_rotvec(), atol=1e-12)
    assert same_rotation(rot.quat_from_rotvec(ref.as_rotvec()), q)
    tiny = np.array([[1e-12, -2e-12, 3e-12]])
    np.testing.assert_allclose(rot.rotvec_from_quat(rot.quat_from_rotvec(tiny)), tiny, rtol=1e-9)


def test_yaw_quaternion() -> None:
    q = rot.quat_from_yaw(np.array([0.3, -2.0]))
    np.testing.assert_allclose(Rotation.from_quat(q).as_euler("zyx")[:, 0], [0.3, -2.0], atol=1e-14)


@settings(max_examples=50, deadline=None)
@given(st.floats(0.0, 1.0))
def test_slerp_matches_scipy(t: float) -> None:
    from scipy.spatial.transform import Slerp

    q = random_quats(2)
    ours = rot.quat_slerp(q[0], q[1], t)
    theirs = Slerp([0.0, 1.0], Rotation.from_quat(q))([t]).as_quat()[0]
    assert same_rotation(ours, theirs, atol=1e-10)


def test_transforms_inverse_and_roundtrip() -> None:
    q = random_quats(50)
    p = RNG.normal(size=(50, 3))
    T = matrices_from_pose(p, q)
    eye = np.einsum("nij,njk->nik", T, invert_transforms(T))
    np.testing.assert_allclose(eye, np.broadcast_to(np.eye(4), eye.shape), atol=1e-13)
    p2, q2 = pose_from_matrices(T)
    np.testing.assert_allclose(p2, p)
    assert same_rotation(q2, q)
    pts = RNG.normal(size=(7, 3))
    np.testing.assert_allclose(transform_points(T[0], pts), pts @ T[0, :3, :3].T + p[0])


@pytest.mark.parametrize("n", [1, 3])
def test_normalize_canonical_sign(n: int) -> None:
    q = -random_quats(n) * 2.0
    out = rot.quat_normalize(q)
    assert np.all(out[:, 3] >= 0)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0)
