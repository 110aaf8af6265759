"""Round trips of the sequence files written by the generator (io/sequence.py)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs
from hypothesis.extra import numpy as hnp

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.core.trajectory import Trajectory
from ibiscape_eval.io import IbiscapeGroundTruth, write_ibiscape_groundtruth
from ibiscape_eval.io.sequence import (
    read_controls,
    read_weather_csv,
    write_controls,
    write_groundtruth_chunks,
    write_weather_csv,
)

_unit = hs.floats(0.0, 1.0, allow_nan=False, width=64)


@settings(max_examples=30, deadline=None)
@given(n=hs.integers(1, 40), data=hs.data())
def test_controls_round_trip(n: int, data: hs.DataObject) -> None:
    st = np.cumsum(data.draw(hnp.arrays(np.int64, n, elements=hs.integers(1, 10**9)))) + 10**12
    thr = data.draw(hnp.arrays(np.float64, n, elements=_unit))
    steer = data.draw(hnp.arrays(np.float64, n, elements=hs.floats(-1.0, 1.0, width=64)))
    brk = data.draw(hnp.arrays(np.float64, n, elements=_unit))
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "Tesla_simulation.txt"
        write_controls(p, st, thr, steer, brk)
        c = read_controls(p)
    np.testing.assert_array_equal(c.stamps_ns, st)
    for a, b in ((c.throttle, thr), (c.steer, steer), (c.brake, brk)):
        np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-15)


@settings(max_examples=30, deadline=None)
@given(n=hs.integers(1, 30), k=hs.integers(1, 11), data=hs.data())
def test_weather_round_trip(n: int, k: int, data: hs.DataObject) -> None:
    st = 10**12 + np.arange(n, dtype=np.int64) * 50_000_000
    v = data.draw(hnp.arrays(np.float64, (n, k), elements=hs.floats(-1e3, 1e3, width=64)))
    cols = [f"c{i}" for i in range(k)]
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "weather.csv"
        write_weather_csv(p, st, v, cols)
        st2, v2, cols2 = read_weather_csv(p)
    np.testing.assert_array_equal(st2, st)
    np.testing.assert_allclose(v2, v, rtol=1e-14, atol=1e-15)
    assert cols2 == cols


def test_bad_controls_name_the_line(tmp_path: Path) -> None:
    p = tmp_path / "c.txt"
    p.write_text("1000,0.1,0.0,0 \n2000,1.5,0.0,0 \n")
    with pytest.raises(FormatError, match=r"c\.txt:2: throttle"):
        read_controls(p)
    p.write_text("1000,0.1,0.0 \n")
    with pytest.raises(FormatError, match="4 columns"):
        read_controls(p)


def test_groundtruth_chunks_equal_one_shot_writer(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    n = 257
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    st = 10**12 + np.arange(n, dtype=np.int64) * 5_000_000
    arr = [rng.normal(size=(n, 3)) for _ in range(4)]
    gt = IbiscapeGroundTruth(Trajectory(st, arr[0], q), arr[1], arr[2], arr[3])
    write_ibiscape_groundtruth(tmp_path / "a.csv", gt)
    parts = [IbiscapeGroundTruth(Trajectory(st[s], arr[0][s], q[s]), arr[1][s], arr[2][s], arr[3][s])
             for s in (slice(0, 100), slice(100, 101), slice(101, n))]
    write_groundtruth_chunks(tmp_path / "b.csv", parts)
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
