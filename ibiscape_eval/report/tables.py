"""Plain-text tables for trajectory metrics, as the IBISCape paper prints them (mean +- std)."""

from __future__ import annotations

import math
from typing import Any

__all__ = ["format_drift_table", "format_error_table", "format_header"]

_STAT_KEYS = ("rmse", "mean", "median", "std", "min", "max", "sse")


def _fmt(v: float, width: int = 10) -> str:
    # one separating blank, then the number in width - 1 characters (4 decimals while they fit)
    w = width - 1
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return f" {'nan':>{w}}"
    return f" {v:>{w}.4f}" if abs(v) < 10 ** (w - 5) else f" {v:>{w}.4g}"


def format_header(doc: dict[str, Any], est_name: str, ref_name: str) -> str:
    """One line that says what was compared and how: matches, drops, alignment, offset."""
    parts = [
        f"{est_name} vs {ref_name}:",
        f"{doc['n_matched']} poses matched,",
        f"dropped {doc['n_dropped_est']} est / {doc['n_dropped_ref']} ref;",
        f"alignment {doc['alignment']}",
    ]
    if doc["alignment"] == "sim3":
        parts.append(f"(scale {doc['scale']:.6f})")
    parts.append(f"; time offset {doc['t_offset_s']:+.6f} s")
    return " ".join(parts).replace(" ;", ";")


def format_error_table(doc: dict[str, Any], *, title: str) -> str:
    """Statistics table of ``translation_m`` and ``rotation_deg`` plus the paper's mean +- std line."""
    tr, ro = doc["translation_m"], doc["rotation_deg"]
    lines = [title, f"{'':<16}" + "".join(f"{k:>10}" for k in _STAT_KEYS)]
    lines.append(f"{'translation [m]':<16}" + "".join(_fmt(tr[k]) for k in _STAT_KEYS))
    lines.append(f"{'rotation [deg]':<16}" + "".join(_fmt(ro[k]) for k in _STAT_KEYS))
    lines.append(
        f"mean ± std: {tr['mean']:.4f} ± {tr['std']:.4f} m, {ro['mean']:.4f} ± {ro['std']:.4f} deg"
    )
    return "\n".join(lines)


def format_drift_table(doc: dict[str, Any]) -> str:
    """Per-length KITTI drift table and the averages."""
    lines = [f"{'length [m]':>12}{'segments':>10}{'trans [%]':>12}{'rot [deg/m]':>14}"]
    for L, n, t, r in zip(
        doc["lengths_m"],
        doc["n_segments"],
        doc["translation_pct"],
        doc["rotation_deg_per_m"],
        strict=True,
    ):
        lines.append(f"{L:>12.2f}{n:>10d}{_fmt(t, 12)}{_fmt(r, 14)}")
    lines.append(
        f"{'average':>12}{sum(doc['n_segments']):>10d}{_fmt(doc['mean_translation_pct'], 12)}"
        f"{_fmt(doc['mean_rotation_deg_per_m'], 14)}"
    )
    return "\n".join(lines)
