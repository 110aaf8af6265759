"""ESVI: the VIO on stereo event frames, on a small generated sequence (128x96 DVS pair,
6 s, standstill start), against the generator's truth; causality of the frames; bad input."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli
from ibiscape_eval.core.errors import CalibrationError, FormatError
from ibiscape_eval.io.open_sequence import open_sequence
from ibiscape_eval.metrics import ate
from ibiscape_eval.sim import generate, preset
from ibiscape_eval.sim.config import with_resolution
from ibiscape_eval.vio.events_input import EsviOptions, event_stereo_frames
from ibiscape_eval.vio.inputs import resolve_setup, stereo_inputs
from ibiscape_eval.vio.pipeline import run_vio


@pytest.fixture(scope="module")
def esvi_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("esvi") / "ESVI_1_town"
    generate(with_resolution(preset("esvi", "slam", "clear", duration_s=6.0, seed=3), 128, 96), out,
             render=True)
    return out


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


@pytest.mark.filterwarnings("ignore:the rotation of the yaw alignment")
def test_esvi_runs_on_the_event_pair_within_the_truth(esvi_folder: Path) -> None:
    seq = open_sequence(esvi_folder)
    assert resolve_setup(seq) == "esvi"
    res = run_vio(seq)
    s = res.stats
    assert s.setup == "esvi" and s.frames == 120
    # the vehicle stands still for the first second or so (no events, no features): those
    # frames are not usable, the driving ones are
    assert 60 <= s.usable_frames < s.frames
    # tracking loss is reported as spans (IMU only, smoother resets), never a divergence
    assert s.failures and all(f.kind != "diverged" for f in s.failures)
    gt = seq.ground_truth()
    assert gt is not None
    a = ate(res.trajectory, gt, align="yaw", max_diff_s=0.02)
    length = float(a.ref.path_length_m()[-1])
    assert length > 10.0
    # a coarse 128 px DVS (0.09 % at 346x260 over 15 s)
    assert a.translation_m.rmse < 0.05 * length


def test_esvi_frames_are_causal(esvi_folder: Path, tmp_path: Path) -> None:
    """Frame i uses only events up to its window's end: deleting every later window changes nothing
    (the log-intensity reconstruction, which carries a memory across windows)."""
    i = 60
    seq = open_sequence(esvi_folder)
    _, reader, _ = event_stereo_frames(seq, "davisL", "davisR", EsviOptions("log-intensity", tau_s=0.1))
    full = [reader(k) for k in range(i + 1)][-1]
    cut = _copy(esvi_folder, tmp_path / "cut")
    for cam in ("davisL", "davisR"):
        lines = (cut / cam / "timestamps.csv").read_text().splitlines(keepends=True)
        (cut / cam / "timestamps.csv").write_text("".join(lines[: i + 2]))  # header + i+1 windows
        for f in sorted((cut / cam / "events").glob("*.npz"))[i + 1:]:
            f.unlink()
    _, reader2, _ = event_stereo_frames(open_sequence(cut), "davisL", "davisR",
                                        EsviOptions("log-intensity", tau_s=0.1))
    short = [reader2(k) for k in range(i + 1)][-1]
    assert full[0].std() > 5  # a frame with texture, not a blank one
    np.testing.assert_array_equal(full[0], short[0])
    np.testing.assert_array_equal(full[1], short[1])


def test_esvi_reconstructions_differ(esvi_folder: Path) -> None:
    seq = open_sequence(esvi_folder)
    frames = {}
    for m in ("log-intensity", "accumulate-signed", "time-surface"):
        _, reader, _ = event_stereo_frames(seq, "davisL", "davisR", EsviOptions(m))
        frames[m] = [reader(k) for k in range(41)][-1][0]
    assert not np.array_equal(frames["log-intensity"], frames["accumulate-signed"])
    with pytest.raises(Exception, match="reconstruction"):
        EsviOptions("e2vid")


def test_missing_event_window_exits_2_naming_the_file(esvi_folder: Path, tmp_path: Path) -> None:
    bad = _copy(esvi_folder, tmp_path / "bad")
    victim = sorted((bad / "davisR" / "events").glob("*.npz"))[50]
    victim.unlink()
    with pytest.raises(FormatError, match=victim.name):
        run_vio(open_sequence(bad))
    out = tmp_path / "est.txt"
    r = CliRunner().invoke(cli, ["vio", str(bad), "-o", str(out)])
    assert r.exit_code == 2, r.output
    err = [ln for ln in r.output.splitlines() if ln.startswith("error:")]
    assert len(err) == 1 and victim.name in err[0] and "Traceback" not in r.output
    assert not out.exists()


def test_one_event_camera_of_the_pair_exits_2(esvi_folder: Path, tmp_path: Path) -> None:
    bad = _copy(esvi_folder, tmp_path / "mono")
    doc = yaml.safe_load((bad / "sequence.yaml").read_text())
    del doc["cameras"]["davisR"]
    del doc["files"]["cameras"]["davisR"]
    (bad / "sequence.yaml").write_text(yaml.safe_dump(doc))
    shutil.rmtree(bad / "davisR")
    with pytest.raises(CalibrationError, match="two event cameras"):
        stereo_inputs(open_sequence(bad), setup="esvi")
    out = tmp_path / "est.txt"
    r = CliRunner().invoke(cli, ["vio", str(bad), "-o", str(out), "--setup", "esvi"])
    assert r.exit_code == 2, r.output
    err = [ln for ln in r.output.splitlines() if ln.startswith("error:")]
    assert len(err) == 1 and "sequence.yaml" in err[0] and "davisL" in err[0]
    assert not out.exists()
