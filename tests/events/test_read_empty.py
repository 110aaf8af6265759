"""Empty event streams: refused as a recording (nothing to process), accepted as one window of a
still camera when asked (``allow_empty``), the same way for a lone ``.npz`` and an IBISCape folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from ibiscape_eval.calib.events import read_event_window
from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.core.events import Events
from ibiscape_eval.io.dvs_folder import DvsFolderWriter
from ibiscape_eval.io.events import iter_event_chunks, read_events


def _ev(rng: np.random.Generator, n: int, a: int, b: int) -> Events:
    return Events(np.sort(rng.integers(a, b, n)).astype(np.int64), rng.integers(0, 8, n).astype(np.uint16),
                  rng.integers(0, 6, n).astype(np.uint16), rng.random(n) < 0.5)


def _empty_npz(p: Path) -> Path:
    np.savez(p, t=np.zeros(0, np.int64), x=np.zeros(0, np.uint16), y=np.zeros(0, np.uint16), p=np.zeros(0, bool))
    return p


def test_an_empty_npz_is_refused_unless_allowed(tmp_path: Path) -> None:
    p = _empty_npz(tmp_path / "1000.npz")
    with pytest.raises(FormatError, match=r"1000\.npz.*no events"):
        read_events(p, fmt="npz")
    got = read_events(p, fmt="npz", allow_empty=True)
    assert len(got) == 0 and got.t_ns.dtype == np.int64 and got.x.dtype == np.uint16
    assert len(read_event_window(p)) == 0
    assert [len(c.events) for c in iter_event_chunks(p, allow_empty=True)] == [0]
    # allow_empty does not relax any other check
    np.savez(tmp_path / "bad.npz", t=np.zeros(0, np.float64), x=np.zeros(0, np.uint16), y=np.zeros(0, np.uint16),
             p=np.zeros(0, bool))
    with pytest.raises(FormatError, match="integer nanoseconds"):
        read_events(tmp_path / "bad.npz", fmt="npz", allow_empty=True)


@settings(max_examples=20, deadline=None)
@given(hs.lists(hs.integers(0, 30), min_size=1, max_size=6), hs.integers(0, 2**31))
def test_folder_with_empty_windows_reads_back(tmp_path_factory: pytest.TempPathFactory, sizes: list[int],
                                              seed: int) -> None:
    """Windows written by the DVS folder writer, some empty, read back in order; a folder with no
    event at all is refused (naming the folder) unless allowed, and every lone window reads back."""
    rng = np.random.default_rng(seed)
    root = tmp_path_factory.mktemp("dvs") / "davisL"
    w = DvsFolderWriter(root, frames=False)
    parts = []
    for k, n in enumerate(sizes):
        a, b = 10**9 + k * 10**6, 10**9 + (k + 1) * 10**6
        parts.append(_ev(rng, n, a, b))
        w.add(a, b, parts[-1], None)
    w.close()
    want = Events.concatenate(parts)
    if len(want) == 0:
        with pytest.raises(FormatError, match=r"davisL.*no events"):
            read_events(root)
    else:
        got = read_events(root)
        np.testing.assert_array_equal(got.t_ns, want.t_ns)
        np.testing.assert_array_equal(got.p, want.p)
    got = read_events(root, allow_empty=True)
    np.testing.assert_array_equal(got.t_ns, want.t_ns)
    for f, part in zip(sorted((root / "events").glob("*.npz")), parts, strict=True):
        one = read_event_window(f)
        np.testing.assert_array_equal(one.x, part.x)
        np.testing.assert_array_equal(one.y, part.y)
