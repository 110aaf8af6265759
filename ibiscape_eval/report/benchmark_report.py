"""The benchmark's report: one set of tables in the paper's layout, as Markdown, HTML and JSON.

:func:`benchmark_tables` turns a :class:`~ibiscape_eval.benchmark.BenchmarkResult` into plain
tables (title, header, rows of text); :func:`benchmark_markdown` and :func:`benchmark_html` render
them (the HTML page is self-contained, like the ``report`` command's); :func:`write_benchmark_report`
writes ``report.md``, ``report.html``, ``report.json`` and the VIO table as LaTeX.
"""

from __future__ import annotations

import html
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .html import _CSS

if TYPE_CHECKING:
    from ibiscape_eval.benchmark import BenchmarkResult
    from ibiscape_eval.benchmark.results import StepRecord

__all__ = ["Table", "benchmark_html", "benchmark_markdown", "benchmark_tables",
           "write_benchmark_report"]


@dataclass(frozen=True)
class Table:
    """A titled table of text cells."""

    key: str
    title: str
    note: str
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]

    def to_markdown(self) -> str:
        lines = [f"## {self.title}", "", self.note, "",
                 "| " + " | ".join(self.header) + " |",
                 "|" + "|".join("---" for _ in self.header) + "|"]
        lines += ["| " + " | ".join(c.replace("|", "\\|") for c in r) + " |" for r in self.rows]
        if not self.rows:
            lines.append("| " + " | ".join(["(none)"] + [""] * (len(self.header) - 1)) + " |")
        return "\n".join(lines) + "\n"

    def to_html(self) -> str:
        e = html.escape
        head = "".join(f"<th>{e(h)}</th>" for h in self.header)
        body = "".join(_html_row(r) for r in self.rows)
        if not self.rows:
            body = f'<tr><td colspan="{len(self.header)}">(none)</td></tr>'
        return (f"<h2>{e(self.title)}</h2><p>{e(self.note)}</p>"
                f'<div class="table-scroll"><table><thead><tr>{head}</tr></thead>'
                f"<tbody>{body}</tbody></table></div>")


_NOTES = ("FAILED: ", "not applicable: ")
_EXTRA_CSS = "td.note { white-space: normal; text-align: left; max-width: 70em; }"


def _html_row(row: tuple[str, ...]) -> str:
    """A row; a failure or "not applicable" note spans the remaining columns and wraps."""
    e = html.escape
    cells = []
    for i, c in enumerate(row):
        if c.startswith(_NOTES):
            cells.append(f'<td class="note" colspan="{len(row) - i}">{e(c)}</td>')
            break
        cells.append(f"<td>{e(c)}</td>")
    return "<tr>" + "".join(cells) + "</tr>"


def _f(v: Any, fmt: str = ".3f") -> str:
    if v is None:
        return "–"
    try:
        return format(float(v), fmt)
    except (TypeError, ValueError):
        return str(v)


def _failed(rec: StepRecord[Any]) -> str:
    return f"FAILED: {rec.error}"


def _camera_tables(res: BenchmarkResult) -> list[Table]:
    intr: list[tuple[str, ...]] = []
    pairs: list[tuple[str, ...]] = []
    for r in res.steps.camera_calibration:
        v = r.value
        if not r.ok or v is None:
            intr.append((r.key, "", _failed(r), "", "", "", "", "", ""))
            continue
        for c in v.cameras:
            intr.append((r.key, c.camera, str(v.target), _f(c.fx_error_px), _f(c.fy_error_px),
                         _f(c.cx_error_px), _f(c.cy_error_px), _f(c.distortion_max_error, ".4f"),
                         _f(v.rms_px)))
        for p in v.chain:
            pairs.append((r.key, f"{p.from_camera} → {p.to_camera}", _f(p.baseline_truth_m),
                          _f(p.baseline_error_mm, ".2f"), _f(p.rotation_error_deg, ".4f")))
    return [
        Table("camera_intrinsics", "Camera calibration: intrinsics against the truth",
              "Errors of the estimate minus the simulated camera (table:camerasintrinsics); "
              "model pinhole-radtan; RMS reprojection error of the whole solve.",
              ("sequence", "camera", "target", "fx err [px]", "fy err [px]", "cx err [px]",
               "cy err [px]", "max |dist err|", "RMS [px]"), tuple(intr)),
        Table("baselines", "Camera calibration: stereo baselines against the truth",
              "table:baselines: baseline error [mm] and relative rotation error [deg].",
              ("sequence", "pair", "true baseline [m]", "baseline err [mm]",
               "rotation err [deg]"), tuple(pairs))]


def _imu_camera_table(res: BenchmarkResult) -> Table:
    rows: list[tuple[str, ...]] = []
    for r in res.steps.imu_camera:
        if not r.ok or r.value is None:
            rows.append((r.key, "", _failed(r), "", "", ""))
            continue
        for c in r.value.cameras:
            rows.append((r.key, c.camera, _f(c.rotation_error_deg, ".4f"),
                         _f(c.translation_error_mm, ".2f"), _f(c.timeshift_error_ms, ".4f"),
                         _f(c.reprojection_rms_px)))
    return Table("imu_camera", "Camera-IMU calibration against the truth",
                 "T_cam_imu rotation and translation errors, time offset error.",
                 ("sequence", "camera", "rotation err [deg]", "translation err [mm]",
                  "time offset err [ms]", "RMS [px]"), tuple(rows))


def _imu_noise_table(res: BenchmarkResult) -> Table:
    rows: list[tuple[str, ...]] = []
    for r in res.steps.imu_noise:
        v = r.value
        if not r.ok or v is None:
            rows.append((r.key, _failed(r), "", "", ""))
            continue
        for k in v.rows:
            rows.append((f"{r.key} ({_f(v.duration_h, '.2f')} h)", k.key, _f(k.truth, ".4g"),
                         _f(k.estimate, ".4g"), _f(k.error_pct, "+.1f")))
    return Table("imu_noise", "IMU noise (Allan deviation) against the configured truth",
                 "table:imuvalues: Kalibr densities (largest of the three axes), continuous time.",
                 ("sequence", "Kalibr key", "truth", "estimate", "error [%]"), tuple(rows))


def _hot_pixels_table(res: BenchmarkResult) -> Table:
    rows: list[tuple[str, ...]] = []
    for r in res.steps.hot_pixels:
        v = r.value
        if not r.ok or v is None:
            rows.append((r.key, _failed(r), "", "", "", "", ""))
            continue
        rows.append((r.key, f"{v.n_events:,}", str(v.n_hot_pixels), str(v.n_noisy_pixels),
                     _f(100 * (v.fraction_removed or 0.0), ".2f"), _f(v.precision),
                     _f(v.recall)))
    return Table("hot_pixels", "DVS hot pixels (n-sigma 5)",
                 "Fraction of events removed; precision and recall of the detected pixels "
                 "against the pixels the simulated rain and fog made noisy (– in clear weather: "
                 "none planted).",
                 ("sequence/camera", "events", "hot pixels", "noisy pixels (truth)",
                  "removed [%]", "precision", "recall"), tuple(rows))


def _vio_table(res: BenchmarkResult) -> Table:
    rows: list[tuple[str, ...]] = []
    ev = {r.sequence: r for r in res.steps.evaluation}
    for r in res.steps.vio:
        if not r.ok:
            rows.append((r.key, _failed(r), "", "", "", ""))
            continue
        s = r.value.stats if r.value is not None else {}
        n_poses = r.value.n_poses if r.value is not None else None
        e = ev.get(r.key)
        sc = e.value if e is not None and e.ok else None
        ate = (None, None, None) if sc is None else (sc.ate_rmse_m, sc.rpe_m, sc.rpe_deg)
        rows.append((r.key, f"{s.get('frames_estimated', n_poses)}/{s.get('frames')}",
                     str(len(s.get("failures") or [])), *(_f(x) for x in ate)))
    for sk in res.skipped:
        if sk["step"] == "vio":
            rows.append((sk["sequence"], f"not applicable: {sk['reason']}", "", "", "", ""))
    return Table("vio", "VIO baseline on the SLAM sequences",
                 "table:evaluation: ATE RMSE [m] after 4-DoF (position + yaw) alignment, RPE over "
                 "1 s (mean).",
                 ("sequence", "frames estimated", "failure spans", "ATE [m]", "RPE [m]",
                  "RPE [deg]"), tuple(rows))


def _timing_table(res: BenchmarkResult) -> Table:
    recs = dict(res.steps.items())
    rows = tuple((k, _f(v, ".1f"), str(len(recs.get(k, ()))),
                  str(sum(not r.ok for r in recs.get(k, ())))) for k, v in res.wall_s.items())
    return Table("timing", "Wall time per step", "Seconds of wall clock for each step's batch.",
                 ("step", "wall [s]", "jobs", "failed"), rows)


def benchmark_tables(res: BenchmarkResult) -> list[Table]:
    """The report's tables, in the paper's order."""
    return [*_camera_tables(res), _imu_camera_table(res), _imu_noise_table(res),
            _hot_pixels_table(res), _vio_table(res), _timing_table(res)]


def _meta(res: BenchmarkResult) -> str:
    return (f"suite {res.suite} at scale {res.scale:g}; {res.n_jobs} jobs, {res.n_failed} failed; "
            f"total wall time {sum(res.wall_s.values()):.1f} s")


def benchmark_markdown(res: BenchmarkResult) -> str:
    """The report as Markdown."""
    parts = ["# IBISCape benchmark on generated data", "", _meta(res), ""]
    parts += [t.to_markdown() for t in benchmark_tables(res)]
    if res.evaluation:
        parts += ["## VIO in the paper's table layout", "",
                  res.evaluation["markdown"]]
    fails = res.failed()
    if fails:
        parts += ["## Failed jobs", ""] + [f"- {f['step']} {f['key']}: {f['error']}" for f in fails]
    return "\n".join(parts) + "\n"


def benchmark_html(res: BenchmarkResult) -> str:
    """The report as one self-contained HTML page (figures embedded as PNG data)."""
    import base64

    e = html.escape
    parts = ["<!DOCTYPE html>", '<html lang="en">', "<head>", '<meta charset="utf-8">',
             "<title>IBISCape benchmark</title>", f"<style>{_CSS}{_EXTRA_CSS}</style>", "</head>", "<body>",
             "<h1>IBISCape benchmark on generated data</h1>", f'<p class="meta">{e(_meta(res))}</p>']
    parts += [t.to_html() for t in benchmark_tables(res)]
    if res.evaluation:
        parts += ["<h2>VIO in the paper's table layout</h2>",
                  res.evaluation["html"]]
    if res.figures:
        parts.append("<h2>VIO figures</h2>")
    for _, caption, png in res.figures:
        data = base64.b64encode(png).decode("ascii")
        parts.append(f'<figure><img src="data:image/png;base64,{data}" alt="{e(caption)}">'
                     f"<figcaption>{e(caption)}</figcaption></figure>")
    fails = res.failed()
    if fails:
        parts += ["<h2>Failed jobs</h2>", '<div class="table-scroll"><table class="failed">'
                  "<thead><tr><th>step</th><th>job</th><th>error</th></tr></thead><tbody>"]
        parts += [f"<tr><td>{e(f['step'])}</td><td>{e(f['key'])}</td><td>{e(str(f['error']))}"
                  "</td></tr>" for f in fails]
        parts.append("</tbody></table></div>")
    parts += ["</body>", "</html>"]
    return "\n".join(parts) + "\n"


def write_benchmark_report(out_dir: str | os.PathLike[str], res: BenchmarkResult) -> list[Path]:
    """Write ``report.html``, ``report.md``, ``report.json`` (and ``table_vio.tex``, the VIO
    figures as ``figures/<name>.png``) into ``out_dir`` (created; earlier files of the same names
    are replaced atomically)."""
    from ibiscape_eval.batch.files import atomic_write

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    docs = {"report.md": benchmark_markdown(res), "report.html": benchmark_html(res),
            "report.json": json.dumps(res.to_dict(), indent=1, allow_nan=False) + "\n"}
    if res.evaluation:
        docs["table_vio.tex"] = res.evaluation["latex"]
    written = []
    for name, text in docs.items():
        with atomic_write(out / name) as f:
            f.write(text)
        written.append(out / name)
    if res.figures:
        (out / "figures").mkdir(exist_ok=True)
    for fname, _, png in res.figures:
        with atomic_write(out / "figures" / fname, "wb") as fb:
            fb.write(png)
        written.append(out / "figures" / fname)
    return written
