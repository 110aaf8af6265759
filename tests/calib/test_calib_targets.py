"""Targets: Kalibr's corner numbering, the simulator's boards, symmetric renumberings, bad yaml keys."""

from __future__ import annotations

import numpy as np
import pytest

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.kalibr import CalibrationTarget, target_from_kalibr
from ibiscape_eval.sim.targets import make_target


def test_object_points_match_the_simulator():
    for kind in ("checkerboard", "aprilgrid"):
        sim = make_target(kind, T_world_target=np.eye(4))
        t = target_from_kalibr(sim.kalibr)
        np.testing.assert_allclose(t.object_points(), sim.corners_target_m, atol=1e-12)
    # one geometry: the simulator's board is the core type itself
    assert make_target("aprilgrid", T_world_target=np.eye(4)).board == t


def test_tag_corner_ids_follow_kalibr():
    t = CalibrationTarget("aprilgrid", 6, 6, tag_size_m=0.4, tag_spacing=0.3)
    # FORMATS.md: base = floor(id / tagCols) * 4 tagCols + (id mod tagCols) * 2
    assert t.tag_corner_ids([0]).tolist() == [[0, 1, 13, 12]]
    assert t.tag_corner_ids([7]).tolist() == [[26, 27, 39, 38]]
    obj = t.object_points()
    c = obj[t.tag_corner_ids([7])[0]]
    # bottom-left, bottom-right, top-right, top-left of a square of tagSize
    np.testing.assert_allclose(np.diff(c[:, :2], axis=0), [[0.4, 0], [0, 0.4], [-0.4, 0]], atol=1e-12)


@pytest.mark.parametrize("rows,cols,sx,sy,n", [(7, 7, 0.5, 0.5, 8), (6, 9, 0.1, 0.1, 4), (7, 7, 0.1, 0.2, 4)])
def test_symmetries_are_rigid_motions(rows, cols, sx, sy, n):
    t = CalibrationTarget("checkerboard", rows, cols, spacing_x_m=sx, spacing_y_m=sy)
    obj = t.object_points()
    perms = t.symmetries()
    assert len(perms) == n
    for perm in perms:
        assert sorted(perm.tolist()) == list(range(t.n_corners))
        a, b = obj - obj.mean(0), obj[perm] - obj[perm].mean(0)
        # a proper rotation maps a onto b (Kabsch)
        u, _, vt = np.linalg.svd(b.T @ a)
        R = u @ np.diag([1, 1, np.linalg.det(u @ vt)]) @ vt
        np.testing.assert_allclose(a @ R.T, b, atol=1e-9)


@pytest.mark.parametrize("doc,match", [
    ({"target_type": "chessboard"}, "target_type"),
    ({"target_type": "checkerboard", "targetRows": 7}, "missing targetCols"),
    ({"target_type": "aprilgrid", "tagRows": 6, "tagCols": 6, "tagSize": 0.1}, "missing tagSpacing"),
    ({"target_type": "aprilgrid", "tagRows": 6.5, "tagCols": 6, "tagSize": 0.1, "tagSpacing": 0.3},
     "integers"),
    ({"target_type": "checkerboard", "targetRows": 7, "targetCols": 7, "rowSpacingMeters": "x",
      "colSpacingMeters": 0.1}, "numbers"),
    ({"target_type": "checkerboard", "targetRows": 7, "targetCols": 7, "rowSpacingMeters": -0.1,
      "colSpacingMeters": 0.1}, r"in \(0, 10\] m"),
    # physically absurd boards (the mutation campaign's huge numbers) are refused by the reader
    ({"target_type": "checkerboard", "targetRows": 7, "targetCols": 7, "rowSpacingMeters": 1e9,
      "colSpacingMeters": 0.5}, r"in \(0, 10\] m"),
    ({"target_type": "checkerboard", "targetRows": 7, "targetCols": 7, "rowSpacingMeters": 5.0,
      "colSpacingMeters": 0.01}, "times longer than wide"),
    ({"target_type": "aprilgrid", "tagRows": 6, "tagCols": 100000, "tagSize": 0.1, "tagSpacing": 0.3},
     r"counts in 1..1000"),
    ({"target_type": "aprilgrid", "tagRows": 6, "tagCols": 6, "tagSize": 0.1, "tagSpacing": 1e9},
     r"tagSpacing in \(0, 10\]"),
    ({"target_type": "checkerboard", "targetRows": 1, "targetCols": 7, "rowSpacingMeters": 0.1,
      "colSpacingMeters": 0.1}, "inner corners"),
    ([1, 2], "mapping"),
])
def test_bad_target_keys(doc, match):
    with pytest.raises(IbiscapeError, match=match):
        target_from_kalibr(doc, source="t.yaml")


def test_round_trip_kalibr_keys():
    for t in (CalibrationTarget("checkerboard", 6, 8, spacing_x_m=0.03, spacing_y_m=0.04),
              CalibrationTarget("aprilgrid", 6, 6, tag_size_m=0.088, tag_spacing=0.3)):
        assert target_from_kalibr(t.to_kalibr()) == t
