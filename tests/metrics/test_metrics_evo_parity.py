"""Same numbers as evo on the real data: association counts, ATE and RPE statistics (1e-9)."""

from __future__ import annotations

import copy

import pytest
from metrics_gen import from_evo, load_evo, needs_data

from ibiscape_eval.metrics import ate, rpe

pytestmark = needs_data

CASES = [
    ("freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-rgbdslam.txt", "se3", 0.2),
    ("V102_groundtruth.csv", "V102.txt", "se3", 0.5),
    ("freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-ORB_kf_mono.txt", "sim3", 0.1),
]
STATS = ("rmse", "mean", "median", "std", "min", "max", "sse")


def _evo_pair(gt: str, est: str, method: str) -> tuple[object, object]:
    from evo.core import sync

    ref_e, est_e = sync.associate_trajectories(load_evo(gt), load_evo(est), max_diff=0.01)
    est_e = copy.deepcopy(est_e)
    est_e.align(ref_e, correct_scale=method == "sim3")  # type: ignore[attr-defined]
    return ref_e, est_e


def _assert_stats(ours: object, theirs: dict[str, float]) -> None:
    for key in STATS:
        assert getattr(ours, key) == pytest.approx(theirs[key], rel=1e-9, abs=1e-15), key


@pytest.mark.parametrize(("gt", "est", "method", "delta_m"), CASES)
def test_ate_matches_evo(gt: str, est: str, method: str, delta_m: float) -> None:
    from evo.core import metrics

    ref_e, est_e = _evo_pair(gt, est, method)
    res = ate(from_evo(load_evo(est)), from_evo(load_evo(gt)), align=method)
    assert res.n_matched == ref_e.num_poses  # type: ignore[attr-defined]
    for relation, ours in ((metrics.PoseRelation.translation_part, res.translation_m),
                           (metrics.PoseRelation.rotation_angle_deg, res.rotation_deg)):
        m = metrics.APE(relation)
        m.process_data((ref_e, est_e))
        _assert_stats(ours, m.get_all_statistics())


@pytest.mark.parametrize(("gt", "est", "method", "delta_m"), CASES)
@pytest.mark.parametrize("pairs", ["consecutive", "all"])
def test_rpe_matches_evo(gt: str, est: str, method: str, delta_m: float, pairs: str) -> None:
    from evo.core import metrics
    from evo.core.units import Unit

    ref_e, est_e = _evo_pair(gt, est, method)
    est_t, gt_t = from_evo(load_evo(est)), from_evo(load_evo(gt))
    for delta, unit, evo_unit in ((1, "frames", Unit.frames), (delta_m, "metres", Unit.meters)):
        res = rpe(est_t, gt_t, delta=delta, delta_unit=unit, pairs=pairs, align=method)
        for relation, ours in ((metrics.PoseRelation.translation_part, res.translation_m),
                               (metrics.PoseRelation.rotation_angle_deg, res.rotation_deg)):
            m = metrics.RPE(relation, delta, evo_unit, all_pairs=pairs == "all")
            m.process_data((ref_e, est_e))
            assert res.n_pairs == len(m.error), (unit, relation)
            _assert_stats(ours, m.get_all_statistics())


def test_rpe_degrees_consecutive_matches_evo() -> None:
    from evo.core import metrics
    from evo.core.units import Unit

    gt, est = CASES[0][:2]
    ref_e, est_e = _evo_pair(gt, est, "se3")
    res = rpe(from_evo(load_evo(est)), from_evo(load_evo(gt)), delta=5.0, delta_unit="degrees",
              align="se3")
    m = metrics.RPE(metrics.PoseRelation.translation_part, 5.0, Unit.degrees)
    m.process_data((ref_e, est_e))
    assert res.n_pairs == len(m.error)
    _assert_stats(res.translation_m, m.get_all_statistics())
