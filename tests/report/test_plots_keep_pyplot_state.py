"""Library plots draw on their own Figure: the caller's backend and pyplot figures survive."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np
import pytest

from ibiscape_eval.core import Trajectory


@pytest.fixture
def svg_backend():
    """A backend other than the Agg the library used to force, restored afterwards."""
    import matplotlib.pyplot as plt

    old = matplotlib.get_backend()
    plt.switch_backend("svg")
    fig = plt.figure()  # the notebook user's open figure
    yield fig
    plt.close(fig)
    plt.switch_backend(old)


def _traj(n: int, rng: np.random.Generator, name: str) -> Trajectory:
    t = np.arange(n, dtype=np.int64) * 100_000_000
    pos = np.cumsum(rng.normal(size=(n, 3)), axis=0)
    q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    return Trajectory(t, pos, q, name)


def test_plot_functions_leave_backend_and_figures_alone(svg_backend, tmp_path: Path) -> None:
    import matplotlib.pyplot as plt

    from ibiscape_eval.events import detect_hot_pixels, synthetic_events
    from ibiscape_eval.events.plots import hot_pixel_figure
    from ibiscape_eval.imu import allan_deviation, fit_noise_model
    from ibiscape_eval.metrics import ate, drift
    from ibiscape_eval.report.plots import plot_allan, plot_drift, plot_trajectory_errors

    before = plt.get_fignums()
    rng = np.random.default_rng(0)
    ref = _traj(400, rng, "ref")
    est = Trajectory(ref.stamps_ns, ref.pos_m + rng.normal(0, 0.05, ref.pos_m.shape),
                     ref.quat_xyzw, "est")
    res = ate(est, ref)
    plot_trajectory_errors(tmp_path / "ate.png", est_aligned=res.est_aligned, ref=res.ref,
                           stamps_ns=res.stamps_ns, errors_m=res.errors_m,
                           errors_deg=res.errors_deg, title="ate")
    d = drift(est, ref, lengths_m=(10.0, 20.0))
    plot_drift(tmp_path / "drift.png", d, title="drift")
    y = rng.normal(size=(20_000, 6))
    adev = allan_deviation(y, 100.0)
    plot_allan(tmp_path / "allan.png", adev, fit_noise_model(adev), title="allan")
    ev = synthetic_events(sensor_size=(64, 48), duration_s=0.1, seed=1).events
    fig = hot_pixel_figure(detect_hot_pixels(ev.x, ev.y, sensor_size=(64, 48), top_n=3))
    fig.savefig(tmp_path / "hot.png")

    assert matplotlib.get_backend() == "svg"
    assert plt.get_fignums() == before
    for name in ("ate", "drift", "allan", "hot"):
        assert (tmp_path / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
