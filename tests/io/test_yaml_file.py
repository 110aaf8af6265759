"""The one YAML reader: OpenCV ``%YAML:1.0`` / ``!!opencv-matrix`` files read like
``cv2.FileStorage`` reads them (real ORB-SLAM3, VINS-Fusion, OpenVINS, Kalibr and EuRoC files),
plain YAML unchanged, duplicate keys and Python tags refused."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.io.yaml_file import read_yaml

REAL = Path(__file__).resolve().parents[1] / "data" / "real" / "kalibr"


def _compare_with_filestorage(node: Any, ours: Any, where: str) -> int:
    """Every value FileStorage reads equals ours; returns how many leaves were compared."""
    if node.isMap():
        keys = list(node.keys())
        mat = node.mat() if "dt" in keys else None
        if mat is not None:
            assert isinstance(ours, np.ndarray), where
            assert ours.dtype == mat.dtype and np.array_equal(ours, mat), where
            return 1
        assert isinstance(ours, dict) and sorted(map(str, ours)) == sorted(keys), where
        return sum(_compare_with_filestorage(node.getNode(k), ours[k], f"{where}.{k}") for k in keys)
    if node.isSeq():
        assert isinstance(ours, list) and len(ours) == node.size(), where
        return sum(_compare_with_filestorage(node.at(i), ours[i], f"{where}[{i}]") for i in range(node.size()))
    if node.isInt():
        assert ours == int(node.real()) and not isinstance(ours, bool), where
    elif node.isReal():
        assert isinstance(ours, float) and ours == node.real(), where
    elif node.isString():
        # FileStorage keeps a trailing ``# comment`` inside an unquoted string (YAML drops it)
        assert ours == node.string().split(" #")[0].rstrip(), where
    return 1


def _filestorage_refusal(cv2: Any, path: Path) -> str:
    """OpenCV's parse error (the Python binding raises SystemError with the cv2.error as its cause)."""
    try:
        cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as e:
        return str(e.__cause__ or e)
    raise AssertionError(f"FileStorage read {path}")


OPENCV_FILES = ["vinsfusion_euroc_stereo_imu_config.yaml", "openvins_euroc_kalibr_imucam_chain.yaml",
                "openvins_euroc_kalibr_imu_chain.yaml", "kalibr_imu.yaml", "euroc_cam0_sensor.yaml",
                "kalibr_april_6x6_80x80cm.yaml"]


def test_filestorage_cannot_read_kalibrs_own_camchain():
    """Why one reader for both dialects: OpenCV refuses the block lists PyYAML writes (Kalibr's
    camchain-imucam), PyYAML refuses OpenCV's header; ours reads both."""
    cv2 = pytest.importorskip("cv2")
    f = REAL / "kalibr_camchain-imucam-camera_imu.yaml"
    assert "Incorrect indentation" in _filestorage_refusal(cv2, f)
    assert read_yaml(f)["cam0"]["T_cam_imu"][3] == [0.0, 0.0, 0.0, 1.0]


@pytest.mark.parametrize("name", OPENCV_FILES)
def test_real_files_read_like_filestorage(name):
    cv2 = pytest.importorskip("cv2")
    fs = cv2.FileStorage(str(REAL / name), cv2.FILE_STORAGE_READ)
    assert fs.isOpened()
    n = _compare_with_filestorage(fs.root(), read_yaml(REAL / name), name)
    assert n >= 5


def test_orbslam3_settings_like_filestorage(tmp_path):
    """ORB-SLAM3's EuRoC.yaml as it was published: ``%YAML:1.0``, ``!!opencv-matrix`` with
    ``dt: f`` and ``dt: d``, ``data:[`` and ``Viewer.PointSize:2`` without a space.  The published
    file lacks a comma at the end of a ``Tbc`` row: OpenCV 5 refuses it and so do we, naming the line;
    with the comma added both read the same 49 values."""
    cv2 = pytest.importorskip("cv2")
    src = REAL / "orbslam3_stereo_inertial_EuRoC.yaml"
    assert "(40): Missing , between the elements" in _filestorage_refusal(cv2, src)
    with pytest.raises(FormatError, match=r"EuRoC.yaml:39: .*opencv-matrix: data lacks a comma"):
        read_yaml(src)
    lines = src.read_text().splitlines(keepends=True)
    assert lines[38].rstrip().endswith("0.0")
    lines[38] = lines[38].rstrip() + ",\n"
    fixed = tmp_path / "EuRoC.yaml"
    fixed.write_text("".join(lines))
    fs = cv2.FileStorage(str(fixed), cv2.FILE_STORAGE_READ)
    doc = read_yaml(fixed)
    assert _compare_with_filestorage(fs.root(), doc, "EuRoC.yaml") == 49
    assert doc["Tbc"].dtype == np.float32 and doc["LEFT.K"].dtype == np.float64
    np.testing.assert_array_equal(doc["Tbc"], np.diag([1.0, -1.0, -1.0, 1.0]).astype(np.float32))
    assert doc["Viewer.PointSize"] == 2 and doc["IMU.AccWalk"] == 3e-3


def test_euroc_sensor_yaml_with_the_download_header(tmp_path):
    """EuRoC's sensor.yaml with its ``%YAML:1.0`` first line (the download has
    it; the repository copy in tests/data/real does not) reads the same as without it."""
    from ibiscape_eval.io.asl import read_asl_sensor_yaml

    f = tmp_path / "sensor.yaml"
    f.write_text("%YAML:1.0\n" + (REAL / "euroc_cam0_sensor.yaml").read_text())
    a, b = read_asl_sensor_yaml(f), read_asl_sensor_yaml(REAL / "euroc_cam0_sensor.yaml")
    np.testing.assert_array_equal(a["T_BS"], b["T_BS"])
    assert {k: v for k, v in a.items() if k != "T_BS"} == {k: v for k, v in b.items() if k != "T_BS"}
    assert a["distortion_coefficients"] == [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]


@pytest.mark.parametrize("text,match,line", [
    ("a: 1\nb: 2\na: 3\n", r"duplicate key 'a' \(first on line 1\)", 3),
    ("m:\n  x: 1\n  x: 1\n", "duplicate key 'x'", 3),
    ("a: !!python/object/apply:os.system ['echo hi']\n", "could not determine a constructor", 1),
    ("%YAML:1.0\nK: !!opencv-matrix\n  rows: 2\n  cols: 2\n  dt: d\n  data: [1, 2, 3]\n",
     r"rows x cols = 2 x 2 but data holds 3", 6),
    ("%YAML:1.0\nK: !!opencv-matrix\n  rows: 1\n  cols: 1\n  dt: q\n  data: [1]\n", "dt 'q'", 6),
    ("%YAML:1.0\nK: !!opencv-matrix\n  rows: 1\n  cols: 1\n  dt: d\n  data: [x]\n", "data must be numbers", 6),
    ("%YAML:1.0\nK: !!opencv-matrix\n  rows: 1\n", "needs the keys rows, cols", 2),
    ("a: [1, 2\n", "not valid YAML", 2),
])
def test_bad_yaml_names_file_and_line(tmp_path, text, match, line):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(FormatError, match=match) as e:
        read_yaml(f)
    assert e.value.path == str(f) and e.value.line == line


def test_numbers_yaml_11_reads_as_strings(tmp_path):
    f = tmp_path / "n.yaml"
    f.write_text("a: 1e-3\nb: -2E+5\nc: 1.5e-3\nd: 7\ne: '1e-3'\nf: 1e3x\n")
    assert read_yaml(f) == {"a": 1e-3, "b": -2e5, "c": 1.5e-3, "d": 7, "e": "1e-3", "f": "1e3x"}


plain = st.recursive(st.one_of(st.none(), st.booleans(), st.integers(-10**12, 10**12),
                               st.floats(allow_nan=False), st.text(max_size=8)),
                     lambda c: st.one_of(st.lists(c, max_size=4),
                                         st.dictionaries(st.text("abcxyz_", min_size=1, max_size=5), c,
                                                         max_size=4)), max_leaves=12)


@settings(max_examples=60, deadline=None)
@given(doc=st.dictionaries(st.text("abcdefgh", min_size=1, max_size=6), plain, max_size=6))
def test_plain_yaml_reads_as_safe_load(tmp_path_factory, doc):
    """Every document yaml.safe_dump writes is read back as yaml.safe_load reads it."""
    f = tmp_path_factory.mktemp("y") / "doc.yaml"
    text = yaml.safe_dump(doc, sort_keys=False)
    f.write_text(text)
    assert read_yaml(f) == yaml.safe_load(text)


def test_real_fixture_sizes_stay_small():
    files = sorted(REAL.iterdir())
    assert sum(p.stat().st_size for p in files) < 64 * 1024
    listed = (REAL / "PROVENANCE.md").read_text()
    assert all(p.name in listed for p in files if p.suffix == ".yaml")
