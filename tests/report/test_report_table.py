"""``report`` on a tiny runs folder whose numbers are known by hand (see _report_runs)."""

from __future__ import annotations

import csv
import io
import json
import math
import re
import shutil
import subprocess

import pytest
from _report_runs import GAMMA_RPE_M, SQRT35, build_runs
from click.testing import CliRunner

from ibiscape_eval.batch import LocalExecutor
from ibiscape_eval.cli.main import cli
from ibiscape_eval.report.evaluate import EvaluationOptions, evaluate_runs
from ibiscape_eval.report.paper_table import PaperTable
from ibiscape_eval.report.runs import discover_runs


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    return build_runs(tmp_path_factory.mktemp("report"))


@pytest.fixture(scope="module")
def evaluation(folders):
    runs, seqs = folders
    layout = discover_runs(runs, sequences_dir=seqs)
    return evaluate_runs(layout, EvaluationOptions(align="none"), executor=LocalExecutor(1))


def test_per_run_values_match_hand_computation(evaluation) -> None:
    by = {(r["sequence"], r["algorithm"], r["trial"]): r for r in evaluation.runs}
    assert len(by) == 8
    a = by["seq1", "alpha", "t1"]
    assert a["status"] == "ok" and a["n_matched"] == 11
    assert a["ate"]["translation_m"]["rmse"] == pytest.approx(0.1, abs=1e-12)
    assert a["rpe"]["translation_m"]["mean"] == pytest.approx(0.0, abs=1e-12)
    for k, s in enumerate((1.1, 1.2, 1.3), start=1):
        b = by["seq1", "beta", f"t{k}"]
        assert b["ate"]["translation_m"]["rmse"] == pytest.approx((s - 1) * SQRT35, rel=1e-12)
        assert b["rpe"]["translation_m"]["mean"] == pytest.approx(s - 1, rel=1e-12)
        assert b["rpe"]["translation_m"]["std"] == pytest.approx(0.0, abs=1e-12)
    bad = by["seq1", "beta", "t4"]
    assert bad["status"] == "failed" and bad["ate"] is None
    assert re.search(r"t4/est\.txt:3.*not a number", bad["error"])
    g = by["seq1", "gamma", "t1"]
    assert g["ate"]["translation_m"]["rmse"] == pytest.approx(0.0, abs=1e-12)
    assert g["ate"]["rotation_deg"]["mean"] == pytest.approx(5.0, rel=1e-9)
    assert g["rpe"]["translation_m"]["mean"] == pytest.approx(GAMMA_RPE_M, rel=1e-9)
    assert g["rpe"]["rotation_deg"]["mean"] == pytest.approx(0.0, abs=1e-9)
    assert by["seq2", "alpha", "t1"]["ate"]["translation_m"]["rmse"] == pytest.approx(0.2)
    assert by["seq2", "beta", "t1"]["ate"]["translation_m"]["rmse"] == pytest.approx(0, abs=1e-9)
    # the per-run statistics are exactly the ate command's JSON
    assert set(a["ate"]) >= {"metric", "n_matched", "alignment", "translation_m", "rotation_deg"}
    assert a["ate"]["alignment"] == "none" and a["rpe"]["metric"] == "rpe"


def test_table_cells_median_success_and_bold(evaluation) -> None:
    t = PaperTable.from_runs(evaluation.runs)
    assert t.sequences == ("seq1", "seq2") and t.algorithms == ("alpha", "beta", "gamma")
    beta = t.cell("seq1", "beta")
    assert beta is not None
    assert (beta.n_ok, beta.n_trials, beta.success_rate) == (3, 4, 0.75)
    assert beta.ate_m == pytest.approx(0.2 * SQRT35, rel=1e-12)  # median of the 3 trials
    assert beta.rpe_m_mean == pytest.approx(0.2, rel=1e-12)
    assert t.cell("seq2", "gamma") is None
    assert t.is_best("seq1", "gamma", "ate_m") and not t.is_best("seq1", "alpha", "ate_m")
    assert t.is_best("seq1", "alpha", "rpe_m") and not t.is_best("seq1", "gamma", "rpe_m")
    assert all(t.is_best("seq1", a, "rpe_deg") for a in t.algorithms)  # a three-way tie
    assert t.is_best("seq2", "beta", "ate_m") and not t.is_best("seq2", "alpha", "ate_m")

    md = t.to_markdown().splitlines()
    assert md[0].startswith("| Sequence | alpha ATE [m] | alpha RPE [m] |")
    row1 = [c.strip() for c in md[2].strip("|").split("|")]
    assert row1[:5] == ["seq1", "0.1000", "**0.0000 ± 0.0000**", "**0.0000 ± 0.0000**", "1/1"]
    assert row1[5:9] == [f"{0.2 * SQRT35:.4f}", "0.2000 ± 0.0000", "**0.0000 ± 0.0000**", "3/4"]
    assert row1[9:11] == ["**0.0000**", f"{GAMMA_RPE_M:.4f} ± 0.0000"]
    row2 = [c.strip() for c in md[3].strip("|").split("|")]
    # gamma has no run on seq2: marked "--" (no estimate), explained in the caption below
    assert row2[1] == "0.2000" and row2[5] == "**0.0000**" and row2[9:] == ["--"] * 4
    assert md[-1].startswith("ATE [m]: RMSE") and "--: no estimate" in md[-1]

    rows = list(csv.DictReader(io.StringIO(t.to_csv())))
    assert len(rows) == 5
    b = next(r for r in rows if (r["sequence"], r["algorithm"]) == ("seq1", "beta"))
    assert float(b["ate_rmse_m"]) == pytest.approx(0.2 * SQRT35, rel=1e-12)
    assert (b["n_trials"], b["n_ok"], float(b["success_rate"])) == ("4", "3", 0.75)
    assert float(b["drift_translation_pct"]) == pytest.approx(20.0, rel=1e-9)  # 0.2 m per m
    assert (b["best_ate_m"], b["best_rpe_m"], b["best_rpe_deg"]) == ("0", "0", "1")


def _check_latex_structure(tex: str) -> None:
    """Balanced braces, one environment closed per one opened, every row as wide as the header."""
    depth = 0
    for ch in re.sub(r"\\[{}]", "", tex):
        depth += (ch == "{") - (ch == "}")
        assert depth >= 0
    assert depth == 0
    begins = re.findall(r"\\begin\{(\w+)\}", tex)
    ends = re.findall(r"\\end\{(\w+)\}", tex)
    assert begins == ends[::-1]
    spec = re.search(r"\\begin\{tabular\}\{([^}]*)\}", tex)
    assert spec is not None
    ncols = len(re.sub(r"[^lcr]", "", spec.group(1)))
    body = tex[spec.end(): tex.index(r"\end{tabular}")]
    for row in body.split(r"\\")[:-1]:
        row = row.replace(r"\hline", "").strip()
        cells = re.split(r"(?<!\\)&", row)
        width = sum(int(m.group(1)) if (m := re.match(r"\s*\\multicolumn\{(\d+)\}", c)) else 1
                    for c in cells)
        assert width == ncols, row


def _odd_table(evaluation) -> PaperTable:
    """The fixture's table with LaTeX specials in an algorithm name."""
    return PaperTable.from_runs([{**r, "algorithm": "orb_slam3 & 50%"} if r["algorithm"] == "beta"
                                 else r for r in evaluation.runs])


def test_latex_parses(evaluation) -> None:
    tex = PaperTable.from_runs(evaluation.runs).to_latex()
    _check_latex_structure(tex)
    assert r"\textbf{0.0000}" in tex and r"0.2000$\pm$0.0000" in tex and "3/4" in tex
    assert r"\label{table:ate-rpe}" in tex  # from the content; the report's file splits it
    for part in PaperTable.from_runs(evaluation.runs).to_latex_tables().split("\n\n"):
        _check_latex_structure(part)
    odd = _odd_table(evaluation).to_latex()
    assert r"orb\_slam3 \& 50\%" in odd
    _check_latex_structure(odd)
    with pytest.raises(AssertionError):  # the structural check does catch a broken row
        _check_latex_structure(tex.replace(r"\texttt{seq1} &", r"\texttt{seq1} & & ", 1))


def test_latex_compiles(evaluation, tmp_path) -> None:
    engine = shutil.which("pdflatex") or shutil.which("latex")
    if engine is None:
        pytest.skip("no TeX engine (Debian: apt-get install texlive-latex-base); "
                    "test_latex_parses checks the structure")
    doc = tmp_path / "t.tex"
    doc.write_text("\\documentclass{article}\n\\begin{document}\n"
                   + _odd_table(evaluation).to_latex() + _odd_table(evaluation).to_latex_tables()
                   + "\\end{document}\n")
    res = subprocess.run([engine, "-interaction=nonstopmode", "-halt-on-error", doc.name],
                         cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stdout[-2000:]


def test_cli_json_and_out_folder(folders, tmp_path) -> None:
    runs, seqs = folders
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["report", str(runs), "--sequences", str(seqs), "--align",
                                   "none", "--json", "--no-cache", "--workers", "1",
                                   "--out", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert [(r["sequence"], r["algorithm"], r["trial"], r["status"]) for r in doc["runs"]][:5] == [
        ("seq1", "alpha", "t1", "ok"), ("seq1", "beta", "t1", "ok"), ("seq1", "beta", "t2", "ok"),
        ("seq1", "beta", "t3", "ok"), ("seq1", "beta", "t4", "failed")]
    r0 = doc["runs"][0]
    assert {"sequence", "algorithm", "trial", "status", "n_matched", "ate", "rpe"} <= set(r0)
    assert r0["ate"]["translation_m"]["rmse"] == pytest.approx(0.1)
    assert doc["summary"]["n_failed"] == 1 and doc["summary"]["n_ok"] == 7
    assert "failed" in res.stderr and "seq1/beta/t4" in res.stderr
    names = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    assert names == ["figures/errors_boxplot.png", "figures/trajectories_seq1.png",
                     "figures/trajectories_seq2.png", "report.html", "report.json", "runs.csv",
                     "table.csv", "table.md", "table.tex"]
    assert json.loads((out / "report.json").read_text())["runs"] == doc["runs"]
    page = (out / "report.html").read_text()
    assert page.count("data:image/png;base64,") == 3 and "<strong>0.0000</strong>" in page
    assert "seq1/beta/t4" in page  # failed runs are listed with their error
    runs_rows = list(csv.DictReader(io.StringIO((out / "runs.csv").read_text())))
    assert len(runs_rows) == 8 and runs_rows[4]["status"] == "failed"
    assert math.isclose(float(runs_rows[1]["ate_rmse_m"]), 0.1 * SQRT35, rel_tol=1e-12)
    # an earlier report is replaced; a foreign non-empty folder is refused
    res2 = CliRunner().invoke(cli, ["report", str(runs), "--sequences", str(seqs), "--no-cache",
                                    "--workers", "1", "--out", str(out), "--no-figures"])
    assert res2.exit_code == 0 and not (out / "figures").exists()
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("x")
    res3 = CliRunner().invoke(cli, ["report", str(runs), "--sequences", str(seqs), "--no-cache",
                                    "--workers", "1", "--out", str(foreign)])
    assert res3.exit_code == 2 and "holds no earlier report" in res3.stderr
    assert sorted(p.name for p in foreign.iterdir()) == ["thesis.tex"]


def test_cli_rerun_uses_the_cache(folders, tmp_path) -> None:
    runs, seqs = folders
    args = ["report", str(runs), "--sequences", str(seqs), "--cache", str(tmp_path / "c"),
            "--workers", "1", "--json", "--align", "none"]
    first = CliRunner().invoke(cli, args)
    second = CliRunner().invoke(cli, args)
    assert first.exit_code == second.exit_code == 0
    assert "(0 from the cache)" in first.stderr and "(7 from the cache)" in second.stderr
    d1, d2 = json.loads(first.stdout), json.loads(second.stdout)
    assert d1["runs"] == d2["runs"] and d1["table"] == d2["table"]
