"""Reading the VIO inputs: EuRoC ASL folders, Kalibr camchains, frame lists and IMU csv files."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from ibiscape_eval.core.errors import CalibrationError, FormatError
from ibiscape_eval.io.kalibr import read_camchain
from ibiscape_eval.io.stereo import read_frame_list, read_imu_samples
from ibiscape_eval.vio.inputs import load_sequence
from ibiscape_eval.vio.pipeline import run_vio

# the one re-packer of a generated sequence into EuRoC's layout (tests/io/_sequence_helpers.py)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "io"))
from _sequence_helpers import euroc_from


def test_euroc_folder_gives_the_same_estimate(street, tmp_path):
    seq_dir, calib = street
    euroc = euroc_from(seq_dir, tmp_path / "MH_street", calib, empty_gt=False)
    a = load_sequence(seq_dir, calib=calib)
    b = load_sequence(euroc)
    assert b.layout == "euroc" and b.n_frames == a.n_frames
    np.testing.assert_array_equal(a.imu_stamps_ns, b.imu_stamps_ns)
    np.testing.assert_allclose(b.gyro_rad_s, a.gyro_rad_s, rtol=1e-15)
    np.testing.assert_allclose(b.rig.T_body_left, a.rig.T_body_left, atol=1e-12)
    ra = run_vio(a, max_frames=30)
    rb = run_vio(b, max_frames=30)
    np.testing.assert_allclose(rb.trajectory.pos_m, ra.trajectory.pos_m, atol=1e-6)


def test_camchain_needs_cam0_and_cam1(tmp_path):
    f = tmp_path / "camchain.yaml"
    f.write_text(yaml.safe_dump({"cam0": {"intrinsics": [100, 100, 50, 50], "resolution": [100, 100],
                                          "T_cam_imu": np.eye(4).tolist()}}))
    from ibiscape_eval.vio.inputs import _rig_from_camchain

    with pytest.raises(CalibrationError, match="cam1"):
        _rig_from_camchain(f)
    f.write_text("cam0: [unclosed")
    with pytest.raises(FormatError, match="YAML"):
        read_camchain(f)


@given(st.lists(st.integers(0, 2**62), min_size=1, max_size=30, unique=True))
def test_frame_list_reads_back_sorted_stamps(tmp_path_factory, stamps):
    stamps = sorted(stamps)
    f = tmp_path_factory.mktemp("fl") / "timestamps.csv"
    f.write_text("#timestamp [ns],filename\n" + "".join(f"{t},{t}.png\n" for t in stamps))
    st_ns, names = read_frame_list(f)
    assert st_ns.tolist() == stamps and names == [f"{t}.png" for t in stamps]


def test_frame_list_errors(tmp_path):
    f = tmp_path / "timestamps.csv"
    f.write_text("#timestamp [ns],filename\n10,a.png\n9,b.png\n")
    with pytest.raises(FormatError, match=r"timestamps.csv:3.*increase"):
        read_frame_list(f)
    f.write_text("#timestamp [ns],filename\nabc,a.png\n")
    with pytest.raises(FormatError, match=r":2.*integer"):
        read_frame_list(f)
    f.write_text("#timestamp [ns],filename\n")
    with pytest.raises(FormatError, match="no frames"):
        read_frame_list(f)


def test_imu_samples_ibiscape_frame_is_mirrored(tmp_path):
    f = tmp_path / "imu.csv"
    f.write_text("#t,wx,wy,wz,ax,ay,az\n1,0.1,0.2,0.3,1,2,9.8\n2,0.1,0.2,0.3,1,2,9.8\n")
    t, g, a = read_imu_samples(f, fmt="ibiscape")
    assert t.tolist() == [1, 2]
    np.testing.assert_allclose(g[0], [-0.1, 0.2, -0.3])
    np.testing.assert_allclose(a[0], [1, -2, 9.8])
    f.write_text("#t,wx,wy,wz,ax,ay,az\n1,0.1,0.2,0.3,1,2,x\n2,0.1,0.2,0.3,1,2,9.8\n")
    with pytest.raises(FormatError, match=":2"):
        read_imu_samples(f)
