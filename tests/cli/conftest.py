"""Fixtures for command-line tests: run ``ibiscape-eval`` in-process through click's runner."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from _cli_data import write_tum
from click.testing import CliRunner, Result

from ibiscape_eval.cli.main import cli


@pytest.fixture
def run_cli() -> Callable[..., Result]:
    def run(*args: object) -> Result:
        return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)

    return run


@pytest.fixture
def tum_pair(tmp_path: Path) -> tuple[Path, Path]:
    """A curvy 3-D ground truth at 20 Hz and a noisy estimate of it (same stamps)."""
    rng = np.random.default_rng(5)
    n = 300
    t = 100.0 + np.arange(n) * 0.05
    pos = np.column_stack([np.cos(t / 3) * 5, np.sin(t / 2) * 4, 0.3 * np.sin(t)])
    yaw = t / 5
    quat = np.column_stack([np.zeros(n), np.zeros(n), np.sin(yaw / 2), np.cos(yaw / 2)])
    gt = write_tum(tmp_path / "gt.txt", t, pos, quat)
    est = write_tum(tmp_path / "est.txt", t, pos + rng.normal(0, 0.02, pos.shape), quat)
    return est, gt
