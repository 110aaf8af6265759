"""A contact sheet of a rendered sequence: a few frames of every camera side by side in one PNG
(RGB as is, depth false-coloured, segmentation in the CityScapes palette, DVS event frames)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError

__all__ = ["contact_sheet"]


def _tile(img: np.ndarray, size: int) -> npt.NDArray[np.uint8]:
    import cv2

    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    h, w = img.shape[:2]
    s = size / max(h, w)
    out = cv2.resize(np.ascontiguousarray(img[..., :3]), (max(1, round(w * s)), max(1, round(h * s))),
                     interpolation=cv2.INTER_AREA)
    canvas = np.zeros((size, size, 3), np.uint8)
    canvas[: out.shape[0], : out.shape[1]] = out
    return canvas


def _depth_colour(path: Path) -> npt.NDArray[np.uint8]:
    import cv2

    from ibiscape_eval.io.images import read_depth_mm

    d = read_depth_mm(path)
    inv = np.where(np.isfinite(d), 1.0 / np.maximum(d, 0.1), 0.0)  # near = bright
    code = np.clip(inv / 0.5 * 255.0, 0, 255).astype(np.uint8)
    bgr = cv2.applyColorMap(code, cv2.COLORMAP_TURBO)
    bgr[~np.isfinite(d)] = 0
    return np.ascontiguousarray(bgr[..., ::-1])


def contact_sheet(seq_dir: str | os.PathLike[str], out_png: str | os.PathLike[str], *, n_frames: int = 4,
                  tile_px: int = 192) -> list[str]:
    """Write a contact sheet of ``seq_dir`` (rows: cameras, columns: ``n_frames`` evenly spaced
    frames) to ``out_png``.  Returns the camera rows drawn, top to bottom."""
    import cv2

    from ibiscape_eval.io.images import read_frame_timestamps, read_png, write_png
    from ibiscape_eval.io.sequence import read_sequence_yaml

    seq = Path(seq_dir)
    doc = read_sequence_yaml(seq / "sequence.yaml")
    rows, names = [], []
    for name, entry in (doc.get("cameras") or {}).items():
        if not entry.get("rendered"):
            continue
        kind = entry.get("kind", "rgb")
        folder = seq / name
        if kind == "dvs":
            files = sorted((folder / "frames").glob("*.png"))
        else:
            _, listed = read_frame_timestamps(folder / "timestamps.csv")
            files = [folder / ("mm" if kind == "depth" else "frames") / f for f in listed]
        if not files:
            continue
        pick = np.linspace(0, len(files) - 1, min(n_frames, len(files))).round().astype(int)
        tiles = []
        for i in pick:
            f = files[i]
            img = _depth_colour(f) if kind == "depth" else read_png(f)
            if img.dtype != np.uint8:
                img = (img / max(1, img.max()) * 255).astype(np.uint8)
            tiles.append(_tile(img, tile_px))
        while len(tiles) < n_frames:
            tiles.append(np.zeros((tile_px, tile_px, 3), np.uint8))
        row = np.concatenate(tiles, axis=1)
        cv2.putText(row, f"{name} ({kind})", (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 0), 1,
                    cv2.LINE_AA)
        rows.append(row)
        names.append(name)
    if not rows:
        raise IbiscapeError(f"{seq}: no rendered camera to show; generate it without --no-render")
    write_png(out_png, np.concatenate(rows, axis=0))
    return names
