"""The Trajectory value type: validation, immutability, conversions."""

import numpy as np
import pytest

from ibiscape_eval.core import IbiscapeError, Trajectory, ns_from_s, s_from_ns


def make(n: int = 5) -> Trajectory:
    q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    return Trajectory(
        np.arange(n, dtype=np.int64) * 10, np.arange(3 * n, dtype=float).reshape(n, 3), q, "t"
    )


def test_arrays_are_read_only_and_inputs_untouched() -> None:
    pos = np.zeros((3, 3))
    quat = np.tile([0.0, 0.0, 0.0, 1.0 + 5e-4], (3, 1))  # renormalised silently (within 1e-3)
    t = Trajectory(np.array([1, 2, 3]), pos, quat)
    with pytest.raises(ValueError):
        t.pos_m[0, 0] = 1.0
    pos[0, 0] = 5.0
    assert t.pos_m[0, 0] == 0.0
    assert quat[0, 3] == 1.0 + 5e-4
    assert pos.flags.writeable
    np.testing.assert_allclose(t.quat_xyzw[:, 3], 1.0)


@pytest.mark.parametrize(
    ("stamps", "pos", "quat", "msg"),
    [
        ([1, 1, 2], np.zeros((3, 3)), np.tile([0, 0, 0, 1.0], (3, 1)), "increase strictly"),
        ([1, 2, 3], np.zeros((3, 2)), np.tile([0, 0, 0, 1.0], (3, 1)), "expected stamps"),
        ([1, 2, 3], np.zeros((3, 3)), np.zeros((3, 4)), "unit quaternion"),
        ([1, 2, 3], np.full((3, 3), np.nan), np.tile([0, 0, 0, 1.0], (3, 1)), "not finite"),
        ([1.0, 2.0, 3.0], np.zeros((3, 3)), np.tile([0, 0, 0, 1.0], (3, 1)), "integer nanoseconds"),
    ],
)
def test_validation(stamps: list, pos: np.ndarray, quat: np.ndarray, msg: str) -> None:
    with pytest.raises(IbiscapeError, match=msg):
        Trajectory(np.asarray(stamps), pos, quat)


def test_matrices_roundtrip_and_take() -> None:
    t = make()
    back = Trajectory.from_matrices(t.stamps_ns, t.matrices(), "b")
    np.testing.assert_allclose(back.pos_m, t.pos_m)
    sub = t.take([0, 2])
    assert len(sub) == 2 and sub.stamps_ns.tolist() == [0, 20]
    np.testing.assert_allclose(t.path_length_m()[-1], 4 * np.sqrt(27))
    assert list(t.to_frame().columns)[:2] == ["stamp_ns", "x_m"]


def test_seconds_conversion_exact_at_epoch_scale() -> None:
    ns = np.array([1_305_031_102_175_304_000, 1_403_715_273_262_142_976], dtype=np.int64)
    assert (ns_from_s(np.array([0.5, 1.25])) == [500_000_000, 1_250_000_000]).all()
    np.testing.assert_allclose(s_from_ns(ns), ns / 1e9, rtol=1e-15)


def test_atomic_outputs_get_umask_permissions(tmp_path) -> None:
    """mkstemp creates 0600 files; published outputs must be readable like any other file."""
    import os

    from ibiscape_eval.io.atomic import atomic_output_path, atomic_write

    old = os.umask(0o022)
    try:
        with atomic_write(tmp_path / "a.txt") as f:
            f.write("x")
        with atomic_output_path(tmp_path / "b.png") as p:
            p.write_bytes(b"x")
    finally:
        os.umask(old)
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "b.png").stat().st_mode & 0o777 == 0o644
