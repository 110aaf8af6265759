"""The VIO's grey PNG decoder (``decode_png_grey``): the same pixels as OpenCV's libpng decode on
every filter type, RGB and grey, generated and real (EuRoC) frames; every PNG variant it does not
handle goes to OpenCV; a corrupt file is refused as before."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.io.images import decode_png_grey, write_png
from ibiscape_eval.io.stereo import read_gray_image

REAL = Path(__file__).resolve().parents[1] / "data" / "real" / "euroc_v1_01_kimera" / "mav0"


def _scene(h: int, w: int, seed: int = 0) -> np.ndarray:
    """RGB texture with smooth and noisy parts and grey patches (R == G == B), so that libpng's
    adaptive filtering picks every filter type."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w]
    img = np.stack([(x * 255 // max(w - 1, 1)), (y * 255 // max(h - 1, 1)),
                    ((x + y) * 3) % 256], axis=2).astype(np.int32)
    img[h // 3:, : w // 2] = rng.integers(0, 256, (h - h // 3, w // 2, 3))
    img[: h // 4, w // 2:] = rng.integers(0, 256, (h // 4, w - w // 2, 1))  # grey noise
    img[h // 2:, w // 2:] = cv2.GaussianBlur(rng.integers(0, 256, (h - h // 2, w - w // 2, 3))
                                             .astype(np.uint8), (0, 0), 3)
    return img.clip(0, 255).astype(np.uint8)


def _chunks(data: bytes) -> list[tuple[bytes, bytes]]:
    out, pos = [], 8
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        out.append((kind, data[pos + 8:pos + 8 + n]))
        pos += 12 + n
    return out


def _png(chunks: list[tuple[bytes, bytes]]) -> bytes:
    body = b"".join(struct.pack(">I", len(d)) + k + d + struct.pack(">I", zlib.crc32(k + d))
                    for k, d in chunks)
    return b"\x89PNG\r\n\x1a\n" + body


def _filters(data: bytes) -> set[int]:
    ihdr = _chunks(data)[0][1]
    w, h, _, colour = struct.unpack(">IIBB", ihdr[:10])
    raw = zlib.decompress(b"".join(d for k, d in _chunks(data) if k == b"IDAT"))
    stride = 1 + w * (3 if colour == 2 else 1)
    return {raw[i * stride] for i in range(h)}


def _encode(img: np.ndarray) -> bytes:
    """A PNG whose row ``y`` uses filter type ``y % 5`` (libpng never picks 0 on textures)."""
    h, w = img.shape[:2]
    bpp = 1 if img.ndim == 2 else 3
    rows = img.reshape(h, w * bpp).astype(np.int32)
    out = []
    for y in range(h):
        x = rows[y]
        b = rows[y - 1] if y else np.zeros_like(x)
        a = np.concatenate([np.zeros(bpp, np.int32), x[:-bpp]])
        c = np.concatenate([np.zeros(bpp, np.int32), b[:-bpp]])
        p = a + b - c
        pa, pb, pc = np.abs(p - a), np.abs(p - b), np.abs(p - c)
        paeth = np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, c))
        f = y % 5
        pred = [np.zeros_like(x), a, b, (a + b) >> 1, paeth][f]
        out.append(bytes([f]) + ((x - pred) & 255).astype(np.uint8).tobytes())
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 0 if bpp == 1 else 2, 0, 0, 0)
    return _png([(b"IHDR", ihdr), (b"IDAT", zlib.compress(b"".join(out))), (b"IEND", b"")])


def _opencv(data: bytes) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)


@pytest.mark.parametrize("shape", [(96, 128, 3), (64, 50, 3), (96, 128), (1, 7, 3)])
def test_same_pixels_as_opencv_on_every_filter(tmp_path: Path, shape: tuple[int, ...]) -> None:
    img = _scene(shape[0], shape[1])
    if len(shape) == 2:
        img = img[..., 1].copy()
    seen: set[int] = set()
    for level in (1, 6, 9):  # the generator writes level 1
        f = tmp_path / f"f{level}.png"
        write_png(f, img, compression=level)
        data = f.read_bytes()
        seen |= _filters(data)
        ours = decode_png_grey(data)
        assert ours is not None and ours.dtype == np.uint8
        np.testing.assert_array_equal(ours, _opencv(data))
        np.testing.assert_array_equal(read_gray_image(f), cv2.imread(str(f), cv2.IMREAD_GRAYSCALE))
    if shape[0] > 1:
        assert seen >= {1, 2, 3, 4}, seen  # libpng's choices; every filter, 0 too, below
        data = _encode(img)
        assert _filters(data) == {0, 1, 2, 3, 4}
        ours = decode_png_grey(data)
        assert ours is not None
        np.testing.assert_array_equal(ours, _opencv(data))


def test_rgb_grey_is_libpngs_not_cvtcolor(tmp_path: Path) -> None:
    """libpng's truncating weights, not cvtColor's rounded ones: they differ on about half of the
    pixels, so a decoder with the wrong conversion fails the test above; here the values."""
    img = np.array([[[255, 0, 0], [0, 255, 0], [0, 0, 255], [10, 20, 30], [7, 7, 7]]], np.uint8)
    write_png(tmp_path / "p.png", img)
    ours = decode_png_grey((tmp_path / "p.png").read_bytes())
    assert ours is not None
    assert ours.tolist() == [[(9797 * 255) >> 15, (19234 * 255) >> 15, (3737 * 255) >> 15,
                              (9797 * 10 + 19234 * 20 + 3737 * 30) >> 15, 7]]


def test_real_euroc_frames() -> None:
    files = sorted(REAL.glob("cam*/data/*.png"))
    assert len(files) == 8
    for f in files:
        data = f.read_bytes()
        ours = decode_png_grey(data)
        assert ours is not None, f
        np.testing.assert_array_equal(ours, _opencv(data))


def _variant(kind: str) -> bytes:
    img = _scene(16, 20)
    if kind == "rgba":
        ok, enc = cv2.imencode(".png", np.dstack([img, np.full((16, 20), 200, np.uint8)]))
    elif kind == "grey16":
        ok, enc = cv2.imencode(".png", (img[..., 0].astype(np.uint16) * 257))
    else:
        ok, enc = cv2.imencode(".png", img[..., ::-1])
    assert ok
    data = enc.tobytes()
    ch = _chunks(data)
    if kind == "gamma":  # a gAMA chunk: libpng may apply gamma in its grey conversion
        ch.insert(1, (b"gAMA", struct.pack(">I", 100000)))
    elif kind == "interlaced":
        ch[0] = (b"IHDR", ch[0][1][:12] + b"\x01")
    elif kind == "palette":
        w, h = 20, 16
        raw = b"".join(b"\x00" + bytes((x + y) % 4 for x in range(w)) for y in range(h))
        ch = [(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 3, 0, 0, 0)),
              (b"PLTE", bytes([0, 0, 0, 255, 0, 0, 0, 255, 0, 0, 0, 255])),
              (b"IDAT", zlib.compress(raw)), (b"IEND", b"")]
    elif kind == "bad_filter":
        raw = bytearray(zlib.decompress(ch[1][1]))
        raw[0] = 7
        ch[1] = (b"IDAT", zlib.compress(bytes(raw)))
    elif kind == "bad_crc":
        return data[:-20] + bytes([data[-20] ^ 1]) + data[-19:]
    elif kind == "short_idat":
        ch[1] = (b"IDAT", zlib.compress(zlib.decompress(ch[1][1])[:-30]))
    return _png(ch)


@pytest.mark.parametrize("kind", ["rgba", "grey16", "gamma", "interlaced", "palette",
                                  "bad_filter", "bad_crc", "short_idat"])
def test_variants_go_to_opencv(tmp_path: Path, kind: str) -> None:
    data = _variant(kind)
    assert decode_png_grey(data) is None
    f = tmp_path / "v.png"
    f.write_bytes(data)
    ref = cv2.imread(str(f), cv2.IMREAD_GRAYSCALE)
    if ref is None:
        with pytest.raises(FormatError, match="not an image OpenCV can read"):
            read_gray_image(f)
    else:
        np.testing.assert_array_equal(read_gray_image(f), ref)


def test_not_a_png_and_missing(tmp_path: Path) -> None:
    assert decode_png_grey(b"GIF89a...") is None
    f = tmp_path / "x.png"
    f.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 40)
    with pytest.raises(FormatError, match=r"x\.png.*not an image OpenCV can read"):
        read_gray_image(f)
    with pytest.raises(FormatError, match="missing"):
        read_gray_image(tmp_path / "none.png")
    bmp = tmp_path / "b.bmp"
    cv2.imwrite(str(bmp), _scene(8, 8))
    np.testing.assert_array_equal(read_gray_image(bmp), cv2.imread(str(bmp), cv2.IMREAD_GRAYSCALE))


@pytest.mark.parametrize("cut", [0, 20, 60, -13])
def test_truncated_or_empty_files_go_to_opencv(tmp_path: Path, cut: int) -> None:
    """The mapped file's chunk walk never reads past its end: an empty file or one cut inside a
    chunk is OpenCV's to refuse (or to decode, as it would)."""
    f = tmp_path / "whole.png"
    cv2.imwrite(str(f), _scene(40, 48))
    data = f.read_bytes()
    g = tmp_path / "cut.png"
    g.write_bytes(data[:cut] if cut > 0 else data[:len(data) + cut] if cut else b"")
    assert decode_png_grey(g.read_bytes()) is None
    ref = cv2.imread(str(g), cv2.IMREAD_GRAYSCALE)
    if ref is None:
        with pytest.raises(FormatError, match=r"cut\.png"):
            read_gray_image(g)
    else:
        np.testing.assert_array_equal(read_gray_image(g), ref)
