"""What the figures draw: labels, legends, no offset notation, the error-coloured trajectory."""

from __future__ import annotations

import numpy as np
import pytest

from ibiscape_eval.core import Trajectory
from ibiscape_eval.core.rotations import quat_from_rotvec


def _pair(n: int = 300) -> tuple[Trajectory, Trajectory]:
    rng = np.random.default_rng(0)
    t = np.arange(n) / 10.0
    pos = np.stack([np.cos(0.2 * t) * 20, np.sin(0.2 * t) * 20, 0.1 * t], 1)
    stamps = (1_400_000_000 + t * 1e9).astype(np.int64) * 1  # large epoch
    ref = Trajectory(stamps, pos, quat_from_rotvec(np.c_[0 * t, 0 * t, 0.2 * t]), "gt.txt")
    est = Trajectory(stamps, pos + rng.normal(0, 0.05, pos.shape), ref.quat_xyzw, "est.txt")
    return est, ref


def _texts(fig: object) -> str:
    out = []
    for ax in fig.axes:  # type: ignore[attr-defined]
        out += [ax.get_xlabel(), ax.get_ylabel(), ax.get_title()]
        leg = ax.get_legend()
        if leg is not None:
            out += [t.get_text() for t in leg.get_texts()]
    sup = fig._suptitle  # type: ignore[attr-defined]
    if sup is not None:
        out.append(sup.get_text())
    return "\n".join(out)


def _no_offsets(fig: object) -> None:
    fig.canvas.draw()  # type: ignore[attr-defined]
    for ax in fig.axes:  # type: ignore[attr-defined]
        for axis in (ax.xaxis, ax.yaxis):
            assert axis.get_offset_text().get_text() == "", ax.get_ylabel()


def test_constant_rotation_error_has_no_offset_notation() -> None:
    from ibiscape_eval.report.plots import trajectory_errors_figure

    est, ref = _pair()
    err = np.full(len(ref), 0.3096) + np.linspace(0, 1e-8, len(ref))
    fig = trajectory_errors_figure(est_aligned=est, ref=ref, stamps_ns=ref.stamps_ns,
                                   errors_m=err, errors_deg=err, errors=err,
                                   error_label="rotation error", error_unit="deg")
    _no_offsets(fig)


def test_trajectory_panel_is_coloured_by_error_with_colorbar_and_stat_lines() -> None:
    from matplotlib.collections import LineCollection

    from ibiscape_eval.metrics import ate
    from ibiscape_eval.report.plots import trajectory_errors_figure

    est, ref = _pair()
    res = ate(est, ref)
    fig = trajectory_errors_figure(est_aligned=res.est_aligned, ref=res.ref,
                                   stamps_ns=res.stamps_ns, errors_m=res.errors_m,
                                   errors_deg=res.errors_deg, plane="xz", aligned="se3",
                                   distance_m=res.ref.path_length_m())
    traj_ax = fig.axes[0]
    lcs = [c for c in traj_ax.collections if isinstance(c, LineCollection)]
    assert lcs and np.allclose(np.sort(lcs[0].get_array())[-1], res.errors_m.max())
    assert traj_ax.get_xlabel() == "x [m]" and traj_ax.get_ylabel() == "z [m]"
    text = _texts(fig)
    assert "estimate, aligned (se3)" in text
    for word in ("rmse", "mean", "median", "std"):
        assert word in text
    assert "/" not in (fig._suptitle.get_text() if fig._suptitle else "")
    assert any(ax.get_label() == "<colorbar>" for ax in fig.axes)
    _no_offsets(fig)


def test_single_panel_and_unaligned_label() -> None:
    from ibiscape_eval.report.plots import trajectory_errors_figure

    est, ref = _pair()
    fig = trajectory_errors_figure(est_aligned=est, ref=ref, stamps_ns=ref.stamps_ns,
                                   errors_m=np.ones(len(ref)), errors_deg=np.ones(len(ref)),
                                   panels=["trajectory"], aligned="none")
    assert len([a for a in fig.axes if a.get_label() != "<colorbar>"]) == 1
    assert "estimate, not aligned" in _texts(fig)
    with pytest.raises(ValueError, match="panel"):
        trajectory_errors_figure(est_aligned=est, ref=ref, stamps_ns=ref.stamps_ns,
                                 errors_m=np.ones(len(ref)), errors_deg=np.ones(len(ref)),
                                 panels=["map"])


def test_drift_box_plots_with_exact_lengths() -> None:
    from ibiscape_eval.metrics import drift
    from ibiscape_eval.report.plots import drift_figure

    est, ref = _pair(600)
    d = drift(est, ref, lengths_m=(2.5, 10.0, 20.0))
    fig = drift_figure(d)
    labels = [t.get_text() for t in fig.axes[0].get_xticklabels()]
    assert labels == ["2.5", "10", "20"]
    assert fig.axes[0].get_ylabel() == "translation error [%]"
    _no_offsets(fig)


def test_allan_legend_explains_markers_and_units_are_typeset() -> None:
    from ibiscape_eval.imu import allan_deviation, fit_noise_model
    from ibiscape_eval.report.plots import allan_figure

    rng = np.random.default_rng(1)
    y = rng.normal(size=(20_000, 6))
    res = allan_deviation(y, 100.0)
    fig = allan_figure(res, fit_noise_model(res))
    text = _texts(fig)
    assert "m/s$^2$" in fig.axes[1].get_ylabel()
    for needle in ("N: slope", "K: slope", "B: minimum", "w_x", "a_z"):
        assert needle in text
    for ax in fig.axes:
        leg = ax.get_legend()
        assert leg is not None and not leg.get_title().get_text()


def test_hot_pixel_figure_shows_silent_pixels_and_log_histogram() -> None:
    from ibiscape_eval.events import detect_hot_pixels, synthetic_events
    from ibiscape_eval.events.plots import hot_pixel_figure

    ev = synthetic_events(sensor_size=(64, 48), duration_s=0.05, seed=1).events
    res = detect_hot_pixels(ev.x, ev.y, sensor_size=(64, 48), top_n=3)
    assert (res.count_map == 0).any()
    fig = hot_pixel_figure(res)
    ax_h, ax_m = fig.axes[0], fig.axes[1]
    assert ax_h.get_xscale() == "log" and ax_h.get_yscale() == "log"
    assert "silent" in _texts(fig)
    img = ax_m.get_images()[0]
    rgba = img.to_rgba(img.get_array())
    silent = rgba[res.count_map == 0]
    assert np.allclose(silent, silent[0]) and not np.allclose(silent[0], img.cmap(0.0))


def test_other_results_have_short_repr_and_dict() -> None:
    import json

    from ibiscape_eval.events import accumulate_frames, detect_hot_pixels, synthetic_events
    from ibiscape_eval.metrics import ate

    est, ref = _pair(2000)
    al = ate(est, ref).alignment
    assert len(repr(al)) < 200 and "array" not in repr(al)
    json.dumps(al.to_dict(), allow_nan=False)
    ev = synthetic_events(sensor_size=(64, 48), duration_s=0.2, seed=1).events
    hot = detect_hot_pixels(ev.x, ev.y, sensor_size=(64, 48), top_n=3)
    assert hot._repr_html_().startswith("<table>")
    fr = accumulate_frames(ev, sensor_size=(64, 48), rate_hz=20)
    assert repr(fr).startswith("EventFrames(") and len(repr(fr)) < 200
    json.dumps(fr.to_dict(), allow_nan=False)
