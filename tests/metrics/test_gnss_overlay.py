"""GNSS fixes placed in a reference trajectory's frame (the ``--gps`` plot overlay)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli
from ibiscape_eval.io import read_gnss, read_trajectory
from ibiscape_eval.metrics import associate
from ibiscape_eval.metrics.gnss import gnss_in_reference_frame
from ibiscape_eval.sim import generate, preset


def test_ideal_gnss_lands_on_the_ground_truth(tmp_path: Path) -> None:
    seq = tmp_path / "seq"
    generate(preset("svi", "slam", "clear", duration_s=30.0, seed=4, ideal=True), seq)
    gt = read_trajectory(seq / "vehicle_gt" / "groundtruth_sync.csv", "ibiscape")
    fixes = read_gnss(seq / "other_sensors" / "gnss.csv")
    xyz = gnss_in_reference_frame(fixes.stamps_ns, fixes.lat_deg, fixes.lon_deg, fixes.alt_m, gt)
    ident = np.tile([0.0, 0.0, 0.0, 1.0], (len(xyz), 1))
    from ibiscape_eval.core import Trajectory

    m = associate(Trajectory(fixes.stamps_ns, xyz, ident), gt, max_diff_s=0.001)
    # the antenna sits 0.2 m ahead of and 2.8 m above the body origin: a 4-DoF fit absorbs the
    # constant height, and the horizontal residual is the rotating 0.2 m lever arm at most
    horiz = np.linalg.norm(m.est.pos_m[:, :2] - m.ref.pos_m[:, :2], axis=1)
    assert len(m.est) >= 25 and horiz.max() < 0.25
    assert np.abs(m.est.pos_m[:, 2] - m.ref.pos_m[:, 2]).max() < 0.01


def test_cli_plot_with_gps(tmp_path: Path) -> None:
    seq = tmp_path / "seq"
    generate(preset("svi", "slam", "clear", duration_s=20.0, seed=5), seq)
    gt = seq / "vehicle_gt" / "groundtruth_sync.csv"
    res = CliRunner().invoke(
        cli,
        [
            "ate",
            str(gt),
            str(gt),
            "--gps",
            str(seq / "other_sensors" / "gnss.csv"),
            "--plot",
            str(tmp_path / "p.png"),
            "--json",
        ],
        catch_exceptions=False,
    )
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["translation_m"]["max"] < 1e-9
    assert (tmp_path / "p.png").stat().st_size > 20_000
