"""Real event recordings from public repositories (tests/data/real/*/PROVENANCE.md), each
cross-checked against a second reader."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ibiscape_eval.io.events import open_events, read_events

REAL = Path(__file__).resolve().parents[1] / "data" / "real"
DVXPLORER = REAL / "tonic_dvxplorer" / "sample.aedat4"


def test_dvxplorer_aedat4_stream_table_and_events():
    src = open_events(DVXPLORER)
    assert src.fmt == "aedat4" and src.sensor_size == (320, 240)
    assert src.size_from == "the AEDAT4 stream table"
    assert src.meta["streams"] == "0 (events), 2 (imus), 3 (triggers)"
    ev = read_events(DVXPLORER)
    assert len(ev) == 111954
    assert int(ev.x.max()) < 320 and int(ev.y.max()) < 240
    # DV stamps are Unix microseconds: this one was recorded on 2020-11-16
    assert 1605484800 * 10**9 < int(ev.t_ns[0]) < 1605571200 * 10**9
    assert np.all(ev.t_ns % 1000 == 0) and 0.45 < ev.p.mean() < 0.55


def test_dvxplorer_aedat4_same_events_with_dv_processing():
    """iniVation's own decoder (a test-only dependency) reads the same events, bit for bit."""
    dv = pytest.importorskip("dv_processing")
    rec = dv.io.MonoCameraRecording(str(DVXPLORER))
    assert rec.getCameraName() == "DVXplorer_DXB00010"
    assert tuple(rec.getEventResolution()) == (320, 240)
    parts = []
    while (b := rec.getNextEventBatch()) is not None:
        parts.append(b.numpy())
    a = np.concatenate(parts)
    ev = read_events(DVXPLORER)
    np.testing.assert_array_equal(a["timestamp"].astype(np.int64) * 1000, ev.t_ns)
    np.testing.assert_array_equal(a["x"], ev.x)
    np.testing.assert_array_equal(a["y"], ev.y)
    np.testing.assert_array_equal(a["polarity"] != 0, ev.p)
