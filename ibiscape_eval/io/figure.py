"""Figures to files and bytes: one resolution, atomic writes.

Every figure the project saves goes through :func:`save_figure` (a file, format from the suffix)
or :func:`figure_png` (PNG bytes for the HTML report): :data:`FIGURE_DPI` dots per inch, the
bounding box cropped to the drawn artists.  matplotlib is only needed by the caller that made the
figure; nothing here imports it.
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .atomic import atomic_output_path

__all__ = ["FIGURE_DPI", "figure_png", "save_figure", "save_figures"]

#: dots per inch of every saved figure (files and the report's embedded PNGs)
FIGURE_DPI = 150


def _savefig(fig: Any, target: Any, fmt: str) -> None:
    fig.savefig(target, dpi=FIGURE_DPI, bbox_inches="tight", format=fmt)


def save_figure(fig: Any, path: str | os.PathLike[str]) -> None:
    """Write ``fig`` to ``path`` (PNG, PDF, SVG ... by the suffix; PNG without one) atomically."""
    with atomic_output_path(path) as tmp:
        _savefig(fig, tmp, Path(path).suffix.lstrip(".").lower() or "png")


def save_figures(folder: str | os.PathLike[str], figures: Sequence[tuple[str, Any]]) -> list[Path]:
    """Save ``(file name, Figure)`` pairs into ``folder`` (created), each atomically."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    for name, fig in figures:
        save_figure(fig, out / name)
    return [out / name for name, _ in figures]


def figure_png(fig: Any) -> bytes:
    """The figure as PNG bytes."""
    buf = io.BytesIO()
    _savefig(fig, buf, "png")
    return buf.getvalue()
