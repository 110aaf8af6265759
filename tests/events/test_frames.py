"""Event frames: accumulation and time surfaces, known answers."""

from __future__ import annotations

import numpy as np
import pytest

from ibiscape_eval.core.errors import DegenerateInputError, IbiscapeError
from ibiscape_eval.core.events import Events
from ibiscape_eval.events import accumulate_frames, time_surfaces
from ibiscape_eval.events.frames import frame_windows

MS = 1_000_000


def small() -> Events:
    t = np.array([0, 1, 2, 12, 13, 25], np.int64) * MS
    x = np.array([0, 0, 1, 2, 2, 3], np.uint16)
    y = np.array([0, 0, 1, 0, 0, 1], np.uint16)
    p = np.array([True, False, True, True, True, False])
    return Events(t, x, y, p)


def test_frame_windows_at_a_fixed_rate():
    a, b = frame_windows(0, 25 * MS, rate_hz=100)
    np.testing.assert_array_equal(b, np.array([10, 20, 30]) * MS)
    np.testing.assert_array_equal(a, b - 10 * MS)
    a, b = frame_windows(0, 25 * MS, rate_hz=100, window_ns=5 * MS)
    np.testing.assert_array_equal(b - a, 5 * MS)


def test_accumulation_frames_known_answer():
    fr = accumulate_frames(small(), sensor_size=(4, 2), rate_hz=100)
    assert fr.frames.shape == (3, 2, 4) and fr.frames.dtype == np.float32
    f0, f1, f2 = fr.frames
    assert f0[0, 0] == 0 and f0[1, 1] == 1  # +1 -1 at (0,0); +1 at (1,1)
    assert f1[0, 2] == 2 and f1.sum() == 2
    assert f2[1, 3] == -1
    un = accumulate_frames(small(), sensor_size=(4, 2), rate_hz=100, signed=False)
    assert un.frames[0, 0, 0] == 2 and un.frames.sum() == 6
    img = fr.to_uint8()
    assert img.dtype == np.uint8 and img[0, 0, 1] == 128 and img[0, 1, 1] == 255


def test_time_surface_known_answer():
    tau = 10 * MS
    ts = time_surfaces(small(), sensor_size=(4, 2), windows=([0], [20 * MS]), tau_ns=tau)
    f = ts.frames[0]
    assert f[0, 0] == pytest.approx(np.exp(-19 / 10), rel=1e-6)  # last event at 1 ms
    assert f[0, 2] == pytest.approx(np.exp(-7 / 10), rel=1e-6)  # at 13 ms
    assert f[1, 3] == 0.0  # fires only later
    signed = time_surfaces(small(), sensor_size=(4, 2), windows=([0], [20 * MS]), tau_ns=tau,
                           signed=True)
    assert signed.frames[0, 0, 0] == pytest.approx(-np.exp(-19 / 10), rel=1e-6)  # last was negative


def test_frames_bad_input():
    with pytest.raises(DegenerateInputError):
        accumulate_frames(Events.empty(), sensor_size=(4, 2), rate_hz=10)
    with pytest.raises(IbiscapeError, match="outside"):
        accumulate_frames(small(), sensor_size=(2, 2), rate_hz=10)
    with pytest.raises(IbiscapeError, match="rate"):
        accumulate_frames(small(), sensor_size=(4, 2))
