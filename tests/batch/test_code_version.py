"""The cache's code version covers every module a job can reach, the simulator and CLI included."""

from __future__ import annotations

import shutil
from pathlib import Path

import _batch_jobs as jobs_mod
import tomllib

import ibiscape_eval.sim
from ibiscape_eval.batch import ContentCache, Job, LocalExecutor, code_version, run_jobs
from ibiscape_eval.batch.cache import code_files

ROOT = Path(__file__).resolve().parents[2]


def test_every_source_folder_of_the_project_is_hashed() -> None:
    doc = tomllib.loads((ROOT / "pyproject.toml").read_text())
    folders = set(doc["tool"]["setuptools"]["package-dir"].values())
    assert {"sim", "cli"} <= folders
    hashed = {p.resolve() for p in code_files(jobs_mod.square).values()}
    for folder in folders:
        mods = sorted((ROOT / folder).rglob("*.py"))
        assert mods, folder
        assert not [m for m in mods if m.resolve() not in hashed], folder
    assert Path(jobs_mod.__file__).resolve() in hashed  # the job's own module


def test_editing_a_simulator_module_misses_the_cache(tmp_path, monkeypatch) -> None:
    # a copy of the simulator package stands in for sim/, so the test edits no real file
    sim_copy = tmp_path / "sim"
    shutil.copytree(Path(ibiscape_eval.sim.__path__[0]), sim_copy,
                    ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(ibiscape_eval.sim, "__path__", [str(sim_copy)])
    assert any(p.is_relative_to(sim_copy) for p in code_files(jobs_mod.square).values())
    job = Job("sq", jobs_mod.square, {"x": 3})
    v1 = code_version(jobs_mod.square)

    def cached() -> int:
        return run_jobs([job], LocalExecutor(1), cache=ContentCache(tmp_path / "c"))[1].n_cached

    assert cached() == 0 and cached() == 1  # stored, then served
    with open(sim_copy / "noise.py", "a") as f:
        f.write("\n# an edit of the simulator\n")
    assert code_version(jobs_mod.square) != v1
    assert cached() == 0  # the simulator changed: computed again
