"""Image-set pairing: every frame lands in exactly one view, simultaneous frames share a view."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ibiscape_eval.io.image_sets import ImageSet, pair_views


@settings(max_examples=60, deadline=None)
@given(st.lists(st.lists(st.integers(0, 50), min_size=1, max_size=20, unique=True), min_size=2,
                max_size=4), st.integers(0, 3))
def test_every_frame_once_and_common_instants_shared(stamp_lists, jitter_ms):
    sets = []
    for k, st_list in enumerate(stamp_lists):
        stamps = np.sort(np.array(st_list, np.int64)) * 50_000_000 + k * jitter_ms * 100_000
        sets.append(ImageSet(f"c{k}", tuple(Path(f"{t}.png") for t in stamps), stamps, "frames", Path(".")))
    common = set(stamp_lists[0]).intersection(*map(set, stamp_lists[1:]))
    try:
        table = pair_views(sets)
    except Exception as e:  # no common instant at all: the only allowed failure
        assert "share no instant" in str(e)
        assert all(len(set(a) & set(b)) == 0 for i, a in enumerate(stamp_lists) for b in stamp_lists[i + 1:])
        return
    for k, s in enumerate(sets):
        col = [row[k] for row in table if row[k] is not None]
        assert sorted(col) == list(range(len(s)))
    full = [row for row in table if all(c is not None for c in row)]
    assert len(full) == len(common)
