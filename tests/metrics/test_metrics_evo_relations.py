"""evo's remaining options on the real data: every pose relation, projection to a plane, and
RPE pairs from the reference; same numbers as evo's Python API (1e-9)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from metrics_gen import from_evo, load_evo, needs_data, smooth_trajectory

from ibiscape_eval.core import IbiscapeError
from ibiscape_eval.metrics import POSE_RELATIONS, ate, project_to_plane, rpe

GT, EST = "freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-rgbdslam.txt"
GT2, EST2 = "V102_groundtruth.csv", "V102.txt"


def _evo_relation(name: str) -> object:
    from evo.core.metrics import PoseRelation

    return {
        "trans": PoseRelation.translation_part,
        "rot-angle": PoseRelation.rotation_angle_deg,
        "rot-part": PoseRelation.rotation_part,
        "full": PoseRelation.full_transformation,
        "point-distance": PoseRelation.point_distance,
    }[name]


def _evo_pair(gt: str, est: str, plane: str | None) -> tuple[object, object]:
    from evo.core import sync
    from evo.core.trajectory import Plane

    ref_e, est_e = sync.associate_trajectories(load_evo(gt), load_evo(est), max_diff=0.01)
    est_e = copy.deepcopy(est_e)
    est_e.align(ref_e)  # type: ignore[attr-defined]
    if plane is not None:
        p = {"xy": Plane.XY, "xz": Plane.XZ, "yz": Plane.YZ}[plane]
        ref_e.project(p)  # type: ignore[attr-defined]
        est_e.project(p)  # type: ignore[attr-defined]
    return ref_e, est_e


def _close(ours: np.ndarray, theirs: np.ndarray) -> None:
    assert ours.shape == theirs.shape
    np.testing.assert_allclose(ours, theirs, rtol=1e-9, atol=1e-9)


@needs_data
@pytest.mark.parametrize("relation", POSE_RELATIONS)
@pytest.mark.parametrize("plane", [None, "xy", "xz", "yz"])
def test_ate_relations_and_planes_match_evo(relation: str, plane: str | None) -> None:
    from evo.core import metrics

    ref_e, est_e = _evo_pair(GT, EST, plane)
    res = ate(from_evo(load_evo(EST)), from_evo(load_evo(GT)), align="se3",
              pose_relation=relation, project_to_plane=plane)
    m = metrics.APE(_evo_relation(relation))
    m.process_data((ref_e, est_e))
    _close(res.errors, np.asarray(m.error))
    assert res.stats.rmse == pytest.approx(m.get_statistic(metrics.StatisticsType.rmse),
                                           rel=1e-9)
    doc = res.to_dict()
    assert doc["pose_relation"] == relation and doc["project_to_plane"] == plane


@needs_data
@pytest.mark.parametrize("relation", POSE_RELATIONS)
@pytest.mark.parametrize(("plane", "pairs_from"), [(None, "est"), (None, "ref"), ("xz", "ref"),
                                                   ("xy", "est")])
def test_rpe_relations_planes_pairs_from_match_evo(relation: str, plane: str | None,
                                                   pairs_from: str) -> None:
    from evo.core import metrics
    from evo.core.units import Unit

    ref_e, est_e = _evo_pair(GT2, EST2, plane)
    res = rpe(from_evo(load_evo(EST2)), from_evo(load_evo(GT2)), delta=0.5, delta_unit="metres",
              align="se3", pose_relation=relation, project_to_plane=plane, pairs_from=pairs_from)
    m = metrics.RPE(_evo_relation(relation), 0.5, Unit.meters,
                    pairs_from_reference=pairs_from == "ref")
    m.process_data((ref_e, est_e))
    _close(res.errors, np.asarray(m.error))
    assert res.to_dict()["pairs_from"] == pairs_from


@needs_data
def test_pairs_from_ref_differs_from_est() -> None:
    est_t, gt_t = from_evo(load_evo(EST2)), from_evo(load_evo(GT2))
    a = rpe(est_t, gt_t, delta=0.5, delta_unit="metres", align="se3", pairs_from="est")
    b = rpe(est_t, gt_t, delta=0.5, delta_unit="metres", align="se3", pairs_from="ref")
    assert a.n_pairs != b.n_pairs or not np.array_equal(a.first_index, b.first_index)


def test_projection_flattens_and_keeps_heading() -> None:
    traj = smooth_trajectory(50)
    flat = project_to_plane(traj, "xz")
    assert np.all(flat.pos_m[:, 1] == 0.0)
    np.testing.assert_array_equal(flat.pos_m[:, [0, 2]], traj.pos_m[:, [0, 2]])
    # only a rotation about y remains
    assert np.allclose(flat.quat_xyzw[:, [0, 2]], 0.0, atol=1e-12)


def test_relation_identities_on_generated_data() -> None:
    est = smooth_trajectory(200, seed=3)
    ref = smooth_trajectory(200, seed=4)
    full = ate(est, ref, align="se3", pose_relation="full")
    rot = ate(est, ref, align="se3", pose_relation="rot-part")
    np.testing.assert_allclose(full.errors**2, rot.errors**2 + full.errors_m**2, rtol=1e-12)
    assert np.all(rot.errors <= 2 * np.sqrt(2) + 1e-12)


@pytest.mark.parametrize("kw", [{"pose_relation": "angle"}, {"project_to_plane": "xw"}])
def test_bad_relation_or_plane_is_a_clear_error(kw: dict[str, str]) -> None:
    traj = smooth_trajectory(20)
    with pytest.raises(IbiscapeError, match="choose one of"):
        ate(traj, traj, **kw)  # type: ignore[arg-type]


def test_bad_pairs_from() -> None:
    traj = smooth_trajectory(20)
    with pytest.raises(IbiscapeError, match="'est' or 'ref'"):
        rpe(traj, traj, pairs_from="gt")


def test_result_repr_is_short_and_has_html() -> None:
    traj = smooth_trajectory(2000)
    res = ate(traj, traj)
    r = repr(res)
    assert r.startswith("AteResult(") and len(r.splitlines()) <= 6 and len(r) < 1200
    assert "rmse=" in r and "array" not in r
    h = res._repr_html_()
    assert h.startswith("<table>") and "<th>rmse</th>" in h
    rp = rpe(traj, traj)
    assert repr(rp).startswith("RpeResult(") and len(repr(rp)) < 1200
