"""Kalibr yaml: camchain round trips (hypothesis), target yaml, bad files, atomic writes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import FormatError, IbiscapeError
from ibiscape_eval.io.kalibr import (
    CameraChain,
    read_camchain,
    read_target_yaml,
    write_camchain,
    write_json,
)

finite = st.floats(-0.5, 0.5, allow_nan=False)


@st.composite
def chains(draw):
    n = draw(st.integers(1, 4))
    cams, Ts = [], []
    for i in range(n):
        w, h = draw(st.integers(16, 2048)), draw(st.integers(16, 2048))
        model = draw(st.sampled_from(["radtan", "equidistant"]))
        cams.append(CameraModel(w, h, draw(st.floats(10, 3000)), draw(st.floats(10, 3000)),
                                draw(st.floats(-10, 3000)), draw(st.floats(-10, 3000)), model,
                                tuple(draw(finite) for _ in range(4))))
        if i:
            T = np.eye(4)
            T[:3, :3] = Rotation.from_rotvec([draw(finite) for _ in range(3)]).as_matrix()
            T[:3, 3] = [draw(st.floats(-2, 2)) for _ in range(3)]
            Ts.append(T)
    return CameraChain(tuple(f"cam{i}" for i in range(n)), tuple(cams), tuple(Ts),
                       tuple(f"/cam{i}/image_raw" for i in range(n)))


@settings(max_examples=40, deadline=None)
@given(chain=chains())
def test_camchain_round_trip(tmp_path_factory, chain):
    p = tmp_path_factory.mktemp("cc") / "camchain.yaml"
    write_camchain(p, chain)
    back = read_camchain(p)
    assert back.names == chain.names and back.rostopics == chain.rostopics
    assert back.cameras == chain.cameras
    for a, b in zip(back.T_cn_cnm1, chain.T_cn_cnm1, strict=True):
        np.testing.assert_array_equal(a, b)
    doc = yaml.safe_load(p.read_text())
    assert set(doc["cam0"]) >= {"camera_model", "intrinsics", "distortion_model", "distortion_coeffs",
                                "resolution", "rostopic"}
    assert ("T_cn_cnm1" in doc.get("cam1", {"T_cn_cnm1": 1}))


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "f.yaml"
    p.write_text(text)
    return p


CAM = ("camera_model: pinhole\nintrinsics: [500, 500, 320, 240]\ndistortion_model: radtan\n"
       "distortion_coeffs: [0, 0, 0, 0]\nresolution: [640, 480]\n")


@pytest.mark.parametrize("text,match", [
    ("a: [1, 2", "not valid YAML"),
    ("- 1\n- 2\n", "mapping"),
    ("foo: 1\n", "no cam0"),
    ("cam0:\n  intrinsics: [1, 2]\n  resolution: [640, 480]\n", "intrinsics"),
    ("cam0:\n" + "".join("  " + ln + "\n" for ln in CAM.splitlines()) + "cam2: {}\n", "without gaps"),
    ("cam0:\n" + "".join("  " + ln + "\n" for ln in CAM.splitlines())
     + "cam1:\n" + "".join("  " + ln + "\n" for ln in CAM.splitlines()), "T_cn_cnm1"),
    ("cam0:\n" + "".join("  " + ln + "\n" for ln in CAM.splitlines())
     + "cam1:\n" + "".join("  " + ln + "\n" for ln in CAM.splitlines())
     + "  T_cn_cnm1: [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n", "rotation"),
    ("cam0:\n" + "".join("  " + ln + "\n" for ln in CAM.replace("radtan", "fov").splitlines()), "radtan"),
])
def test_bad_camchain(tmp_path, text, match):
    with pytest.raises(FormatError, match=match) as e:
        read_camchain(_write(tmp_path, text))
    assert "f.yaml" in str(e.value)


def test_camchain_no_pickle_tags(tmp_path):
    p = _write(tmp_path, "cam0: !!python/object/apply:os.system ['echo hi']\n")
    with pytest.raises(FormatError, match="not valid YAML"):
        read_camchain(p)


def test_target_yaml(tmp_path):
    p = _write(tmp_path, "target_type: 'aprilgrid'\ntagCols: 6\ntagRows: 6\ntagSize: 0.088\ntagSpacing: 0.3\n")
    assert read_target_yaml(p)["tagSize"] == 0.088
    with pytest.raises(FormatError, match="target_type"):
        read_target_yaml(_write(tmp_path, "tagCols: 6\n"))


def test_writers_are_atomic(tmp_path):
    bad = CameraChain(("cam0",), (CameraModel(10, 10, 5, 5, 5, 5),), (), ("/c",))
    out = tmp_path / "sub" / "cc.yaml"
    write_camchain(out, bad)
    assert out.exists() and [p.name for p in out.parent.iterdir()] == ["cc.yaml"]
    with pytest.raises(IbiscapeError):
        CameraChain(("cam0", "cam1"), (CameraModel(10, 10, 5, 5, 5, 5),) * 2, (), ("/a", "/b"))
    write_json(tmp_path / "r.json", {"a": float("nan"), "b": np.float64(2.0), "c": np.arange(2)})
    assert (tmp_path / "r.json").read_text().split() == ['{', '"a":', 'null,', '"b":', '2.0,', '"c":',
                                                         '[', '0,', '1', ']', '}']
