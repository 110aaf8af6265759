"""Bad input of the VIO's other setups (issue #24) that ``test_vio_esvi.py`` / ``test_vio_rgbd.py``
do not cover: an event window file that cannot be read (an error: exit 2, one line naming it, no
estimate written) against a window that holds no events because the vehicle stands still (no
error: the estimator runs on the IMU there and reports the span); a sequence with only one camera
of the stereo pair (SVI) or of the RGB-D pair."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli
from ibiscape_eval.core.errors import CalibrationError, FormatError
from ibiscape_eval.core.events import Events
from ibiscape_eval.io.events import write_events
from ibiscape_eval.io.open_sequence import open_sequence
from ibiscape_eval.sim import generate, preset
from ibiscape_eval.sim.config import with_resolution
from ibiscape_eval.vio.inputs import stereo_inputs
from ibiscape_eval.vio.pipeline import run_vio

pytestmark = pytest.mark.filterwarnings("ignore:the rotation of the yaw alignment")


@pytest.fixture(scope="module")
def esvi_small(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """4 s ESVI drive at 96x72 (seed 3): still for the first 0.85 s (17 empty windows), then drives."""
    out = tmp_path_factory.mktemp("esvi_bad") / "ESVI_1_town"
    generate(with_resolution(preset("esvi", "slam", "clear", duration_s=4.0, seed=3), 96, 72), out,
             render=True)
    return out


def _windows(folder: Path, cam: str) -> list[Path]:
    return sorted((folder / cam / "events").glob("*.npz"))


def _exits_2_naming(args: list[str], out: Path, name: str) -> None:
    r = CliRunner().invoke(cli, [*args, "-o", str(out)])
    assert r.exit_code == 2, r.output
    err = [ln for ln in r.output.splitlines() if ln.startswith("error:")]
    assert len(err) == 1 and name in err[0], r.output
    assert "Traceback" not in r.output
    assert not out.exists()


@pytest.mark.parametrize("damage", ["garbage", "truncated", "empty file"])
def test_unreadable_event_window_exits_2_naming_it(esvi_small: Path, tmp_path: Path,
                                                  damage: str) -> None:
    bad = tmp_path / "bad"
    shutil.copytree(esvi_small, bad)
    victim = _windows(bad, "davisL")[30]
    data = victim.read_bytes()
    victim.write_bytes({"garbage": b"not an npz file at all" * 20, "truncated": data[: len(data) // 2],
                        "empty file": b""}[damage])
    with pytest.raises(FormatError, match=victim.name):
        run_vio(open_sequence(bad))
    _exits_2_naming(["vio", str(bad)], tmp_path / "est.txt", victim.name)


def test_still_vehicle_windows_are_empty_and_run_on_the_imu(esvi_small: Path, tmp_path: Path) -> None:
    """A window without events is what a still DVS records: not an error.  The standstill start's
    windows are empty, and so are 10 windows (0.5 s) emptied mid-drive in both cameras (as if the
    vehicle had stopped): the estimate goes on, the empty frames are not usable, and a reported
    IMU-only span covers them."""
    from ibiscape_eval.calib.events import read_event_window

    seq_dir = tmp_path / "stop"
    shutil.copytree(esvi_small, seq_dir)
    first = [len(read_event_window(f)) for f in _windows(seq_dir, "davisL")[:17]]
    assert first == [0] * 17  # the standstill start: no events at all (clear weather)
    emptied = []
    for cam in ("davisL", "davisR"):
        for f in _windows(seq_dir, cam)[40:50]:
            assert len(read_event_window(f)) > 0
            write_events(f, Events.empty(), fmt="npz")
            emptied.append(int(f.stem))
    res = run_vio(open_sequence(seq_dir))
    s = res.stats
    assert s.frames == 80 and s.usable_frames <= 80 - 17 - 10
    assert all(f.kind != "diverged" for f in s.failures)
    spans = [(f.start_ns, f.end_ns) for f in s.failures if f.kind == "tracking"]

    def covered(t: int) -> bool:
        return any(a <= t <= b for a, b in spans)

    assert all(covered(t) for t in emptied), (spans, emptied)
    st = res.trajectory.stamps_ns
    assert st[0] <= min(emptied) and st[-1] >= max(emptied)  # the estimate went through the stop
    assert np.all(np.isfinite(res.trajectory.pos_m))
    out = tmp_path / "est.txt"
    r = CliRunner().invoke(cli, ["vio", str(seq_dir), "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert out.is_file()


def test_svi_with_one_camera_of_the_pair_exits_2(street: tuple[Path, Path], tmp_path: Path) -> None:
    """rgbR listed in sequence.yaml but not recorded, or not listed at all."""
    src, _ = street
    missing = tmp_path / "no_rgbR_folder"
    shutil.copytree(src, missing)
    shutil.rmtree(missing / "rgbR")
    with pytest.raises(FormatError, match="rgbR"):
        run_vio(open_sequence(missing))
    _exits_2_naming(["vio", str(missing)], tmp_path / "a.txt", "rgbR/timestamps.csv")

    unlisted = tmp_path / "no_rgbR"
    shutil.copytree(src, unlisted)
    doc = yaml.safe_load((unlisted / "sequence.yaml").read_text())
    del doc["cameras"]["rgbR"]
    doc.get("files", {}).get("cameras", {}).pop("rgbR", None)
    (unlisted / "sequence.yaml").write_text(yaml.safe_dump(doc))
    shutil.rmtree(unlisted / "rgbR")
    with pytest.raises(CalibrationError, match="two"):
        stereo_inputs(open_sequence(unlisted), setup="svi")
    _exits_2_naming(["vio", str(unlisted), "--setup", "svi"], tmp_path / "b.txt", "sequence.yaml")


def test_rgbd_without_the_depth_camera_exits_2(street: tuple[Path, Path], tmp_path: Path) -> None:
    """An RGB-D run on a sequence with RGB cameras only (the depth half of the pair is absent)."""
    src, _ = street
    with pytest.raises(CalibrationError, match="depth camera"):
        stereo_inputs(open_sequence(src), setup="rgbd")
    _exits_2_naming(["vio", str(src), "--setup", "rgbd"], tmp_path / "c.txt", "sequence.yaml")
