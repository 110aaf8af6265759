"""Write a report folder from a :class:`~ibiscape_eval.report.evaluate.RunsEvaluation`.

``write_report(out, evaluation)`` creates, atomically (the folder appears complete or not at all)::

    out/
      table.md  table.csv              the paper-style table (see paper_table), with its caption
      table.tex                        two LaTeX tables: ATE (table:ate) and RPE (table:rpe)
      runs.csv                         one line per run (status, error, every statistic)
      report.json                      the ``report --json`` document plus the table
      report.html                      self-contained page, figures embedded
      figures/trajectories_<sequence>.png   ground truth, GNSS, aligned estimates (in the plot
                                       plane of the ground truth's format: KITTI x-z, else x-y)
      figures/errors_boxplot.png       ATE/RPE error distributions per sequence and algorithm
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from ibiscape_eval.batch.files import atomic_output_dir
from ibiscape_eval.core.errors import IbiscapeError, IbiscapeWarning, Remedy

from .evaluate import RunsEvaluation
from .paper_table import PaperTable

__all__ = ["ReportFiles", "runs_csv", "sequence_figures", "write_report"]

ReportFiles = dict[str, str]


def _safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("._") or "sequence"


def runs_csv(evaluation: RunsEvaluation) -> str:
    """One line per run: identity, alignment, status, statistics, error message."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    cols = ["sequence", "algorithm", "trial", "align", "status", "n_matched", "ate_rmse_m",
            "ate_mean_m", "ate_rot_rmse_deg", "rpe_m_mean", "rpe_m_std", "rpe_deg_mean", "rpe_deg_std",
            "drift_translation_pct", "drift_rotation_deg_per_m", "error", "path"]
    w.writerow(cols)

    def g(d: Any, *path: str) -> str:
        for p in path:
            if not isinstance(d, dict) or d.get(p) is None:
                return ""
            d = d[p]
        return repr(float(d))

    for r in evaluation.runs:
        w.writerow([r["sequence"], r["algorithm"], r["trial"], r.get("align") or "", r["status"],
                    "" if r.get("n_matched") is None else r["n_matched"],
                    g(r, "ate", "translation_m", "rmse"), g(r, "ate", "translation_m", "mean"),
                    g(r, "ate", "rotation_deg", "rmse"),
                    g(r, "rpe", "translation_m", "mean"), g(r, "rpe", "translation_m", "std"),
                    g(r, "rpe", "rotation_deg", "mean"), g(r, "rpe", "rotation_deg", "std"),
                    g(r, "drift", "mean_translation_pct"),
                    g(r, "drift", "mean_rotation_deg_per_m"),
                    r.get("error") or "", r["path"]])
    return buf.getvalue()


def _alignment_of(evaluation: RunsEvaluation) -> dict[str, str]:
    """Algorithm -> alignment its runs were evaluated with."""
    if evaluation.alignments:
        return {a: al for a, (al, _) in evaluation.alignments.items()}
    return {a: evaluation.options.align for a in evaluation.layout.algorithms}


def sequence_figures(
    evaluation: RunsEvaluation, *, plot_plane: str | None = None
) -> list[tuple[str, str, bytes]]:
    """``(file name, caption, png)`` of every figure: one view of each sequence and the box
    plots.  A GNSS file that cannot be placed is left out of its figure with a warning.

    ``plot_plane`` (``"xy"``, ``"xz"``, ``"yz"``) is the plane of the trajectory figures; by
    default each sequence's comes from its ground truth's format
    (:func:`ibiscape_eval.report.plots.default_plot_plane`: x-z for KITTI, x-y otherwise).
    """
    from ibiscape_eval.io import detect_trajectory_format, read_gnss, read_trajectory
    from ibiscape_eval.io.figure import figure_png

    from ..metrics.gnss import gnss_in_reference_frame
    from .figures import (
        algorithm_colors,
        error_boxplot_figure,
        representative_runs,
        sequence_trajectories_figure,
    )
    from .plots import PLOT_PLANES, default_plot_plane

    if plot_plane is not None and plot_plane not in PLOT_PLANES:
        raise IbiscapeError(f"unknown plot plane {plot_plane!r}; use one of "
                            f"{', '.join(PLOT_PLANES)}")
    reps = representative_runs(evaluation.runs)
    colors = algorithm_colors(evaluation.layout.algorithms)
    aligns = _alignment_of(evaluation)
    mixed = len(set(aligns.values())) > 1
    # with different alignments the legend says each algorithm's
    name = {a: (f"{a} ({al})" if mixed else a) for a, al in aligns.items()}
    legend_colors = {name[a]: c for a, c in colors.items() if a in name}
    title_align = "per algorithm" if mixed else next(iter(aligns.values()), "se3")
    out = []
    for seq in evaluation.layout.sequences:
        truth = evaluation.layout.truths[seq]
        tracks = {name[a]: r["track_xyz_m"] for (s, a), r in sorted(reps.items())
                  if s == seq and r.get("track_xyz_m")}
        try:
            gt = read_trajectory(truth.groundtruth)
            plane = plot_plane or default_plot_plane(detect_trajectory_format(truth.groundtruth))
        except (IbiscapeError, OSError) as e:
            warnings.warn(f"figure of {seq} left out: {e}", IbiscapeWarning, stacklevel=2)
            continue
        gnss = None
        if truth.gnss is not None:
            try:
                fx = read_gnss(truth.gnss)
                gnss = gnss_in_reference_frame(fx.stamps_ns, fx.lat_deg, fx.lon_deg, fx.alt_m, gt)
            except (IbiscapeError, OSError) as e:
                warnings.warn(f"{truth.gnss}: GNSS left out of the figure of {seq}: {e}",
                              IbiscapeWarning, stacklevel=2)
        fig = sequence_trajectories_figure(
            seq, gt.pos_m,
            {a: np.asarray(xyz, dtype=np.float64).reshape(-1, 3) for a, xyz in tracks.items()},
            gnss_xyz_m=None if gnss is None else np.asarray(gnss),
            align=title_align, colors=legend_colors, plane=plane)
        out.append((f"trajectories_{_safe_name(seq)}.png",
                    f"{seq} ({plane[0]}-{plane[1]} plane): ground truth"
                    f"{', GNSS' if gnss is not None else ''} and the aligned estimate of each "
                    f"algorithm (median-ATE trial; {_align_caption(aligns)})", figure_png(fig)))
    if reps:
        out.append(("errors_boxplot.png", "ATE and RPE error distributions per sequence and "
                    "algorithm (median-ATE trial)", figure_png(error_boxplot_figure(
                        evaluation.runs, colors=colors))))
    return out


def _align_caption(aligns: dict[str, str]) -> str:
    if len(set(aligns.values())) <= 1:
        return f"aligned: {next(iter(aligns.values()), 'se3')}"
    return "aligned: " + ", ".join(f"{a} {al}" for a, al in aligns.items())


def _shown_options(evaluation: RunsEvaluation) -> dict[str, Any]:
    """The options as the page's header shows them: the alignment each algorithm got."""
    opts = evaluation.options.to_dict()
    aligns = _alignment_of(evaluation)
    if len(set(aligns.values())) > 1:
        opts.pop("align_by_algorithm", None)
        opts["align"] = "per algorithm: " + ", ".join(f"{a} {al}" for a, al in aligns.items())
    return opts


def _check_out(out: Path) -> None:
    if out.exists() and not out.is_dir():
        raise IbiscapeError(f"{out}: exists and is a file; {{0}} needs a folder", hint=(Remedy("out"),))
    if out.is_dir() and any(out.iterdir()) and not (out / "report.json").is_file():
        raise IbiscapeError(
            f"{out}: folder exists, is not empty and holds no earlier report (report.json); "
            "choose a new or empty folder"
        )


def write_report(
    out: str | os.PathLike[str], evaluation: RunsEvaluation, *, figures: bool = True,
    plot_plane: str | None = None,
) -> ReportFiles:
    """Write the report folder ``out`` (see the module docstring); returns name -> path.

    An existing ``out`` is replaced only if it is empty or holds an earlier report.
    ``plot_plane``: see :func:`sequence_figures`.
    """
    target = Path(out)
    _check_out(target)
    table = PaperTable.from_runs(evaluation.runs)
    figs = sequence_figures(evaluation, plot_plane=plot_plane) if figures else []
    doc = evaluation.to_dict()
    doc["table"] = table.to_dict()
    from .html import report_html

    page = report_html(
        table,
        title=f"Evaluation of {Path(evaluation.layout.root).name or evaluation.layout.root}",
        options=_shown_options(evaluation),
        summary=evaluation.summary,
        figures=[(cap, png) for _, cap, png in figs],
        failed=[r for r in evaluation.runs if r["status"] != "ok"],
        ignored=evaluation.layout.ignored,
    )
    texts = {
        "table.md": table.to_markdown(),
        "table.tex": table.to_latex_tables(),
        "table.csv": table.to_csv(),
        "runs.csv": runs_csv(evaluation),
        "report.json": json.dumps(doc, indent=1, allow_nan=False) + "\n",
        "report.html": page,
    }
    with atomic_output_dir(target, overwrite=True) as tmp:
        for name, text in texts.items():
            (tmp / name).write_text(text, encoding="utf-8", newline="\n")
        if figs:
            (tmp / "figures").mkdir()
            for name, _, png in figs:
                (tmp / "figures" / name).write_bytes(png)
    files = {name: str(target / name) for name in texts}
    files.update({f"figures/{n}": str(target / "figures" / n) for n, _, _ in figs})
    return files
