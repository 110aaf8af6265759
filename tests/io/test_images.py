"""Image formats of the IBISCape layout: round trips (hypothesis), known encodings, bad input."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from ibiscape_eval.core.errors import FormatError, IbiscapeError
from ibiscape_eval.io.images import (
    CITYSCAPES_PALETTE,
    decode_depth_carla_log,
    encode_depth_carla_log,
    read_association,
    read_depth_carla_log,
    read_depth_mm,
    read_frame_timestamps,
    read_labels,
    read_labels_cityscapes,
    read_png,
    write_association,
    write_depth_carla_log,
    write_depth_mm,
    write_frame_timestamps,
    write_labels,
    write_labels_cityscapes,
    write_png,
)

shapes = st.tuples(st.integers(1, 9), st.integers(1, 9))


@settings(max_examples=25)
@given(img=arrays(np.uint8, st.tuples(st.integers(1, 9), st.integers(1, 9), st.just(3))))
def test_rgb_png_round_trip(tmp_path_factory: pytest.TempPathFactory, img: np.ndarray) -> None:
    p = tmp_path_factory.mktemp("png") / "a.png"
    write_png(p, img)
    back = read_png(p)
    assert back.dtype == np.uint8 and np.array_equal(back, img)


@pytest.mark.parametrize(("channels", "dtype"), [(3, np.uint8), (4, np.uint8), (3, np.uint16), (4, np.uint16)])
@pytest.mark.parametrize("photo", [False, True])
def test_png_channel_order_against_opencv(tmp_path: Path, channels: int, dtype: type, photo: bool) -> None:
    """RGB(A) in memory is BGR(A) in OpenCV's reading of the file, also from a non-contiguous view."""
    import cv2

    img: np.ndarray = np.random.default_rng(channels).integers(0, np.iinfo(dtype).max, (5, 8, channels),
                                                                endpoint=True).astype(dtype)
    view = img[:, ::-1]
    write_png(tmp_path / "a.png", view, photo=photo)
    raw = cv2.imread(str(tmp_path / "a.png"), cv2.IMREAD_UNCHANGED)
    assert raw is not None and raw.dtype == dtype and np.array_equal(raw[..., [2, 1, 0, 3][:channels]], view)
    assert np.array_equal(read_png(tmp_path / "a.png"), view)


@settings(max_examples=25)
@given(mm=arrays(np.uint16, shapes, elements=st.integers(1, 65535)))
def test_depth_mm_round_trip(tmp_path_factory: pytest.TempPathFactory, mm: np.ndarray) -> None:
    p = tmp_path_factory.mktemp("mm") / "d.png"
    write_depth_mm(p, mm.astype(np.float64) / 1000.0)
    d = read_depth_mm(p)
    assert d.dtype == np.float32 and np.array_equal(np.round(d.astype(np.float64) * 1000.0), mm)


def test_depth_mm_no_depth_is_zero_then_nan(tmp_path: Path) -> None:
    depth = np.array([[1.0, np.inf, np.nan], [-2.0, 70.0, 0.0005]])
    write_depth_mm(tmp_path / "d.png", depth)
    raw = read_png(tmp_path / "d.png")
    assert raw.dtype == np.uint16 and raw.tolist() == [[1000, 0, 0], [0, 0, 0]]
    d = read_depth_mm(tmp_path / "d.png")
    assert d[0, 0] == 1.0 and np.isnan(d[0, 1:]).all() and np.isnan(d[1]).all()


def test_carla_log_depth_known_values() -> None:
    # g = 1 + ln(d / 1000) / 5.70378: 1000 m -> 255, 1000 exp(-5.70378 / 2) m -> 127.5
    d = np.array([[1000.0, 1000.0 * math.exp(-5.70378 * 0.5), 1.0, np.inf]])
    code = encode_depth_carla_log(d)
    assert code.tolist() == [[255, 128, 0, 255]]
    back = decode_depth_carla_log(code)
    assert back[0, 0] == pytest.approx(1000.0, rel=1e-6)
    assert back[0, 2] == pytest.approx(1000.0 * math.exp(-5.70378), rel=1e-6)  # 3.34 m floor


@settings(max_examples=25)
@given(code=arrays(np.uint8, shapes))
def test_carla_log_depth_round_trip(tmp_path_factory: pytest.TempPathFactory, code: np.ndarray) -> None:
    p = tmp_path_factory.mktemp("log") / "d.png"
    write_depth_carla_log(p, decode_depth_carla_log(code))
    raw = read_png(p)
    assert raw.shape == (*code.shape, 3) and np.array_equal(raw[..., 0], code)
    assert np.array_equal(encode_depth_carla_log(read_depth_carla_log(p)), code)


@settings(max_examples=25)
@given(lab=arrays(np.uint8, shapes, elements=st.integers(0, len(CITYSCAPES_PALETTE) - 1)))
def test_labels_round_trip(tmp_path_factory: pytest.TempPathFactory, lab: np.ndarray) -> None:
    d = tmp_path_factory.mktemp("lab")
    write_labels(d / "raw.png", lab)
    write_labels_cityscapes(d / "pal.png", lab)
    assert np.array_equal(read_labels(d / "raw.png"), lab)
    assert np.array_equal(read_labels_cityscapes(d / "pal.png"), lab)
    assert np.array_equal(read_png(d / "pal.png"), CITYSCAPES_PALETTE[lab])


def test_cityscapes_known_colours(tmp_path: Path) -> None:
    write_labels_cityscapes(tmp_path / "p.png", np.array([[7, 13, 10]]))  # road, sky, vehicles
    assert read_png(tmp_path / "p.png").tolist() == [[[128, 64, 128], [70, 130, 180], [0, 0, 142]]]


@settings(max_examples=25)
@given(st.lists(st.integers(0, 2**62), min_size=0, max_size=20, unique=True))
def test_timestamps_and_association_round_trip(tmp_path_factory: pytest.TempPathFactory,
                                               stamps: list[int]) -> None:
    d = tmp_path_factory.mktemp("ts")
    s = np.sort(np.array(stamps, dtype=np.int64))
    write_frame_timestamps(d / "timestamps.csv", s)
    st_back, names = read_frame_timestamps(d / "timestamps.csv")
    assert np.array_equal(st_back, s) and names == [f"{t}.png" for t in s.tolist()]
    files = [f"rgb/{t}.png" for t in s.tolist()]
    write_association(d / "association.txt", s, files, s + 1, files)
    a, fa, b, fb = read_association(d / "association.txt")
    assert np.array_equal(a, s) and np.array_equal(b, s + 1) and fa == files == fb


def test_timestamps_header_like_the_dataset(tmp_path: Path) -> None:
    write_frame_timestamps(tmp_path / "t.csv", [5, 7])
    assert (tmp_path / "t.csv").read_text() == "#timestamp [ns], filename\n5, 5.png \n7, 7.png \n"


@pytest.mark.parametrize(("writer", "arg", "needle"), [
    (write_png, np.zeros((3, 3), np.float32), "uint8/uint16"),
    (write_png, np.zeros((0, 3), np.uint8), "uint8/uint16"),
    (write_depth_mm, np.zeros(5), "(H, W)"),
    (write_labels, np.full((2, 2), 300), "0..255"),
    (write_labels, np.zeros((2, 2), np.float32), "integer"),
    (write_labels_cityscapes, np.full((2, 2), 40), "no CityScapes colour"),
])
def test_bad_arrays_write_nothing(tmp_path: Path, writer, arg, needle: str) -> None:
    with pytest.raises(IbiscapeError, match=".*" + __import__("re").escape(needle)):
        writer(tmp_path / "x.png", arg)
    assert not list(tmp_path.iterdir())


def test_bad_files_are_named(tmp_path: Path) -> None:
    with pytest.raises(FormatError, match="not found"):
        read_png(tmp_path / "missing.png")
    (tmp_path / "junk.png").write_bytes(b"not a png")
    with pytest.raises(FormatError, match=r"junk\.png.*not a readable image"):
        read_png(tmp_path / "junk.png")
    write_png(tmp_path / "c.png", np.array([[[1, 2, 3]]], np.uint8))
    with pytest.raises(FormatError, match="not in CARLA's CityScapes palette"):
        read_labels_cityscapes(tmp_path / "c.png")
    with pytest.raises(FormatError, match="three equal channels"):
        read_depth_carla_log(tmp_path / "c.png")
    with pytest.raises(FormatError, match="16-bit"):
        read_depth_mm(tmp_path / "c.png")
    (tmp_path / "t.csv").write_text("#timestamp [ns], filename\n7, 7.png \n5, 5.png \n")
    with pytest.raises(FormatError, match=r"t\.csv:3.*increasing"):
        read_frame_timestamps(tmp_path / "t.csv")
    (tmp_path / "a.txt").write_text("1.0 a.png 1.0\n")
    with pytest.raises(FormatError, match=r"a\.txt:1"):
        read_association(tmp_path / "a.txt")
