"""Every capability has a notebook-style script in ``examples/`` and each one runs: as a user
would (``python examples/<name>.py`` in a fresh process and an empty working folder), on small
generated data (``IBISCAPE_EXAMPLE_SCALE`` shortens the generated recordings)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

#: capability -> its script (the library calls it shows)
SCRIPTS = {
    "ate, rpe, drift": "trajectory_metrics.py",
    "compare": "compare_estimates.py",
    "allan": "allan_imu_noise.py",
    "calibrate_cameras": "calibrate_cameras.py",
    "calibrate_imu_camera": "calibrate_imu_camera.py",
    "run_vio": "vio_baseline.py",
    "simulate": "sim_sequence.py",
    "hot pixels": "hotpix_filter.py",
    "report": "report_runs.py",
}


def test_every_capability_has_a_script() -> None:
    assert all((EXAMPLES / s).is_file() for s in SCRIPTS.values())


@pytest.mark.parametrize("script", sorted(SCRIPTS.values()))
def test_example_runs(script: str, tmp_path: Path) -> None:
    env = {**os.environ, "IBISCAPE_EXAMPLE_SCALE": "0.1", "MPLBACKEND": "Agg"}
    res = subprocess.run([sys.executable, str(EXAMPLES / script)], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=600, check=False)
    assert res.returncode == 0, res.stderr[-3000:]
    assert res.stdout.strip()  # it shows its results
    assert "Traceback" not in res.stderr
