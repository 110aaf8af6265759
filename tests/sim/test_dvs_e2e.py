"""End to end: ``ibiscape-eval sim`` renders a dynamic-weather ESVI sequence (small), and
``ibiscape-eval hotpix`` finds exactly the pixels that ``sequence.yaml`` records as made noisy by
rain and fog (precision and recall >= 0.95, both cameras)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli
from ibiscape_eval.io.events import read_events, read_hot_pixels
from ibiscape_eval.io.sequence import read_sequence_yaml


def test_sim_then_hotpix_finds_the_recorded_noisy_pixels(tmp_path: Path) -> None:
    seq = tmp_path / "ESVI_1_calib"
    conf = tmp_path / "loop.yaml"  # the paper's approach loop: driving at speed from the start
    conf.write_text("motion:\n  calibration_drive: loop\n")
    r = CliRunner().invoke(cli, ["sim", "--setup", "esvi", "--kind", "calibration", "--weather",
                                 "dynamic", "--resolution", "96", "--duration-s", "3", "--seed",
                                 "2", "--config", str(conf), "--out", str(seq)], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    doc = read_sequence_yaml(seq / "sequence.yaml")
    for cam in ("davisL", "davisR"):
        dvs = doc["cameras"][cam]["dvs"]
        assert (dvs["positive_threshold"], dvs["negative_threshold"]) == (0.3, 0.3)  # the sensor's settings
        truth = {tuple(p) for p in dvs["noisy_pixels"]}
        assert len(truth) == round(0.001 * 96 * 96)
        assert 0.1 < dvs["noise_fraction"] < 0.5  # rain ~45 %, fog ~70 %: about a quarter
        ev = read_events(seq / cam)
        assert len(ev) == dvs["n_events"] and np.all(np.diff(ev.t_ns) >= 0)
        hot = tmp_path / f"hot_{cam}.txt"
        h = CliRunner().invoke(cli, ["hotpix", str(seq / cam), "--sensor-size", "96x96",
                                     "--hot-out", str(hot)], catch_exceptions=False)
        assert h.exit_code == 0, h.output
        found = {tuple(map(int, p)) for p in read_hot_pixels(hot)}
        tp = len(found & truth)
        assert tp / max(len(found), 1) >= 0.95 and tp / len(truth) >= 0.95, (cam, found, truth)
