"""Short ``repr`` and Jupyter tables of result objects, built from their ``to_dict()``.

A result holds arrays of thousands of poses; printing it in a notebook should show a few lines
(what was matched, the headline statistics), not the arrays.  Both helpers take any object with
``to_dict()``: scalar entries become ``key=value`` pairs, entries that are dictionaries of
statistics (``rmse``, ``mean``, ...) become one row each, lists and matrices are left out.
"""

from __future__ import annotations

import html
import math
from typing import Any

__all__ = ["summary_html", "summary_repr"]

_STAT_KEYS = ("rmse", "mean", "median", "std", "min", "max")
_MAX_SCALARS = 12


def _fmt(v: Any) -> str:
    if isinstance(v, bool) or v is None:
        return str(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.6g}"
    return str(v)


def _parts(doc: dict[str, Any]) -> tuple[list[tuple[str, Any]], list[tuple[str, dict[str, Any]]]]:
    scalars: list[tuple[str, Any]] = []
    stats: list[tuple[str, dict[str, Any]]] = []
    for k, v in doc.items():
        if isinstance(v, dict) and any(s in v for s in _STAT_KEYS):
            stats.append((k, v))
        elif isinstance(v, str | int | float | bool) or v is None:
            scalars.append((k, v))
    return scalars[:_MAX_SCALARS], stats


def summary_repr(obj: Any, name: str) -> str:
    """``Name(key=value, ...)`` with one indented line per statistics block."""
    scalars, stats = _parts(obj.to_dict())
    head = ", ".join(f"{k}={_fmt(v)}" for k, v in scalars)
    lines = [f"{name}({head}"]
    for k, st in stats:
        vals = ", ".join(f"{s}={_fmt(st.get(s))}" for s in _STAT_KEYS if s in st)
        lines.append(f"  {k}: {vals}")
    return "\n".join(lines) + ")"


def summary_html(obj: Any, title: str) -> str:
    """An HTML table: the statistics blocks as rows, then the scalar entries."""
    scalars, stats = _parts(obj.to_dict())
    esc = html.escape
    rows = [f"<caption>{esc(title)}</caption>"]
    if stats:
        rows.append("<tr><th></th>" + "".join(f"<th>{s}</th>" for s in _STAT_KEYS) + "</tr>")
        for k, st in stats:
            cells = "".join(f"<td>{esc(_fmt(st.get(s)))}</td>" for s in _STAT_KEYS)
            rows.append(f"<tr><th>{esc(k)}</th>{cells}</tr>")
    for k, v in scalars:
        rows.append(f"<tr><th>{esc(k)}</th><td colspan='6'>{esc(_fmt(v))}</td></tr>")
    return "<table>" + "".join(rows) + "</table>"
