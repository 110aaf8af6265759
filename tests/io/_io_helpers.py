"""Shared strategies and helpers of the io tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from hypothesis import strategies as st
from shared_data import require_shared

from ibiscape_eval.core.trajectory import Trajectory


def require_data() -> Path:
    """The shared real trajectories (skip when missing, fail under CI=true)."""
    return require_shared("trajectories")


@st.composite
def trajectories(draw, min_size: int = 1, max_size: int = 30, epoch: bool | None = None):
    """Strictly increasing int64 stamps (incl. epoch scale), positions, random unit quats."""
    n = draw(st.integers(min_size, max_size))
    big = draw(st.booleans()) if epoch is None else epoch
    start = draw(st.integers(0, 2 * 10**18) if big else st.integers(-10**12, 10**12))
    steps = draw(st.lists(st.integers(1, 10**10), min_size=n, max_size=n))
    stamps = start + np.cumsum(np.array(steps, dtype=np.int64))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    scale = 10.0 ** draw(st.integers(-6, 6))
    pos = rng.normal(size=(n, 3)) * scale
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return Trajectory(stamps.astype(np.int64), pos, q, "t")


def assert_same_poses(a: Trajectory, b: Trajectory, *, rtol: float = 1e-9,
                      atol: float = 1e-12, stamps: bool = True) -> None:
    assert len(a) == len(b)
    if stamps:
        np.testing.assert_array_equal(a.stamps_ns, b.stamps_ns)
    np.testing.assert_allclose(a.pos_m, b.pos_m, rtol=rtol, atol=atol)
    dots = np.abs(np.einsum("ij,ij->i", a.quat_xyzw, b.quat_xyzw))
    np.testing.assert_allclose(dots, 1.0, atol=1e-9)
