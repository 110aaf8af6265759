"""The notebook API: ``from ibiscape_eval import ...`` reaches every capability, ``dir()`` lists
only public names, and the main results draw themselves (``.plot()`` returns a Figure with the
expected axes and lines, pyplot untouched)."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import ibiscape_eval
from ibiscape_eval.core.trajectory import Trajectory

CAPABILITIES = ("ate", "rpe", "drift", "compare", "allan_deviation", "fit_noise_model",
                "NoiseModel", "calibrate_cameras", "calibrate_imu_camera", "run_vio", "simulate",
                "sim_preset", "hot_pixels", "detect_hot_pixels", "discover_runs", "evaluate_runs",
                "write_report", "open_sequence", "read_trajectory", "read_imu", "open_events")


def test_dir_shows_the_public_names_only() -> None:
    names = dir(ibiscape_eval)
    assert set(CAPABILITIES) <= set(names)
    assert set(ibiscape_eval.__all__) <= set(names)
    for private in ("TYPE_CHECKING", "annotations", "lazy_exports", "_EXPORTS", "core", "io"):
        assert private not in names
    assert [n for n in names if n.startswith("_")] == ["__all__", "__version__"]


@pytest.mark.parametrize("name", sorted(ibiscape_eval.__all__))
def test_every_export_resolves(name: str) -> None:
    assert getattr(ibiscape_eval, name) is not None


def test_simulate_is_the_generator_entry_point() -> None:
    from ibiscape_eval.sim import generate, preset

    assert ibiscape_eval.simulate is generate and ibiscape_eval.sim_preset is preset


def test_import_stays_light() -> None:
    code = ("import sys, ibiscape_eval; "
            "print(any(m in sys.modules for m in ('numpy', 'matplotlib', 'gtsam', 'cv2')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# ------------------------------------------------------------------------------------- .plot()
def _traj(n: int, noise: float, seed: int, name: str) -> Trajectory:
    t = np.arange(n) * 0.1
    pos = np.column_stack([10 * np.cos(0.05 * t), 10 * np.sin(0.05 * t), 0.3 * np.sin(t)])
    pos = pos + np.random.default_rng(seed).normal(0.0, noise, pos.shape)
    yaw = 0.05 * t + np.pi / 2
    quat = np.column_stack([np.zeros(n), np.zeros(n), np.sin(yaw / 2), np.cos(yaw / 2)])
    return Trajectory((t * 1e9).round().astype(np.int64), pos, quat, name)


@pytest.fixture(scope="module")
def pair() -> tuple[Trajectory, Trajectory]:
    return _traj(400, 0.05, 1, "est"), _traj(400, 0.0, 0, "gt")


def _line_labels(fig) -> set[str]:
    return {ln.get_label() for ax in fig.axes for ln in ax.get_lines()}


def test_ate_result_plot(pair) -> None:
    from matplotlib.figure import Figure

    res = ibiscape_eval.ate(*pair, align="se3")
    fig = res.plot()
    assert isinstance(fig, Figure) and fig.get_suptitle() == "absolute trajectory error"
    # four panels and the colour bar; the estimate coloured by its error, rmse as a line
    assert len(fig.axes) == 5
    labels = _line_labels(fig)
    assert "gt" in labels or "reference" in labels
    assert any(lb.startswith("rmse ") for lb in labels)
    time_ax = next(ax for ax in fig.axes if ax.get_xlabel() == "time since start [s]")
    err = next(ln for ln in time_ax.get_lines() if ln.get_label() == "translation error")
    assert np.allclose(err.get_ydata(), res.errors_m)
    assert len(res.plot(panels=["histogram"], title="x").axes) == 1


def test_rpe_result_plot(pair) -> None:
    res = ibiscape_eval.rpe(*pair, delta=1.0, delta_unit="metres")
    fig = res.plot()
    assert fig.get_suptitle() == "relative pose error"
    time_ax = next(ax for ax in fig.axes if ax.get_xlabel() == "time since start [s]")
    assert len(time_ax.get_lines()[0].get_xdata()) == res.n_pairs


def test_drift_result_plot(pair) -> None:
    res = ibiscape_eval.drift(*pair, lengths_m=(2.0, 4.0))
    fig = res.plot()
    assert fig.axes and fig.get_suptitle() == "drift per segment length"
    # two panels (translation, rotation), the lengths as tick labels, a segment count per box
    assert len(fig.axes) == 2
    assert [t.get_text() for t in fig.axes[0].get_xticklabels()] == ["2", "4"]
    counts = [t.get_text() for t in fig.axes[0].texts]
    assert counts == [f"n={int(n)}" for n in res.n_segments]


def test_compare_result_plot(pair) -> None:
    est, gt = pair
    res = ibiscape_eval.compare(gt, [est, _traj(400, 0.1, 2, "b")], align="origin")
    fig = res.plot()
    assert fig.axes and "2 estimates" in fig.get_suptitle()


def test_allan_result_plot() -> None:
    rng = np.random.default_rng(3)
    samples = np.cumsum(rng.normal(0, 1e-4, (20_000, 6)), axis=0) * 1e-3 + rng.normal(0, 1e-2, (20_000, 6))
    res = ibiscape_eval.allan_deviation(samples, 100.0)
    fig = res.plot()
    assert len(fig.axes) >= 2  # gyro and accelerometer
    curves = [ln for ax in fig.axes for ln in ax.get_lines() if len(ln.get_xdata()) == res.taus_s.size]
    assert len(curves) >= 6  # one curve per axis
    assert fig.get_suptitle() == "overlapping Allan deviation" or any(
        ax.get_title() for ax in fig.axes)


def test_hot_pixels_result_plot(tmp_path: Path) -> None:
    from ibiscape_eval.events.synthetic import synthetic_events
    from ibiscape_eval.io.events import write_events

    stream = synthetic_events(sensor_size=(32, 24), duration_s=0.2, n_hot=3, seed=1)
    write_events(tmp_path / "ev.npz", stream.events, sensor_size=stream.sensor_size)
    run = ibiscape_eval.hot_pixels(tmp_path / "ev.npz", sensor_size=(32, 24))
    assert {tuple(p) for p in run.result.pixels} == {tuple(p) for p in stream.hot_pixels}
    assert run.sensor_size == (32, 24) and not run.size_inferred
    assert run.size_from == "sensor_size"
    assert ibiscape_eval.hot_pixels(tmp_path / "ev.npz").size_inferred
    fig = run.plot()
    assert len(fig.axes) >= 2 and "hot-pixel removal" in fig.get_suptitle()


def test_hot_pixels_refuses_a_list_with_thresholds(tmp_path: Path) -> None:
    from ibiscape_eval.events.pipeline import HotPixelCriteria

    with pytest.raises(ibiscape_eval.IbiscapeError, match="apply_path uses a given") as ei:
        ibiscape_eval.hot_pixels(tmp_path / "none.npz", HotPixelCriteria(top_n=3),
                                 apply_path=tmp_path / "hot.txt")
    assert [r.option for r in ei.value.hint] == ["apply_path", "top_n", "n_sigma",
                                                 "rate_min_events"]


def test_camera_calibration_result_plot() -> None:
    sys.path.insert(0, str(Path(__file__).parent / "calib"))
    from _calib_scenes import stereo_scene

    from ibiscape_eval.calib.calibrate import calibrate

    target, _cams, _T10, _, _, obs = stereo_scene("checkerboard", n_views=4)
    res = calibrate(target, obs)
    fig = res.plot(1)
    scatter = fig.axes[0].collections[0]
    assert len(scatter.get_offsets()) == len(res.cameras[1].residuals_px)
    assert res.plot(0, kind="coverage").axes


def test_vio_result_plot(pair) -> None:
    from ibiscape_eval.vio.estimator import FailureSpan
    from ibiscape_eval.vio.pipeline import VioResult, VioStats

    est, gt = pair
    fail = (FailureSpan("tracking", est.stamps_ns[100], est.stamps_ns[120]),)
    blank = {f.name: (fail if f.name == "failures" else "" if f.type == "str"
                      else {} if "dict" in str(f.type) else 0)
             for f in dataclasses.fields(VioStats)}
    fig = VioResult(est, VioStats(**blank)).plot(gt, title="vio")
    labels = _line_labels(fig)
    assert any(lb.startswith("ground truth") for lb in labels)
    assert any("tracking failure" in lb for lb in labels)
