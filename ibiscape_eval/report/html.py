"""A self-contained HTML page of a report: the table, the figures embedded as PNG data URIs, the
failed runs and the ignored paths.  No script, no external resource: the file can be mailed or
opened offline."""

from __future__ import annotations

import base64
import html
from collections.abc import Sequence
from typing import Any

from .paper_table import PaperTable

__all__ = ["report_html"]

# Readable at any width: the page never gets wider than the window.  A wide table scrolls sideways
# inside its own box (.table-scroll), long words (paths, option lists) break, figures shrink.
_CSS = """
*, *::before, *::after { box-sizing: border-box; }
body { font-family: sans-serif; margin: 2em auto; padding: 0 1em; color: #222;
       max-width: 1400px; overflow-wrap: anywhere; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.6em; }
.table-scroll { max-width: 100%; overflow-x: auto; margin: 0.6em 0; }
table { border-collapse: collapse; font-size: 0.9em; margin: 0.6em 0; }
.table-scroll > table { margin: 0; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.6em; text-align: right; white-space: nowrap;
         overflow-wrap: normal; }
thead th { background: #eee; text-align: center; }
tbody th { text-align: left; font-family: monospace; font-weight: normal; }
td strong { color: #000; }
figure { margin: 1em 0; display: inline-block; vertical-align: top; max-width: 100%; }
figure img { max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { font-size: 0.85em; color: #555; }
.meta, .caption { color: #555; font-size: 0.9em; }
.failed td, .ignored td { text-align: left; font-family: monospace; font-size: 0.85em;
                          white-space: normal; overflow-wrap: anywhere; }
"""


def _img(png: bytes, alt: str) -> str:
    data = base64.b64encode(png).decode("ascii")
    return f'<img src="data:image/png;base64,{data}" alt="{html.escape(alt)}">'


def report_html(
    table: PaperTable,
    *,
    title: str,
    options: dict[str, Any],
    summary: dict[str, Any],
    figures: Sequence[tuple[str, bytes]] = (),
    failed: Sequence[dict[str, Any]] = (),
    ignored: Sequence[tuple[str, str]] = (),
) -> str:
    """The page as text.

    Parameters
    ----------
    table : PaperTable
    title : str
    options, summary : dict
        Shown under the title (evaluation options, job counts).
    figures : sequence of (caption, png bytes)
    failed : sequence of dict
        Run records with ``status`` "failed" (``sequence, algorithm, trial, error``).
    ignored : sequence of (path, reason)
    """
    e = html.escape
    opts = ", ".join(f"{k} = {v}" for k, v in options.items())
    counts = ", ".join(f"{v} {k.removeprefix('n_')}" for k, v in summary.items())
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{e(title)}</title>",
        f"<style>{_CSS}</style>",
        "</head>",
        "<body>",
        f"<h1>{e(title)}</h1>",
        f'<p class="meta">{e(opts)}<br>runs: {e(counts)}</p>',
        "<h2>Evaluation</h2>",
        table.to_html(),  # with its caption: alignment, RPE distance and unit, marks
    ]
    if figures:
        parts.append("<h2>Figures</h2>")
        for caption, png in figures:
            parts.append(f"<figure>{_img(png, caption)}<figcaption>{e(caption)}</figcaption>"
                         "</figure>")
    if failed:
        parts += ["<h2>Failed runs</h2>", '<div class="table-scroll"><table class="failed">'
                  "<thead><tr><th>run</th><th>error</th></tr></thead><tbody>"]
        for r in failed:
            key = f"{r['sequence']}/{r['algorithm']}/{r['trial']}"
            parts.append(f"<tr><td>{e(key)}</td><td>{e(str(r.get('error')))}</td></tr>")
        parts.append("</tbody></table></div>")
    if ignored:
        parts += ["<h2>Ignored paths</h2>", '<div class="table-scroll"><table class="ignored">'
                  "<thead><tr><th>path</th><th>reason</th></tr></thead><tbody>"]
        for p, why in ignored:
            parts.append(f"<tr><td>{e(p)}</td><td>{e(why)}</td></tr>")
        parts.append("</tbody></table></div>")
    parts += ["</body>", "</html>"]
    return "\n".join(parts) + "\n"
