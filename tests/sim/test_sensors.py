"""IMU, GNSS and weather models: known answers on an analytic motion, noise statistics, physics
through the written files (integrating the ideal IMU reproduces the ground truth)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _sb_motion import START_NS, HelixMotion, integrate_imu, pose_at

from ibiscape_eval.core.rotations import matrix_from_quat
from ibiscape_eval.io import read_gnss, read_ibiscape_groundtruth
from ibiscape_eval.io.imu import read_imu
from ibiscape_eval.sim import generate, preset
from ibiscape_eval.sim.config import ImuNoise, ImuSpec, WeatherSpec
from ibiscape_eval.sim.gnss import antenna_positions_m, enu_from_fixes, simulate_gnss
from ibiscape_eval.sim.imu import ideal_imu, simulate_imu
from ibiscape_eval.sim.rig import T_body_imu
from ibiscape_eval.sim.still import still_imu_chunks
from ibiscape_eval.sim.types import MotionState
from ibiscape_eval.sim.weather import simulate_weather

G = np.array([0.0, 0.0, -9.81])


def _stamps(n: int, rate: float = 200.0) -> np.ndarray:
    return START_NS + np.arange(n, dtype=np.int64) * int(1e9 / rate)


def test_gyro_is_body_rate_and_level_still_reads_gravity() -> None:
    st = HelixMotion().sample(_stamps(500))
    m = ideal_imu(st, np.eye(4))
    np.testing.assert_array_equal(m.gyro_rad_s, st.angvel_body_rad_s)
    z = np.zeros((3, 3))
    q = np.tile([0.0, 0.0, 0.0, 1.0], (3, 1))
    still = ideal_imu(MotionState(_stamps(3), z, q, z, z, z, z), np.eye(4))
    np.testing.assert_allclose(still.accel_m_s2, np.tile([0.0, 0.0, 9.81], (3, 1)), atol=1e-15)


def test_lever_arm_matches_second_difference_of_imu_position() -> None:
    """Specific force of an IMU at r = (0, 0.1, 2.8) equals R^T (d2/dt2 (p + R r) - g)."""
    motion = HelixMotion()
    r = np.array([0.0, 0.1, 2.8])
    T = np.eye(4)
    T[:3, 3] = r
    st = motion.sample(_stamps(50))
    m = ideal_imu(st, T)
    t = (st.stamps_ns - START_NS) * 1e-9
    h = 1e-3

    def p_imu(tt: np.ndarray) -> np.ndarray:
        p, R = pose_at(tt)
        return p + R @ r

    acc_fd = (p_imu(t + h) - 2 * p_imu(t) + p_imu(t - h)) / h**2
    R = matrix_from_quat(st.quat_xyzw)
    f_ref = np.einsum("nji,nj->ni", R, acc_fd - G)
    np.testing.assert_allclose(m.accel_m_s2, f_ref, atol=1e-5)
    # without the lever-arm terms the reading would be off by far more than that
    assert np.abs(ideal_imu(st, np.eye(4)).accel_m_s2 - f_ref).max() > 1e-2


def test_rotated_imu_axes() -> None:
    st = HelixMotion().sample(_stamps(20))
    spec = ImuSpec("imuX", (0.0, 0.0, 0.0), rpy_deg=(0.0, 0.0, 90.0))
    m0, m = ideal_imu(st, np.eye(4)), ideal_imu(st, T_body_imu(spec))
    # IMU x = body y, IMU y = -body x
    np.testing.assert_allclose(m.gyro_rad_s[:, 0], m0.gyro_rad_s[:, 1], atol=1e-15)
    np.testing.assert_allclose(m.accel_m_s2[:, 1], -m0.accel_m_s2[:, 0], atol=1e-13)


def test_white_noise_sigma_and_random_walk_and_carla_model() -> None:
    n = 200_000
    z = np.zeros((n, 3))
    q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    st = MotionState(_stamps(n), z, q, z, z, z, z)
    noise = ImuNoise(gyro_random_walk_rad_s2_sqrt_hz=0.0, accel_random_walk_m_s3_sqrt_hz=0.0,
                     gyro_turn_on_bias_sigma_rad_s=0.0, accel_turn_on_bias_sigma_m_s2=0.0)
    m = simulate_imu(st, np.eye(4), noise, rate_hz=200.0, seed=3)
    np.testing.assert_allclose(m.gyro_rad_s.std(axis=0), 1.6968e-4 * math.sqrt(200), rtol=0.01)
    np.testing.assert_allclose((m.accel_m_s2 - [0, 0, 9.81]).std(axis=0), 2e-3 * math.sqrt(200),
                               rtol=0.01)
    carla = simulate_imu(st, np.eye(4), ImuNoise(model="carla", carla_gyro_bias_rad_s=0.01),
                         rate_hz=200.0, seed=3)
    np.testing.assert_allclose(carla.gyro_rad_s.std(axis=0), 0.004, rtol=0.01)
    np.testing.assert_allclose(carla.gyro_rad_s.mean(axis=0), 0.01, atol=5e-5)
    np.testing.assert_allclose((carla.accel_m_s2 - [0, 0, 9.81]).std(axis=0), 0.07, rtol=0.01)
    # turn-on bias: a constant offset, different per seed, zero when ideal
    biased = ImuNoise(gyro_noise_density_rad_s_sqrt_hz=0.0, gyro_random_walk_rad_s2_sqrt_hz=0.0)
    short = MotionState(st.stamps_ns[:10], z[:10], q[:10], z[:10], z[:10], z[:10], z[:10])
    a = simulate_imu(short, np.eye(4), biased, rate_hz=200.0, seed=1)
    assert np.ptp(a.gyro_rad_s, axis=0).max() == 0.0 and np.abs(a.gyro_rad_s).min() > 0
    ideal = simulate_imu(st, np.eye(4), noise, rate_hz=200.0, seed=3, ideal=True)
    np.testing.assert_array_equal(ideal.gyro_rad_s, 0.0)


def test_still_chunks_do_not_depend_on_how_they_are_consumed_and_are_seeded() -> None:
    spec = ImuSpec(rate_hz=100.0)
    kw = {"duration_s": 20.0, "start_ns": START_NS, "ideal": False, "chunk": 300}
    a = list(still_imu_chunks(spec, ImuNoise(), seed=5, **kw))
    b = list(still_imu_chunks(spec, ImuNoise(), seed=5, **kw))
    c = list(still_imu_chunks(spec, ImuNoise(), seed=6, **kw))
    assert sum(len(x[0]) for x in a) == 2001 and max(len(x[0]) for x in a) == 300
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x[1], y[1])
    assert not np.array_equal(a[0][1], c[0][1])
    st = np.concatenate([x[0] for x in a])
    assert np.all(np.diff(st) == 10_000_000) and st[0] == START_NS
    acc = np.concatenate([x[2] for x in a])
    assert abs(acc[:, 2].mean() - 9.81) < 0.1


def test_gnss_ideal_maps_back_to_antenna_and_noise_sigma() -> None:
    cfg = preset("svi", "slam", "clear")
    st = HelixMotion().sample(_stamps(50, 1.0))
    fx = simulate_gnss(st, cfg.gnss, seed=1, ideal=True)
    np.testing.assert_allclose(enu_from_fixes(fx, cfg.gnss), antenna_positions_m(st, cfg.gnss),
                               atol=1e-6)
    assert abs(fx.lat_deg[0] - cfg.gnss.ref_lat_deg) < 1e-3
    n = 5000
    st = HelixMotion(duration_s=6000).sample(_stamps(n, 1.0))
    noisy = simulate_gnss(st, cfg.gnss, seed=2)
    d = enu_from_fixes(noisy, cfg.gnss) - antenna_positions_m(st, cfg.gnss)
    np.testing.assert_allclose(d.std(axis=0), [0.5, 0.5, 1.0], rtol=0.05)


def test_weather_presets_averages_and_sun() -> None:
    st = _stamps(300 * 20, 20.0)
    dyn = simulate_weather(preset(weather="dynamic").weather_model, st, seed=4)
    avg = dyn.averages()
    assert avg["fog_density"] == pytest.approx(70, abs=5)
    assert avg["precipitation"] == pytest.approx(45, abs=5)
    assert avg["wind_intensity"] == pytest.approx(70, abs=5)
    assert dyn.values.min() >= -90 and np.ptp(dyn.column("precipitation")) > 20  # it evolves
    clear = simulate_weather(preset(weather="clear").weather_model, st, seed=4)
    assert clear.column("precipitation").max() == 0 and clear.averages()["fog_density"] == 0
    mod = simulate_weather(preset(weather="moderate").weather_model, st, seed=4).averages()
    assert clear.averages()["cloudiness"] < mod["cloudiness"] < avg["cloudiness"]
    spec = WeatherSpec()
    t = (st - st[0]) * 1e-9
    np.testing.assert_allclose(clear.column("sun_altitude_angle"),
                               70 * np.sin(spec.sun_phase0_rad + spec.sun_phase_rate_rad_s * t) - 20)
    np.testing.assert_array_equal(dyn.values, simulate_weather(
        preset(weather="dynamic").weather_model, st, seed=4).values)
    assert not np.array_equal(dyn.values, simulate_weather(
        preset(weather="dynamic").weather_model, st, seed=5).values)


# ---------------------------------------------------------------------------------------------
# physics through the written files


@pytest.fixture(scope="module")
def ideal_seq(tmp_path_factory: pytest.TempPathFactory):
    out = tmp_path_factory.mktemp("phys") / "seq"
    cfg = preset("esvi", "slam", "clear", duration_s=10.0, ideal=True, seed=3)
    generate(cfg, out, motion=HelixMotion(duration_s=10.0))
    return cfg, out


def test_integrating_ideal_imu0_reproduces_groundtruth(ideal_seq) -> None:
    _, out = ideal_seq
    gt = read_ibiscape_groundtruth(out / "vehicle_gt" / "groundtruth_sync.csv")
    imu = read_imu(out / "other_sensors" / "imu0.csv")
    samples = imu.samples if imu.samples is not None else np.load(imu.path)
    tr = gt.trajectory
    t = (tr.stamps_ns - tr.stamps_ns[0]) * 1e-9
    R_gt = matrix_from_quat(tr.quat_xyzw)
    p, R = integrate_imu(t, samples[:, :3], samples[:, 3:], tr.pos_m[0], gt.vel_m_s[0], R_gt[0])
    assert t[-1] == pytest.approx(10.0)
    assert np.linalg.norm(p - tr.pos_m[-1]) < 0.01
    ang = math.degrees(math.acos(np.clip((np.trace(R.T @ R_gt[-1]) - 1) / 2, -1, 1)))
    assert ang < 0.05
    # gyro = GT angular rate (the file holds it in the world frame)
    w_body = np.einsum("nji,nj->ni", R_gt, gt.angvel_rad_s)
    np.testing.assert_allclose(samples[:, :3], w_body, atol=1e-12)
    # the file itself holds CARLA's left-handed frame, like IBISCape: read as it stands (euroc),
    # w_x, w_z and a_y come out negated
    raw = read_imu(out / "other_sensors" / "imu0.csv", fmt="euroc").samples
    assert imu.samples is not None and raw is not None
    np.testing.assert_array_equal(raw, samples * np.array([-1, 1, -1, 1, -1, 1]))
    assert np.abs(samples[:, [0, 2, 4]]).max() > 1e-3  # the flipped axes are not all zero


def test_lever_arm_imus_in_files(ideal_seq) -> None:
    """IMU1 sits 2.8 m above IMU0: same gyro, different specific force."""
    _, out = ideal_seq
    s0 = read_imu(out / "other_sensors" / "imu0.csv").samples
    s1 = read_imu(out / "other_sensors" / "imu1.csv").samples
    np.testing.assert_allclose(s0[:, :3], s1[:, :3], atol=1e-14)
    assert np.abs(s0[:, 3:] - s1[:, 3:]).max() > 1e-3


def test_gnss_file_maps_back_to_groundtruth(ideal_seq) -> None:
    cfg, out = ideal_seq
    gt = read_ibiscape_groundtruth(out / "vehicle_gt" / "groundtruth_sync.csv")
    fx = read_gnss(out / "other_sensors" / "gnss.csv")
    assert len(fx) == 11 and np.all(np.diff(fx.stamps_ns) == 1_000_000_000)
    idx = np.searchsorted(gt.trajectory.stamps_ns, fx.stamps_ns)
    tr = gt.trajectory
    st = MotionState(tr.stamps_ns[idx], tr.pos_m[idx], tr.quat_xyzw[idx], *(np.zeros((11, 3)),) * 4)
    np.testing.assert_allclose(enu_from_fixes(fx, cfg.gnss), antenna_positions_m(st, cfg.gnss),
                               atol=1e-3)
