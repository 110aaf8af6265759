"""Runs-folder discovery and the bad inputs the report command must explain."""

from __future__ import annotations

import pytest
from _report_runs import build_runs
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli
from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.report.runs import discover_runs


def _one_error_line(res) -> str:
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and "Traceback" not in res.output
    return lines[0]


def test_discovery_finds_runs_truths_and_gnss(tmp_path) -> None:
    runs, seqs = build_runs(tmp_path)
    layout = discover_runs(runs, sequences_dir=seqs)
    assert [r.key for r in layout.runs] == [
        "seq1/alpha/t1", "seq1/beta/t1", "seq1/beta/t2", "seq1/beta/t3", "seq1/beta/t4",
        "seq1/gamma/t1", "seq2/alpha/t1", "seq2/beta/t1"]
    assert layout.truths["seq1"].groundtruth == str(runs / "seq1" / "groundtruth.txt")
    assert layout.truths["seq1"].gnss is None
    assert layout.truths["seq2"].groundtruth.endswith("seq2/vehicle_gt/groundtruth_sync.csv")
    assert layout.truths["seq2"].gnss.endswith("seq2/other_sensors/gnss.csv")
    assert layout.ignored == ()


def test_natural_trial_order_and_kitti_times(tmp_path) -> None:
    runs, seqs = build_runs(tmp_path, with_failure=False)
    for n in (10, 2):
        d = runs / "seq1" / "alpha" / f"trial_{n}"
        d.mkdir()
        (d / "poses.txt").write_text("1 0 0 0 0 1 0 0 0 0 1 0\n")
        (d / "poses.times.txt").write_text("0.0\n")
    layout = discover_runs(runs, sequences_dir=seqs)
    alpha = [r for r in layout.runs if r.sequence == "seq1" and r.algorithm == "alpha"]
    assert [r.trial for r in alpha] == ["t1", "trial_2", "trial_10"]
    assert alpha[1].times_path == str(runs / "seq1" / "alpha" / "trial_2" / "poses.times.txt")


def test_paths_outside_the_layout_are_listed_with_reasons(tmp_path) -> None:
    runs, seqs = build_runs(tmp_path, with_failure=False)
    (runs / "README.txt").write_text("notes")
    (runs / "seq1" / "alpha" / "notes.txt").write_text("x")
    (runs / "seq1" / "beta" / "empty").mkdir()
    two = runs / "seq1" / "gamma" / "t2"
    two.mkdir()
    (two / "a.txt").write_text("x")
    (two / "b.txt").write_text("x")
    (runs / "seq1" / "summary.pdf").write_text("x")
    (runs / "empty_seq").mkdir()
    (runs / ".hidden").mkdir()
    (runs / "report" / "figures").mkdir(parents=True)  # an earlier --out inside the runs folder
    (runs / "report" / "report.json").write_text("{}")
    (runs / "report" / "figures" / "x.png").write_text("")
    layout = discover_runs(runs, sequences_dir=seqs)
    why = {p.removeprefix(str(runs) + "/"): r for p, r in layout.ignored}
    assert set(why) == {"README.txt", "seq1/alpha/notes.txt", "seq1/beta/empty", "seq1/gamma/t2",
                        "seq1/summary.pdf", "empty_seq", "report"}
    assert "expected <sequence>/ folders" in why["README.txt"]
    assert "expected <trial>/ folders" in why["seq1/alpha/notes.txt"]
    assert "without a trajectory file" in why["seq1/beta/empty"]
    assert "2 candidate trajectory files (a.txt, b.txt)" in why["seq1/gamma/t2"]
    assert "neither groundtruth.<ext> nor gnss.csv" in why["seq1/summary.pdf"]
    assert "without any" in why["empty_seq"]
    assert "report folder" in why["report"]
    assert len(layout.runs) == 7

    res = CliRunner().invoke(cli, ["report", str(runs), "--sequences", str(seqs), "--no-cache",
                                   "--workers", "1", "--align", "none"])
    assert res.exit_code == 0
    assert f"ignored {runs / 'README.txt'}: a file directly in the runs folder" in res.stderr
    assert res.stderr.count("ignored ") == 7


def test_sequences_without_ground_truth_are_an_error(tmp_path) -> None:
    runs, _seqs = build_runs(tmp_path)
    with pytest.raises(IbiscapeError, match=r"no ground truth for sequence seq2; expected .*"
                                            r"groundtruth\.<ext> \(or give sequences_dir"):
        discover_runs(runs)
    res = CliRunner().invoke(cli, ["report", str(runs), "--no-cache"])
    line = _one_error_line(res)
    assert "seq2" in line and "--sequences" in line and res.stdout == ""
    res = CliRunner().invoke(cli, ["report", str(runs), "--sequences", str(tmp_path / "nope")])
    assert "--sequences is not a folder" in _one_error_line(res)


def test_empty_or_missing_runs_folder(tmp_path) -> None:
    res = CliRunner().invoke(cli, ["report", str(tmp_path / "missing")])
    assert "not a folder" in _one_error_line(res)
    (tmp_path / "r" / "seqA" / "alg").mkdir(parents=True)
    (tmp_path / "r" / "seqA" / "alg" / "est.txt").write_text("x")
    res = CliRunner().invoke(cli, ["report", str(tmp_path / "r")])
    line = _one_error_line(res)
    assert "no runs found" in line and "a file in an algorithm folder" in line


def test_every_run_failing_is_an_error_without_output(tmp_path) -> None:
    runs, seqs = build_runs(tmp_path)
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["report", str(runs / ".." / "runs"), "--sequences", str(seqs),
                                   "--no-cache", "--workers", "1", "--out", str(out),
                                   "--rpe-delta", "500", "--align", "none"])
    assert "every run failed" in _one_error_line(res)
    assert not out.exists()


def test_unreachable_scheduler_is_one_line_with_the_address(tmp_path) -> None:
    runs, seqs = build_runs(tmp_path)
    res = CliRunner().invoke(cli, ["report", str(runs), "--sequences", str(seqs),
                                   "--scheduler", "tcp://127.0.0.1:9", "--no-cache"])
    line = _one_error_line(res)
    assert "tcp://127.0.0.1:9" in line and "Dask scheduler" in line
