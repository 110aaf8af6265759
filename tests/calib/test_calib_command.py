"""``ibiscape-eval calib`` end to end on rendered sequences, and every bad input (exit 2, one line)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from _calib_scenes import dvs_scene, stereo_scene
from _calib_seqs import sequence_yaml, write_camera_folder, write_dvs_folder, write_sequence
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli
from ibiscape_eval.io.kalibr import read_camchain


def run(*args):
    return CliRunner().invoke(cli, ["calib", *[str(a) for a in args]], catch_exceptions=False)


@pytest.fixture(scope="module")
def checker_seq(tmp_path_factory) -> Path:
    return write_sequence(tmp_path_factory.mktemp("seq") / "SVI_calib", stereo_scene("checkerboard"))


def _fails(res, *words):
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert lines[-1].startswith("error: ")
    for w in words:
        assert w in lines[-1], lines[-1]


def test_sequence_report_yaml_plots_and_check(checker_seq, tmp_path):
    out = tmp_path / "camchain.yaml"
    res = run(checker_seq, "--yaml", out, "--plot", tmp_path / "plots")
    assert res.exit_code == 0, res.output
    assert "against ground truth (table:camerasintrinsics)" in res.stdout
    assert "+-" in res.stdout and "baseline" in res.stdout
    chain = read_camchain(out)
    assert chain.rostopics == ("/rgbL/image_raw", "/rgbR/image_raw")
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == [
        "rgbL_coverage.png", "rgbL_residuals.png", "rgbR_coverage.png", "rgbR_residuals.png"]
    doc = json.loads(run(checker_seq, "--json").stdout)
    gt = doc["ground_truth"]
    assert gt["max_focal_error_px"] < 0.3 and gt["max_principal_point_error_px"] < 0.5
    assert gt["max_baseline_error_mm"] < 1.0 and doc["rms_px"] < 0.1
    assert doc["detection"]["cameras"][0]["frames_tried"] == 12
    chk = run(checker_seq, "--check", out, "--json")
    assert chk.exit_code == 0
    assert json.loads(chk.stdout)["rms_px"] < 0.1


def test_image_globs_with_target_yaml(tmp_path):
    target, _, _, _, (imgs_l, imgs_r), _ = stereo_scene("aprilgrid")
    for i, (a, b) in enumerate(zip(imgs_l, imgs_r, strict=True)):
        cv2.imwrite(str(tmp_path / f"left_{i:03d}.png"), a)
        cv2.imwrite(str(tmp_path / f"right_{i:03d}.png"), b)
    (tmp_path / "target.yaml").write_text(yaml.safe_dump(target.to_kalibr()))
    res = run("--target", tmp_path / "target.yaml", "--images", f"cam0={tmp_path}/left_*.png",
              "--images", f"cam1={tmp_path}/right_*.png", "--json", "--model", "pinhole-radtan")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["ground_truth"] is None and doc["rms_px"] < 0.1
    assert abs(doc["chain"][0]["baseline_m"] - 0.2003) < 0.001
    # right images named with other numbers: no common instant
    for p in tmp_path.glob("right_*.png"):
        p.rename(p.with_name(p.name.replace("right_", "right_9")))
    _fails(run("--target", tmp_path / "target.yaml", "--images", f"cam0={tmp_path}/left_*.png",
               "--images", f"cam1={tmp_path}/right_*.png"), "share no")


def test_event_camera_folder(tmp_path):
    target, cam, _, windows, events = dvs_scene()
    seq = tmp_path / "DVS_calib"
    write_dvs_folder(seq / "davisL", windows, events)
    (seq / "sequence.yaml").write_text(yaml.safe_dump(
        sequence_yaml({"davisL": cam}, {"davisL": np.eye(4)}, target.to_kalibr())))
    res = run(seq, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["reconstruction"]["davisL"]["method"] == "accumulate-signed"
    assert doc["ground_truth"]["max_focal_error_px"] < 1.0


def test_no_target_found(tmp_path):
    seq = tmp_path / "s"
    write_camera_folder(seq / "rgb", [np.full((120, 160), 128, np.uint8)] * 5, [1, 2, 3, 4, 5])
    (seq / "t.yaml").write_text("target_type: checkerboard\ntargetRows: 7\ntargetCols: 7\n"
                                "rowSpacingMeters: 0.1\ncolSpacingMeters: 0.1\n")
    _fails(run(seq, "--target", seq / "t.yaml", "--yaml", tmp_path / "o.yaml"),
           "no target found in any of the 5 frames")
    assert not (tmp_path / "o.yaml").exists()


def test_bad_target_yaml_and_missing_target(checker_seq, tmp_path):
    (tmp_path / "t.yaml").write_text("target_type: aprilgrid\ntagRows: 6\ntagCols: 6\ntagSize: 0.1\n")
    _fails(run(checker_seq, "--target", tmp_path / "t.yaml"), "t.yaml", "tagSpacing")
    seq = tmp_path / "s"
    shutil.copytree(checker_seq, seq)
    doc = yaml.safe_load((seq / "sequence.yaml").read_text())
    doc["target"] = None
    (seq / "sequence.yaml").write_text(yaml.safe_dump(doc))
    _fails(run(seq), "--target")


def test_corrupt_images_are_skipped_and_sizes_checked(checker_seq, tmp_path):
    seq = tmp_path / "s"
    shutil.copytree(checker_seq, seq)
    frames = sorted((seq / "rgbL" / "frames").iterdir())
    frames[0].write_bytes(b"not a png")
    res = run(seq, "--json")
    assert res.exit_code == 0, res.output
    assert f"{frames[0]}: not a readable image; skipped" in res.stderr
    # one image of another size
    img = cv2.imread(str(frames[1]))
    cv2.imwrite(str(frames[1]), cv2.resize(img, (240, 180)))
    _fails(run(seq), "different sizes", frames[1].name)


def test_too_few_views(checker_seq, tmp_path):
    seq = tmp_path / "s"
    shutil.copytree(checker_seq, seq)
    for cam in ("rgbL", "rgbR"):
        rows = (seq / cam / "timestamps.csv").read_text().splitlines()
        (seq / cam / "timestamps.csv").write_text("\n".join(rows[:3]) + "\n")
    _fails(run(seq), "usable views")


def test_needs_input():
    _fails(run(), "SEQ or --images")


def test_euroc_folder_and_pairing_by_order(tmp_path):
    from ibiscape_eval.io.image_sets import image_sets_from_globs, pair_views
    from ibiscape_eval.io.open_sequence import open_sequence

    _, _, _, _, (imgs_l, imgs_r), _ = stereo_scene("checkerboard")
    stamps = [1_403_636_579_763_555_584 + i * 50_000_000 for i in range(len(imgs_l))]
    for cam, imgs in (("cam0", imgs_l), ("cam1", imgs_r)):
        d = tmp_path / "mav0" / cam / "data"
        d.mkdir(parents=True)
        rows = ["#timestamp [ns],filename"]
        for t, im in zip(stamps, imgs, strict=True):
            cv2.imwrite(str(d / f"{t}.png"), im)
            rows.append(f"{t},{t}.png")
        (d.parent / "data.csv").write_text("\n".join(rows) + "\n")
    sets = open_sequence(tmp_path).cameras
    assert [s.name for s in sets] == ["cam0", "cam1"]
    assert pair_views(sets)[3] == [3, 3]
    (tmp_path / "t.yaml").write_text(yaml.safe_dump({
        "target_type": "checkerboard", "targetRows": 7, "targetCols": 7,
        "rowSpacingMeters": 0.5, "colSpacingMeters": 0.5}))
    res = run(tmp_path, "--target", tmp_path / "t.yaml", "--json")
    assert res.exit_code == 0, res.output
    assert abs(json.loads(res.stdout)["chain"][0]["baseline_m"] - 0.2003) < 0.001
    # names without numbers pair by order; unequal counts cannot be paired
    for i, im in enumerate(imgs_l[:4]):
        cv2.imwrite(str(tmp_path / f"l{'abcd'[i]}.png"), im)
        cv2.imwrite(str(tmp_path / f"r{'abcd'[i]}.png"), im)
    sets = image_sets_from_globs([f"a={tmp_path}/l*.png", f"b={tmp_path}/r*.png"])
    assert pair_views(sets) == [[0, 0], [1, 1], [2, 2], [3, 3]]
    (tmp_path / "re.png").write_bytes((tmp_path / "ra.png").read_bytes())
    _fails(run("--target", tmp_path / "t.yaml", "--images", f"a={tmp_path}/l*.png",
               "--images", f"b={tmp_path}/r*.png"), "cannot pair")
