"""The IBISCape paper's evaluation table from many runs.

One row per sequence, one column group per algorithm: ATE [m] (RMSE of the translation errors,
the headline number of evo and of the paper), RPE [m] and RPE [deg] as ``mean ± std``, and the
trials that succeeded (``ok/total``).  With several trials, every number is the median over the
successful trials of that per-trial statistic (robust to one diverged trial; the success rate says
how many there were).  Where two or more algorithms have a value in a row, the lowest of each
metric, compared at the printed precision, is in bold (ties are all bold); with one there is no
comparison and nothing is bold.  A sequence an algorithm has no run for is ``--`` (no estimate), one
whose every trial failed is ``failed``.

Every rendering carries a caption that says how the numbers were made: the alignment (per
algorithm when they differ), the RPE pair distance and its unit, what is a median, what bold and the
marks mean.  Written as Markdown, LaTeX (plain ``tabular``, no package needed; labels derived from
the content: ``table:ate``, ``table:rpe``, ``table:ate-rpe``), CSV (one line per sequence and
algorithm, full precision) and an HTML ``<table>`` in a box that scrolls sideways when the page is
narrower than the table, for :mod:`ibiscape_eval.report.html`.
"""

from __future__ import annotations

import csv
import html
import io
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .runs import natural_key

__all__ = ["METRICS", "Cell", "PaperTable"]

# key, column label
METRICS: tuple[tuple[str, str], ...] = (
    ("ate_m", "ATE [m]"),
    ("rpe_m", "RPE [m]"),
    ("rpe_deg", "RPE [deg]"),
)
DECIMALS = 4
NO_ESTIMATE = "--"
FAILED = "failed"
#: what each alignment fixes, for captions
ALIGN_TEXT = {
    "none": "none (raw poses)",
    "origin": "origin (first poses superposed)",
    "se3": "se3 (rotation and translation, Umeyama)",
    "sim3": "sim3 (rotation, translation and scale, Umeyama)",
    "yaw": "yaw (4-DoF: translation and yaw)",
}
_DELTA_UNIT = {"frames": ("frame", "frames"), "seconds": ("s", "s"), "metres": ("m", "m"),
               "degrees": ("deg", "deg")}


def rpe_setting_text(delta: float, unit: str, pairs: str) -> str:
    """``"1 frame apart, consecutive pairs"`` and the like."""
    one, many = _DELTA_UNIT.get(unit, (unit, unit))
    return f"{delta:g} {one if delta == 1 else many} apart, {pairs} pairs"


def _median(values: list[float]) -> float | None:
    v = [x for x in values if x is not None and math.isfinite(x)]
    return float(np.median(v)) if v else None


def _get(doc: Any, *path: str) -> float | None:
    for p in path:
        if not isinstance(doc, dict) or doc.get(p) is None:
            return None
        doc = doc[p]
    return float(doc)


@dataclass(frozen=True)
class Cell:
    """One sequence × algorithm: medians over the successful trials (None when there are none)."""

    n_trials: int
    n_ok: int
    ate_m: float | None = None
    rpe_m_mean: float | None = None
    rpe_m_std: float | None = None
    rpe_deg_mean: float | None = None
    rpe_deg_std: float | None = None
    drift_pct: float | None = None
    drift_deg_per_m: float | None = None

    @property
    def success_rate(self) -> float:
        return self.n_ok / self.n_trials if self.n_trials else 0.0

    def value(self, metric: str) -> float | None:
        """The number that decides "best" for ``metric`` (ATE RMSE, RPE mean)."""
        return {"ate_m": self.ate_m, "rpe_m": self.rpe_m_mean,
                "rpe_deg": self.rpe_deg_mean}[metric]

    def std(self, metric: str) -> float | None:
        return {"ate_m": None, "rpe_m": self.rpe_m_std, "rpe_deg": self.rpe_deg_std}[metric]

    @classmethod
    def from_runs(cls, runs: Sequence[dict[str, Any]]) -> Cell:
        ok = [r for r in runs if r.get("status") == "ok"]

        def med(*path: str) -> float | None:
            return _median([v for r in ok if (v := _get(r, *path)) is not None])

        return cls(
            n_trials=len(runs),
            n_ok=len(ok),
            ate_m=med("ate", "translation_m", "rmse"),
            rpe_m_mean=med("rpe", "translation_m", "mean"),
            rpe_m_std=med("rpe", "translation_m", "std"),
            rpe_deg_mean=med("rpe", "rotation_deg", "mean"),
            rpe_deg_std=med("rpe", "rotation_deg", "std"),
            drift_pct=med("drift", "mean_translation_pct"),
            drift_deg_per_m=med("drift", "mean_rotation_deg_per_m"),
        )


def _fmt(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.{DECIMALS}f}"


def _tex_escape(text: str) -> str:
    out = []
    for ch in text:
        if ch in "&%$#_{}":
            out.append("\\" + ch)
        elif ch == "\\":
            out.append(r"\textbackslash{}")
        elif ch == "~":
            out.append(r"\textasciitilde{}")
        elif ch == "^":
            out.append(r"\textasciicircum{}")
        else:
            out.append(ch)
    return "".join(out)


def _md_escape(text: str) -> str:
    return text.replace("\\", "\\\\").replace("|", "\\|").replace("*", "\\*").replace("_", "\\_")


@dataclass(frozen=True)
class PaperTable:
    """The table: ``cells[(sequence, algorithm)]`` and which are best per row and metric."""

    sequences: tuple[str, ...]
    algorithms: tuple[str, ...]
    cells: dict[tuple[str, str], Cell]
    #: algorithm -> alignment of its runs ("se3/sim3" if records disagree)
    alignments: dict[str, str] = field(default_factory=dict)
    #: the RPE pair settings of the runs, e.g. ("1 frame apart, consecutive pairs",)
    rpe_settings: tuple[str, ...] = ()

    @classmethod
    def from_runs(cls, runs: Sequence[dict[str, Any]]) -> PaperTable:
        """Group run records (``sequence, algorithm, status, align, ate, rpe, drift``) into
        cells; the alignment of each algorithm comes from ``align`` (or ``ate.alignment``), the
        RPE setting from ``rpe.delta``, ``rpe.delta_unit`` and ``rpe.pairs``."""
        groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
        aligns: dict[str, list[str]] = {}
        rpe: list[str] = []
        for r in runs:
            groups.setdefault((r["sequence"], r["algorithm"]), []).append(r)
            al = r.get("align") or (r.get("ate") or {}).get("alignment")
            if al and al not in aligns.setdefault(r["algorithm"], []):
                aligns[r["algorithm"]].append(str(al))
            doc = r.get("rpe") or {}
            if doc.get("delta") is not None and doc.get("delta_unit"):
                text = rpe_setting_text(float(doc["delta"]), str(doc["delta_unit"]),
                                        str(doc.get("pairs") or "consecutive"))
                if text not in rpe:
                    rpe.append(text)
        seqs = tuple(sorted({s for s, _ in groups}, key=natural_key))
        algs = tuple(sorted({a for _, a in groups}, key=natural_key))
        return cls(seqs, algs, {k: Cell.from_runs(v) for k, v in groups.items()},
                   {a: "/".join(v) for a, v in aligns.items()}, tuple(rpe))

    def __repr__(self) -> str:
        return f"PaperTable({len(self.sequences)} sequences x {len(self.algorithms)} algorithms)"

    def cell(self, sequence: str, algorithm: str) -> Cell | None:
        return self.cells.get((sequence, algorithm))

    def is_best(self, sequence: str, algorithm: str, metric: str) -> bool:
        """Whether this cell has the row's lowest ``metric`` at the printed precision, among two
        or more algorithms with a value (one value alone is no comparison: never best)."""
        c = self.cell(sequence, algorithm)
        if c is None or c.value(metric) is None:
            return False
        shown = [round(v, DECIMALS) for a in self.algorithms
                 if (o := self.cell(sequence, a)) is not None and (v := o.value(metric)) is not None]
        return len(shown) >= 2 and round(c.value(metric) or 0.0, DECIMALS) == min(shown)

    # -- captions -------------------------------------------------------------------------------
    def _marks(self) -> set[str]:
        """Which marks the table shows: ``--`` (no estimate), ``failed``, ``n/a``."""
        out = set()
        for s in self.sequences:
            for a in self.algorithms:
                c = self.cell(s, a)
                if c is None:
                    out.add(NO_ESTIMATE)
                elif c.n_ok == 0:
                    out.add(FAILED)
                elif any(c.value(m) is None for m, _ in METRICS):
                    out.add("n/a")
        return out

    def _any_bold(self, metrics: Sequence[str]) -> bool:
        return any(self.is_best(s, a, m) for s in self.sequences for a in self.algorithms
                   for m in metrics)

    def alignment_text(self, esc: Callable[[str], str] = str) -> str:
        """``"Alignment: se3 (...)"``, or per algorithm when they differ."""
        used = {self.alignments.get(a, "?") for a in self.algorithms}
        if len(used) == 1:
            (al,) = used
            return f"Alignment: {ALIGN_TEXT.get(al, al)}, every algorithm."
        groups: dict[str, list[str]] = {}
        for a in self.algorithms:
            groups.setdefault(self.alignments.get(a, "?"), []).append(esc(a))
        return "Alignment per algorithm: " + "; ".join(
            f"{', '.join(algs)}: {al}" for al, algs in groups.items()) + "."

    def caption(self, metrics: Sequence[str] | None = None, *, esc: Callable[[str], str] = str,
                pm: str = "±") -> str:
        """What the table's numbers are and how they were made (plain text; ``esc`` escapes the
        algorithm names and ``pm`` is the plus-minus sign of the target format)."""
        ms = [m for m, _ in METRICS] if metrics is None else list(metrics)
        parts = []
        if "ate_m" in ms:
            parts.append("ATE [m]: RMSE of the translation errors.")
        if any(m.startswith("rpe") for m in ms):
            units = ", ".join(lab.removeprefix("RPE ") for m, lab in METRICS
                              if m in ms and m.startswith("rpe"))
            setting = "; ".join(self.rpe_settings) or "pair distance not recorded"
            parts.append(f"RPE {units}: mean {pm} std over pose pairs {setting}.")
            if any("frame" in t for t in self.rpe_settings):
                parts.append("(A distance in frames depends on each sequence's frame rate.)")
        parts.append(self.alignment_text(esc))
        parts.append("Median over the successful trials (ok/total).")
        if self._any_bold(ms):
            parts.append("Bold: lowest of the row.")
        marks = self._marks()
        legend = []
        if NO_ESTIMATE in marks:
            legend.append(f"{NO_ESTIMATE}: no estimate")
        if FAILED in marks:
            legend.append(f"{FAILED}: every trial failed")
        if "n/a" in marks:
            legend.append("n/a: not computable")
        if legend:
            parts.append("; ".join(legend) + ".")
        return " ".join(parts)

    # -- text of one entry ----------------------------------------------------------------------
    def _entry(self, seq: str, alg: str, metric: str, pm: str) -> tuple[str, bool]:
        c = self.cell(seq, alg)
        if c is None:
            return NO_ESTIMATE, False
        v = c.value(metric)
        if v is None:
            return FAILED if c.n_ok == 0 else "n/a", False
        s = c.std(metric)
        text = _fmt(v) if metric == "ate_m" else f"{_fmt(v)}{pm}{_fmt(s)}"
        return text, self.is_best(seq, alg, metric)

    @staticmethod
    def _trials(c: Cell | None) -> str:
        return NO_ESTIMATE if c is None else f"{c.n_ok}/{c.n_trials}"

    # -- formats --------------------------------------------------------------------------------
    def to_markdown(self) -> str:
        """A GitHub-flavoured Markdown table (bold = best of the row) and its caption below."""
        head = ["Sequence"]
        for a in self.algorithms:
            head += [f"{_md_escape(a)} {label}" for _, label in METRICS] + [f"{_md_escape(a)} ok"]
        lines = ["| " + " | ".join(head) + " |",
                 "|" + "|".join([":---"] + ["---:"] * (len(head) - 1)) + "|"]
        for s in self.sequences:
            row = [_md_escape(s)]
            for a in self.algorithms:
                for m, _ in METRICS:
                    text, best = self._entry(s, a, m, " ± ")
                    row.append(f"**{text}**" if best else text)
                row.append(self._trials(self.cell(s, a)))
            lines.append("| " + " | ".join(row) + " |")
        return "\n".join(lines) + "\n\n" + self.caption(esc=_md_escape) + "\n"

    @staticmethod
    def default_label(metrics: Sequence[str]) -> str:
        """``table:ate``, ``table:rpe`` or ``table:ate-rpe``: from the metrics the table shows."""
        parts = [p for p, on in (("ate", any(m.startswith("ate") for m in metrics)),
                                 ("rpe", any(m.startswith("rpe") for m in metrics))) if on]
        return "table:" + "-".join(parts)

    def to_latex(self, *, metrics: Sequence[str] | None = None, caption: str | None = None,
                 label: str | None = None) -> str:
        """A ``table`` with a plain ``tabular`` (compiles with LaTeX alone, no packages).

        ``metrics``: keys of :data:`METRICS` to show (default all); ``caption`` is put before
        the generated one (which states alignment, RPE distance and unit); ``label`` defaults to
        :meth:`default_label` of the metrics, so two tables of one report never share one.
        """
        ms = [m for m, _ in METRICS if metrics is None or m in metrics]
        labels = dict(METRICS)
        n = len(ms) + 1
        cols = "l" + "|".join(["c" * n] * len(self.algorithms))
        cap = self.caption(ms, esc=_tex_escape, pm="$\\pm$")
        if caption:
            cap = f"{caption} {cap}"
        lab = label or self.default_label(ms)
        out = [r"\begin{table}[htbp]", r"  \centering", f"  \\caption{{{cap}}}\\label{{{lab}}}",
               f"  \\begin{{tabular}}{{|{cols}|}}", r"    \hline"]
        top = ["\\multicolumn{1}{|l|}{Sequence}"] + [
            f"\\multicolumn{{{n}}}{{c|}}{{{_tex_escape(a)}}}" for a in self.algorithms]
        out.append("    " + " & ".join(top) + r" \\")
        sub = [""] + [lab for _ in self.algorithms for lab in [*(labels[m] for m in ms), "ok"]]
        out.append("    " + " & ".join(sub) + r" \\")
        out.append(r"    \hline")
        for s in self.sequences:
            row = [f"\\texttt{{{_tex_escape(s)}}}"]
            for a in self.algorithms:
                for m in ms:
                    text, best = self._entry(s, a, m, "$\\pm$")
                    row.append(f"\\textbf{{{text}}}" if best else text)
                row.append(self._trials(self.cell(s, a)))
            out.append("    " + " & ".join(row) + r" \\")
        out += [r"    \hline", r"  \end{tabular}", r"\end{table}"]
        return "\n".join(out) + "\n"

    def to_latex_tables(self) -> str:
        """The report's ``table.tex``: an ATE table (``table:ate``) and an RPE table
        (``table:rpe``), each narrow enough for a paper's column with a few algorithms."""
        return (self.to_latex(metrics=("ate_m",)) + "\n"
                + self.to_latex(metrics=("rpe_m", "rpe_deg")))

    def to_csv(self) -> str:
        """One line per sequence and algorithm, full precision, empty fields for missing values."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["sequence", "algorithm", "n_trials", "n_ok", "success_rate", "ate_rmse_m",
                    "rpe_m_mean", "rpe_m_std", "rpe_deg_mean", "rpe_deg_std",
                    "drift_translation_pct", "drift_rotation_deg_per_m",
                    "best_ate_m", "best_rpe_m", "best_rpe_deg", "alignment"])
        for s in self.sequences:
            for a in self.algorithms:
                c = self.cell(s, a)
                if c is None:
                    continue
                vals = [c.ate_m, c.rpe_m_mean, c.rpe_m_std, c.rpe_deg_mean, c.rpe_deg_std,
                        c.drift_pct, c.drift_deg_per_m]
                w.writerow([s, a, c.n_trials, c.n_ok, repr(c.success_rate),
                            *("" if v is None else repr(v) for v in vals),
                            *(int(self.is_best(s, a, m)) for m, _ in METRICS),
                            self.alignments.get(a, "")])
        return buf.getvalue()

    def to_html(self) -> str:
        """An HTML ``<table class="evaluation">`` (best of the row in ``<strong>``) inside a
        ``<div class="table-scroll">`` (scrolls sideways in a page narrower than the table),
        its caption in a ``<p class="caption">`` below."""
        n = len(METRICS) + 1
        h = ['<div class="table-scroll">', '<table class="evaluation">', "<thead>",
             "<tr><th rowspan=\"2\">Sequence</th>"]
        h += [f'<th colspan="{n}">{html.escape(a)}</th>' for a in self.algorithms]
        h.append("</tr><tr>")
        h += [f"<th>{html.escape(lab)}</th>" for _ in self.algorithms
              for lab in [*(m[1] for m in METRICS), "ok"]]
        h += ["</tr>", "</thead>", "<tbody>"]
        for s in self.sequences:
            row = [f"<tr><th>{html.escape(s)}</th>"]
            for a in self.algorithms:
                for m, _ in METRICS:
                    text, best = self._entry(s, a, m, " ± ")
                    t = html.escape(text)
                    row.append(f"<td><strong>{t}</strong></td>" if best else f"<td>{t}</td>")
                row.append(f"<td>{self._trials(self.cell(s, a))}</td>")
            h.append("".join(row) + "</tr>")
        h += ["</tbody>", "</table>", "</div>",
              f'<p class="caption">{html.escape(self.caption())}</p>']
        return "\n".join(h) + "\n"

    def to_dict(self) -> dict[str, Any]:
        """``{"sequences", "algorithms", "cells": [{sequence, algorithm, ...}]}``."""
        rows = []
        for s in self.sequences:
            for a in self.algorithms:
                c = self.cell(s, a)
                if c is not None:
                    rows.append({"sequence": s, "algorithm": a, "n_trials": c.n_trials,
                                 "n_ok": c.n_ok, "success_rate": c.success_rate,
                                 "alignment": self.alignments.get(a),
                                 "ate_rmse_m": c.ate_m, "rpe_m_mean": c.rpe_m_mean,
                                 "rpe_m_std": c.rpe_m_std, "rpe_deg_mean": c.rpe_deg_mean,
                                 "rpe_deg_std": c.rpe_deg_std, "drift_translation_pct": c.drift_pct,
                                 "drift_rotation_deg_per_m": c.drift_deg_per_m})
        return {"sequences": list(self.sequences), "algorithms": list(self.algorithms),
                "alignments": dict(self.alignments), "rpe_settings": list(self.rpe_settings),
                "caption": self.caption(), "cells": rows}
