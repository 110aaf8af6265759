"""The same report on a real Dask LocalCluster (loopback, 2 worker processes) and locally."""

from __future__ import annotations

import json

from _report_runs import build_runs
from click.testing import CliRunner

from ibiscape_eval.cli.main import cli


def test_dask_and_local_runs_give_identical_tables(scheduler, tmp_path) -> None:
    assert scheduler.startswith("tcp://127.0.0.1:")
    runs, seqs = build_runs(tmp_path)
    base = ["report", str(runs), "--sequences", str(seqs), "--align", "none", "--no-cache",
            "--json", "--no-figures"]
    local = CliRunner().invoke(cli, [*base, "--workers", "2", "--out", str(tmp_path / "local")])
    dask = CliRunner().invoke(cli, [*base, "--scheduler", scheduler, "--out",
                                    str(tmp_path / "dask")])
    assert local.exit_code == 0, local.output
    assert dask.exit_code == 0, dask.output
    assert f"on the Dask scheduler {scheduler}" in dask.stderr
    d_local, d_dask = json.loads(local.stdout), json.loads(dask.stdout)
    assert d_local["runs"] == d_dask["runs"]  # every number, bit for bit (JSON floats round-trip)
    assert d_local["table"] == d_dask["table"]
    failed = [r for r in d_dask["runs"] if r["status"] == "failed"]
    assert [(r["trial"], r["error"].split(":")[0]) for r in failed] == [("t4", "FormatError")]
    for name in ("table.md", "table.tex", "table.csv", "runs.csv"):
        assert (tmp_path / "local" / name).read_bytes() == (tmp_path / "dask" / name).read_bytes()
