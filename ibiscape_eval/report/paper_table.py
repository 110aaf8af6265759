"""The IBISCape paper's evaluation table (``table:evaluation``) from many runs.

One row per sequence, one column group per algorithm: ATE [m] (RMSE of the translation errors,
the headline number of evo and of the paper), RPE [m] and RPE [deg] as ``mean ± std``, and the
trials that succeeded (``ok/total``).  With several trials, every number is the median over the
successful trials of that per-trial statistic (robust to one diverged trial; the success rate says
how many there were).  In every row the lowest value of each metric, compared at the printed
precision, is in bold (ties are all bold).

Written as Markdown, LaTeX (plain ``tabular``, no package needed), CSV (one line per sequence and
algorithm, full precision) and an HTML ``<table>`` for :mod:`ibiscape_eval.report.html`.
"""

from __future__ import annotations

import csv
import html
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass
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

    @classmethod
    def from_runs(cls, runs: Sequence[dict[str, Any]]) -> PaperTable:
        """Group run records (``sequence, algorithm, status, ate, rpe, drift``) into cells."""
        groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
        for r in runs:
            groups.setdefault((r["sequence"], r["algorithm"]), []).append(r)
        seqs = tuple(sorted({s for s, _ in groups}, key=natural_key))
        algs = tuple(sorted({a for _, a in groups}, key=natural_key))
        return cls(seqs, algs, {k: Cell.from_runs(v) for k, v in groups.items()})

    def __repr__(self) -> str:
        return f"PaperTable({len(self.sequences)} sequences x {len(self.algorithms)} algorithms)"

    def cell(self, sequence: str, algorithm: str) -> Cell | None:
        return self.cells.get((sequence, algorithm))

    def is_best(self, sequence: str, algorithm: str, metric: str) -> bool:
        """Whether this cell has the row's lowest ``metric`` at the printed precision."""
        c = self.cell(sequence, algorithm)
        if c is None or c.value(metric) is None:
            return False
        shown = [round(v, DECIMALS) for a in self.algorithms
                 if (o := self.cell(sequence, a)) is not None and (v := o.value(metric)) is not None]
        return round(c.value(metric) or 0.0, DECIMALS) == min(shown)

    # -- text of one entry ----------------------------------------------------------------------
    def _entry(self, seq: str, alg: str, metric: str, pm: str) -> tuple[str, bool]:
        c = self.cell(seq, alg)
        if c is None:
            return "", False
        v = c.value(metric)
        if v is None:
            return "failed" if c.n_ok == 0 else "n/a", False
        s = c.std(metric)
        text = _fmt(v) if metric == "ate_m" else f"{_fmt(v)}{pm}{_fmt(s)}"
        return text, self.is_best(seq, alg, metric)

    @staticmethod
    def _trials(c: Cell | None) -> str:
        return "" if c is None else f"{c.n_ok}/{c.n_trials}"

    # -- formats --------------------------------------------------------------------------------
    def to_markdown(self) -> str:
        """A GitHub-flavoured Markdown table (bold = best of the row)."""
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
        return "\n".join(lines) + "\n"

    def to_latex(self, *, caption: str | None = None, label: str = "table:evaluation") -> str:
        """A ``table`` with a plain ``tabular`` (compiles with LaTeX alone, no packages)."""
        n = len(METRICS) + 1
        cols = "l" + "|".join(["c" * n] * len(self.algorithms))
        cap = caption or ("ATE (RMSE) and RPE (mean $\\pm$ std) per sequence and algorithm; "
                          "median over successful trials (ok/total); best in bold.")
        out = [r"\begin{table}[htbp]", r"  \centering", f"  \\caption{{{cap}}}\\label{{{label}}}",
               f"  \\begin{{tabular}}{{|{cols}|}}", r"    \hline"]
        top = ["\\multicolumn{1}{|l|}{Sequence}"] + [
            f"\\multicolumn{{{n}}}{{c|}}{{{_tex_escape(a)}}}" for a in self.algorithms]
        out.append("    " + " & ".join(top) + r" \\")
        sub = [""] + [lab for _ in self.algorithms for lab in [*(m[1] for m in METRICS), "ok"]]
        out.append("    " + " & ".join(sub) + r" \\")
        out.append(r"    \hline")
        for s in self.sequences:
            row = [f"\\texttt{{{_tex_escape(s)}}}"]
            for a in self.algorithms:
                for m, _ in METRICS:
                    text, best = self._entry(s, a, m, "$\\pm$")
                    row.append(f"\\textbf{{{text}}}" if best else text)
                row.append(self._trials(self.cell(s, a)))
            out.append("    " + " & ".join(row) + r" \\")
        out += [r"    \hline", r"  \end{tabular}", r"\end{table}"]
        return "\n".join(out) + "\n"

    def to_csv(self) -> str:
        """One line per sequence and algorithm, full precision, empty fields for missing values."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["sequence", "algorithm", "n_trials", "n_ok", "success_rate", "ate_rmse_m",
                    "rpe_m_mean", "rpe_m_std", "rpe_deg_mean", "rpe_deg_std",
                    "drift_translation_pct", "drift_rotation_deg_per_m",
                    "best_ate_m", "best_rpe_m", "best_rpe_deg"])
        for s in self.sequences:
            for a in self.algorithms:
                c = self.cell(s, a)
                if c is None:
                    continue
                vals = [c.ate_m, c.rpe_m_mean, c.rpe_m_std, c.rpe_deg_mean, c.rpe_deg_std,
                        c.drift_pct, c.drift_deg_per_m]
                w.writerow([s, a, c.n_trials, c.n_ok, repr(c.success_rate),
                            *("" if v is None else repr(v) for v in vals),
                            *(int(self.is_best(s, a, m)) for m, _ in METRICS)])
        return buf.getvalue()

    def to_html(self) -> str:
        """An HTML ``<table class="evaluation">`` (best of the row in ``<strong>``)."""
        n = len(METRICS) + 1
        h = ['<table class="evaluation">', "<thead>", "<tr><th rowspan=\"2\">Sequence</th>"]
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
        h += ["</tbody>", "</table>"]
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
                                 "ate_rmse_m": c.ate_m, "rpe_m_mean": c.rpe_m_mean,
                                 "rpe_m_std": c.rpe_m_std, "rpe_deg_mean": c.rpe_deg_mean,
                                 "rpe_deg_std": c.rpe_deg_std, "drift_translation_pct": c.drift_pct,
                                 "drift_rotation_deg_per_m": c.drift_deg_per_m})
        return {"sequences": list(self.sequences), "algorithms": list(self.algorithms),
                "cells": rows}
