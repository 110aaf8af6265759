"""evo's remaining everyday options give evo's numbers on the real trajectories (1e-9):
``--t_start/--t_end``, ``--downsample``, ``--motion_filter``, RPE ``--delta_tol`` and
``--change_unit``, each run through evo's own pipeline order (filter, cut the reference's time
range, associate, align, metric)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from metrics_gen import from_evo, load_evo, needs_data

from ibiscape_eval.core import IbiscapeError
from ibiscape_eval.metrics import ate, downsample, motion_filter, rpe, time_range

pytestmark = needs_data

GT, EST = "freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-rgbdslam.txt"
STATS = ("rmse", "mean", "median", "std", "min", "max", "sse")


def _evo_ape(ref_e: object, est_e: object, *, max_diff: float = 0.01, unit: object = None
             ) -> tuple[int, dict[str, float]]:
    from evo.core import metrics, sync

    r, e = sync.associate_trajectories(ref_e, est_e, max_diff=max_diff)
    e = copy.deepcopy(e)
    e.align(r)  # type: ignore[attr-defined]
    m = metrics.APE(metrics.PoseRelation.translation_part)
    m.process_data((r, e))
    if unit is not None:
        m.change_unit(unit)
    return r.num_poses, m.get_all_statistics()  # type: ignore[attr-defined]


def _same(ours: dict[str, float], theirs: dict[str, float]) -> None:
    for k in STATS:
        assert ours[k] == pytest.approx(theirs[k], rel=1e-9, abs=1e-15), k


def test_time_range_matches_evo() -> None:
    ref_e, est_e = load_evo(GT), load_evo(EST)
    t0 = float(ref_e.timestamps[0]) + 3.0  # type: ignore[attr-defined]
    t1 = t0 + 12.5
    ref_e.reduce_to_time_range(t0, t1)  # type: ignore[attr-defined]
    n, stats = _evo_ape(ref_e, est_e)
    res = ate(from_evo(load_evo(EST)), from_evo(load_evo(GT)), t_start_s=t0, t_end_s=t1)
    assert res.n_matched == n and 0 < n < 700
    _same(res.translation_m.to_dict(), stats)


def test_downsample_matches_evo() -> None:
    ref_e, est_e = load_evo(GT), load_evo(EST)
    ref_e.downsample(400)  # type: ignore[attr-defined]
    est_e.downsample(400)  # type: ignore[attr-defined]
    np.testing.assert_array_equal(downsample(from_evo(load_evo(GT)), 400).stamps_ns,
                                  from_evo(ref_e).stamps_ns)
    n, stats = _evo_ape(ref_e, est_e)
    res = ate(from_evo(load_evo(EST)), from_evo(load_evo(GT)), downsample=400)
    assert res.n_matched == n and n > 20
    _same(res.translation_m.to_dict(), stats)


@pytest.mark.parametrize(("dist_m", "angle_deg"), [(0.05, 5.0), (0.0, 0.0), (0.2, 1.0)])
def test_motion_filter_matches_evo(dist_m: float, angle_deg: float) -> None:
    ref_e, est_e = load_evo(GT), load_evo(EST)
    ref_e.motion_filter(dist_m, angle_deg, True)  # type: ignore[attr-defined]
    est_e.motion_filter(dist_m, angle_deg, True)  # type: ignore[attr-defined]
    ours_ref = motion_filter(from_evo(load_evo(GT)), dist_m, angle_deg)
    np.testing.assert_array_equal(ours_ref.stamps_ns, from_evo(ref_e).stamps_ns)
    np.testing.assert_array_equal(motion_filter(from_evo(load_evo(EST)), dist_m, angle_deg)
                                  .stamps_ns, from_evo(est_e).stamps_ns)
    n, stats = _evo_ape(ref_e, est_e)
    res = ate(from_evo(load_evo(EST)), from_evo(load_evo(GT)), motion_filter=(dist_m, angle_deg))
    assert res.n_matched == n
    _same(res.translation_m.to_dict(), stats)


@pytest.mark.parametrize("tol", [0.02, 0.3])
def test_rpe_delta_tol_matches_evo(tol: float) -> None:
    from evo.core import metrics, sync
    from evo.core.units import Unit

    r, e = sync.associate_trajectories(load_evo(GT), load_evo(EST), max_diff=0.01)
    m = metrics.RPE(metrics.PoseRelation.translation_part, 0.2, Unit.meters,
                    rel_delta_tol=tol, all_pairs=True)
    m.process_data((r, e))
    res = rpe(from_evo(load_evo(EST)), from_evo(load_evo(GT)), delta=0.2, delta_unit="metres",
              pairs="all", rel_tol=tol)
    assert res.n_pairs == len(m.error)
    _same(res.translation_m.to_dict(), m.get_all_statistics())
    assert res.to_dict()["delta_tol"] == tol


@pytest.mark.parametrize("unit", ["cm", "mm"])
def test_change_unit_matches_evo(unit: str) -> None:
    from evo.core.metrics import Unit

    evo_unit = {"cm": Unit.centimeters, "mm": Unit.millimeters}[unit]
    _, stats = _evo_ape(load_evo(GT), load_evo(EST), unit=evo_unit)
    res = ate(from_evo(load_evo(EST)), from_evo(load_evo(GT)))
    doc = res.to_dict(unit=unit)
    assert "translation_m" not in doc and doc["length_unit"] == unit
    _same(doc[f"translation_{unit}"], stats)
    frame = res.to_frame(unit=unit)
    np.testing.assert_allclose(frame[f"error_{unit}"], res.errors_m * (100 if unit == "cm" else 1000))


def test_selection_refuses_what_it_cannot_do() -> None:
    gt = from_evo(load_evo(GT))
    with pytest.raises(IbiscapeError, match="no pose"):
        time_range(gt, 1.0, 2.0)  # absolute times, like evo: the file starts at 1.3e9 s
    with pytest.raises(IbiscapeError, match="starts after it ends"):
        time_range(gt, 5.0, 2.0)
    with pytest.raises(IbiscapeError, match="positive"):
        downsample(gt, 0)
    with pytest.raises(IbiscapeError, match=">= 0"):
        motion_filter(gt, -1.0, 2.0)
    synthetic = type(gt)(gt.stamps_ns, gt.pos_m, gt.quat_xyzw, "k.txt", stamps_synthetic=True)
    with pytest.raises(IbiscapeError, match="no real timestamps"):
        time_range(synthetic, 0.0, 1.0)
    assert len(downsample(gt, 10)) == 10 and downsample(gt, 10 ** 6) is gt
