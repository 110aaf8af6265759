"""Rendered RGB frames are written with the fast 'photo' PNG settings (#25): lossless, smaller
than the default at the same zlib level on a noisy image."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ibiscape_eval.io.images import read_png, write_png


def test_photo_png_is_lossless_and_smaller_on_a_noisy_image(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    x = np.linspace(0.0, 1.0, 160)
    base = 60.0 + 120.0 * np.outer(np.sin(3 * x) ** 2, x)[..., None] * np.array([1.0, 0.8, 0.6])
    img = np.clip(base + rng.normal(0.0, 2.0, base.shape), 0, 255).astype(np.uint8)
    write_png(tmp_path / "photo.png", img, photo=True)
    write_png(tmp_path / "plain.png", img)
    np.testing.assert_array_equal(read_png(tmp_path / "photo.png"), img)
    assert (tmp_path / "photo.png").stat().st_size < (tmp_path / "plain.png").stat().st_size
