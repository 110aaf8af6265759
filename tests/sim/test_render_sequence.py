"""Rendered sequences end to end: layout, true camera models in sequence.yaml, RGB-D association,
byte-identical reruns, and bad input (the command line: tests/cli/test_sim_render_cli.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.io.images import (
    read_association,
    read_depth_carla_log,
    read_depth_mm,
    read_frame_timestamps,
    read_labels,
    read_labels_cityscapes,
    read_png,
)
from ibiscape_eval.io.sequence import read_sequence_yaml
from ibiscape_eval.sim import generate, preset
from ibiscape_eval.sim.config import parse_resolution, with_resolution


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_svi_calibration_layout_true_cameras_and_determinism(tmp_path: Path) -> None:
    cfg = with_resolution(preset("svi", "calibration", "clear", duration_s=0.3, seed=4), 48, 40)
    generate(cfg, tmp_path / "a", render=True)
    generate(cfg, tmp_path / "b", render=True)
    a, b = _files(tmp_path / "a"), _files(tmp_path / "b")
    assert a == b  # same seed: byte-identical images
    for cam in ("rgbL", "rgbR"):
        st, names = read_frame_timestamps(tmp_path / "a" / cam / "timestamps.csv")
        assert len(st) == 7 and names == [f"{t}.png" for t in st.tolist()]
        img = read_png(tmp_path / "a" / cam / "frames" / names[3])
        assert img.shape == (40, 48, 3) and img.dtype == np.uint8 and img.std() > 5
    doc = read_sequence_yaml(tmp_path / "a" / "sequence.yaml")
    left = doc["cameras"]["rgbL"]
    assert left["rendered"] is True and left["resolution"] == [48, 40] and left["frames"] == 7
    assert left["intrinsics"] == pytest.approx([24.0, 24.0, 23.5, 19.5])  # 90 deg FOV kept
    assert doc["generator"]["rendered"] is True and doc["files"]["cameras"]["rgbR"] == "rgbR"
    np.testing.assert_allclose(np.array(doc["cameras"]["rgbR"]["T_cn_cnm1"])[:3, 3], [-0.4, 0, 0], atol=1e-12)
    left_r = read_png(tmp_path / "a" / "rgbL" / "frames" / names[3])
    right_r = read_png(tmp_path / "a" / "rgbR" / "frames" / names[3])
    assert not np.array_equal(left_r, right_r)  # a stereo pair, not two copies


def test_rgbd_depth_labels_and_association(tmp_path: Path) -> None:
    cfg = with_resolution(preset("rgbd", "slam", "clear", duration_s=0.2, seed=2), 40, 32)
    generate(cfg, tmp_path / "s", render=True)
    seq = tmp_path / "s"
    ta, fa, tb, fb = read_association(seq / "association.txt")
    assert len(ta) == 5 and np.array_equal(ta, tb)
    assert fa[0] == f"rgb/frames/{ta[0]}.png" and fb[0] == f"depth/mm/{ta[0]}.png"
    assert all((seq / f).is_file() for f in fa + fb)
    mm = read_depth_mm(seq / fb[2])
    log = read_depth_carla_log(seq / "depth" / "frames" / f"{ta[2]}.png")
    far = np.isnan(mm)
    near = ~far & (mm > 3.5)
    assert near.sum() > 50
    # the 8-bit log encoding is coarse (about 2.3 % per code) but agrees with the millimetres
    np.testing.assert_allclose(log[near], mm[near], rtol=0.03)
    assert (log[far] > 60).all()  # sky or beyond 65 m
    doc = read_sequence_yaml(seq / "sequence.yaml")
    assert doc["cameras"]["depth"]["encoding"]["mm"].startswith("16-bit")
    assert doc["files"]["association"] == "association.txt"


def test_full_setup_semantic_both_encodings(tmp_path: Path) -> None:
    cfg = with_resolution(preset("full", "slam", "clear", duration_s=0.1, seed=3), 32, 24)
    generate(cfg, tmp_path / "f", render=True)
    seq = tmp_path / "f"
    _, names = read_frame_timestamps(seq / "semantic" / "timestamps.csv")
    raw = read_labels(seq / "semantic" / "labels" / names[0])
    pal = read_labels_cityscapes(seq / "semantic" / "frames" / names[0])
    assert np.array_equal(raw, pal) and 13 in raw  # sky
    for cam in ("davisL", "davisR"):
        assert (seq / cam / "timestamps.csv").is_file() and list((seq / cam / "events").iterdir())
    doc = read_sequence_yaml(seq / "sequence.yaml")
    assert doc["cameras"]["davisL"]["dvs"]["n_windows"] == 2


def test_resolution_parsing() -> None:
    assert parse_resolution("256") == (256, 256) and parse_resolution(" 640X480 ") == (640, 480)
    for bad in ("0", "-5", "64x", "axb", "1x2x3", "100000"):
        with pytest.raises(IbiscapeError, match="resolution"):
            parse_resolution(bad)


def test_no_world_with_custom_motion_is_refused(tmp_path: Path) -> None:
    from _sb_motion import HelixMotion

    cfg = with_resolution(preset("svi", "slam", duration_s=0.2), 16, 16)
    with pytest.raises(IbiscapeError, match="needs the world"):
        generate(cfg, tmp_path / "x", motion=HelixMotion(duration_s=0.2), render=True)
    assert not list(tmp_path.iterdir())


def test_no_disk_space_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import shutil

    import ibiscape_eval.sim.render.sequence as rs

    monkeypatch.setattr(rs.shutil, "disk_usage", lambda p: shutil._ntuple_diskusage(10**9, 10**9, 1000))
    cfg = with_resolution(preset("svi", "calibration", duration_s=0.2), 64, 64)
    with pytest.raises(IbiscapeError, match=r"not enough disk space.*--resolution"):
        generate(cfg, tmp_path / "x", render=True)
    assert not list(tmp_path.iterdir())
