"""The export and VIO readers refuse a named pipe, a folder and a symbolic-link loop with one
FormatError naming the path (they call io.paths.check_input before opening; a pipe would hang)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.io import asl, images, kalibr, stereo, tum_rgbd
from ibiscape_eval.io.dvs_folder import read_dvs_frame_list
from ibiscape_eval.io.rosbag_export import read_bag_images, read_bag_imu

READERS: dict[str, Callable[[Path], Any]] = {
    "asl_image_list": asl.read_asl_image_list,
    "asl_sensor_yaml": asl.read_asl_sensor_yaml,
    "frame_timestamps": images.read_frame_timestamps,
    "association": images.read_association,
    "png": images.read_png,
    "tum_list": tum_rgbd.read_tum_list,
    "stereo_frame_list": stereo.read_frame_list,
    "stereo_imu": stereo.read_imu_samples,
    "gray_image": stereo.read_gray_image,
    "camchain": kalibr.read_camchain,
    "kalibr_imu_yaml": kalibr.read_imu_noise,
    "kalibr_target": kalibr.read_target,
    "dvs_frames": lambda p: read_dvs_frame_list(p.parent.parent),
}


def _target(tmp_path: Path, kind: str) -> Path:
    (tmp_path / "frames").mkdir()
    p = tmp_path / "frames" / "timestamps.csv"
    if kind == "fifo":
        os.mkfifo(p)
    elif kind == "folder":
        p.mkdir()
    else:
        os.symlink(p, p)
    return p


@pytest.mark.parametrize("kind", ["fifo", "folder", "loop"])
@pytest.mark.parametrize("name", sorted(READERS))
def test_reader_refuses_non_files(tmp_path: Path, name: str, kind: str) -> None:
    p = _target(tmp_path, kind)
    with pytest.raises(FormatError, match=r"timestamps\.csv"):
        READERS[name](p)


@pytest.mark.parametrize("reader", [read_bag_images, read_bag_imu])
def test_bag_readers_refuse_a_pipe(tmp_path: Path, reader: Callable[..., Any]) -> None:
    p = tmp_path / "x.bag"
    os.mkfifo(p)
    with pytest.raises(FormatError, match=r"x\.bag.*named pipe"):
        reader(p, "/cam0/image_raw")


def test_stereo_imu_non_utf8_and_ragged_rows(tmp_path: Path) -> None:
    p = tmp_path / "imu.csv"
    p.write_bytes(b"#t,wx,wy,wz,ax,ay,az\n1,0,0,0,0,0,0\n2,0,0,0,\xff,0,0\n")
    with pytest.raises(FormatError, match=r"imu\.csv"):
        stereo.read_imu_samples(p)
    p.write_bytes(b"#t,wx,wy,wz,ax,ay,az\n1,0,0,0,0,0,0\n2,0,0,0,0,0,0,1,2,3\n")
    with pytest.raises(FormatError, match=r"imu\.csv"):
        stereo.read_imu_samples(p)
