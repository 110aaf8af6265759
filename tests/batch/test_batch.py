"""The job model, the local executor and the content cache."""

from __future__ import annotations

import itertools
import json
import math
import os
import time

import _batch_jobs as jobs_mod
import pytest

from ibiscape_eval.batch import (
    ContentCache,
    DaskExecutor,
    Job,
    LocalExecutor,
    canonical_json,
    run_job,
    run_jobs,
)
from ibiscape_eval.core.errors import IbiscapeError


def sq(i: float) -> Job:
    return Job(f"sq{i}", jobs_mod.square, {"x": i})


def test_job_validation() -> None:
    with pytest.raises(IbiscapeError, match="not a module-level function"):
        Job("a", lambda: {}, {})

    def local(**_: object) -> dict[str, object]:
        return {}

    with pytest.raises(IbiscapeError, match="not a module-level function"):
        Job("a", local, {})
    with pytest.raises(IbiscapeError, match="NaN"):
        Job("a", jobs_mod.square, {"x": math.nan})
    with pytest.raises(IbiscapeError, match="not JSON-compatible"):
        Job("a", jobs_mod.square, {"x": object()})
    with pytest.raises(IbiscapeError, match="non-empty key"):
        Job("", jobs_mod.square, {})
    assert json.loads(json.dumps(sq(2).to_dict()))["params"] == {"x": 2}


def test_run_job_ok_and_failures() -> None:
    assert run_job(sq(3)).value == {"x": 3, "y": 9}
    r = run_job(Job("b", jobs_mod.boom, {"x": 1}))
    assert (r.status, r.error) == ("failed", "ValueError: no square for 1")
    r = run_job(Job("c", jobs_mod.not_a_dict, {"x": 1}))
    assert r.status == "failed" and "expected a dict" in (r.error or "")
    r = run_job(Job("n", jobs_mod.nan_result, {"x": 1}))
    assert r.status == "failed" and "not strict JSON" in (r.error or "")
    assert sq(2).to_dict()["func"] == "_batch_jobs:square"


def test_canonical_json_is_order_independent() -> None:
    assert canonical_json({"b": 1, "a": [0.1, None]}) == canonical_json({"a": [0.1, None], "b": 1})
    with pytest.raises(ValueError):
        canonical_json({"a": math.inf})


def test_local_pool_runs_all_and_isolates_failures() -> None:
    jobs = [sq(i) for i in range(6)]
    jobs.insert(2, Job("bad", jobs_mod.boom, {"x": 7}))
    seen: list[tuple[int, int, int]] = []
    results, summary = run_jobs(jobs, LocalExecutor(2),
                                progress=lambda d, f, r: seen.append((d, f, r)))
    assert list(results) == [j.key for j in jobs]  # job order, whatever the completion order
    assert [results[f"sq{i}"].value["y"] for i in range(6)] == [i * i for i in range(6)]
    assert results["bad"].error == "ValueError: no square for 7"
    assert (summary.n_jobs, summary.n_ok, summary.n_failed) == (7, 6, 1)
    assert seen[0] == (0, 0, 7) and seen[-1] == (7, 1, 0)
    assert all(a[0] <= b[0] for a, b in itertools.pairwise(seen))


def test_a_crashing_worker_fails_its_job_only() -> None:
    jobs = [sq(i) for i in range(40)]
    jobs.insert(17, Job("die", jobs_mod.die, {"x": 0}))
    results, summary = run_jobs(jobs, LocalExecutor(2))
    assert results["die"].status == "failed" and "WorkerDied" in (results["die"].error or "")
    assert list(results) == [j.key for j in jobs]
    # the jobs that shared the broken pool ran again: none is lost or failed
    assert (summary.n_ok, summary.n_failed) == (40, 1)
    assert all(r.value["y"] == r.value["x"] ** 2 for k, r in results.items() if k != "die")


def test_single_worker_runs_in_process() -> None:
    results, _ = run_jobs([sq(1), sq(2)], LocalExecutor(1))
    assert [r.value["y"] for r in results.values()] == [1, 4]
    with pytest.raises(IbiscapeError, match="at least 1"):
        LocalExecutor(0)
    with pytest.raises(IbiscapeError, match="duplicate job keys: sq1"):
        run_jobs([sq(1), sq(1)], LocalExecutor(1))


def test_cache_skips_finished_jobs_and_invalidates_by_content(tmp_path) -> None:
    log = tmp_path / "log.txt"
    files = []
    for i in range(3):
        f = tmp_path / f"in{i}.txt"
        f.write_text("x" * (i + 1))
        files.append(f)

    def jobs(extra: int = 0) -> list[Job]:
        return [Job(f"f{i}", jobs_mod.file_size, {"path": str(f), "log": str(log), "extra": extra}
                    if extra else {"path": str(f), "log": str(log)}, inputs=(str(f),))
                for i, f in enumerate(files)]

    def ran() -> list[str]:
        out = log.read_text().splitlines() if log.exists() else []
        log.unlink(missing_ok=True)
        return out

    cache = ContentCache(tmp_path / "cache")
    first, s1 = run_jobs(jobs(), LocalExecutor(1), cache=cache)
    assert len(ran()) == 3 and s1.n_cached == 0
    again, s2 = run_jobs(jobs(), LocalExecutor(1), cache=ContentCache(tmp_path / "cache"))
    assert ran() == [] and s2.n_cached == 3
    assert {k: r.value for k, r in again.items()} == {k: r.value for k, r in first.items()}
    # new bytes in one input: only that job runs again
    files[1].write_text("changed")
    _, s3 = run_jobs(jobs(), LocalExecutor(1), cache=ContentCache(tmp_path / "cache"))
    assert ran() == [str(files[1])] and s3.n_cached == 2
    # new parameters: every job runs
    run_jobs(jobs(extra=1), LocalExecutor(1), cache=ContentCache(tmp_path / "cache"))
    assert len(ran()) == 3
    # entries are plain JSON; a damaged one is recomputed, not trusted
    entries = sorted((tmp_path / "cache").glob("??/*.json"))
    assert entries and all("job" in json.loads(e.read_text()) for e in entries)
    for e in entries:
        e.write_text("{not json")
    _, s4 = run_jobs(jobs(), LocalExecutor(1), cache=ContentCache(tmp_path / "cache"))
    assert len(ran()) == 3 and s4.n_cached == 0


def test_failed_jobs_are_not_cached(tmp_path) -> None:
    cache = ContentCache(tmp_path / "c")
    job = Job("b", jobs_mod.boom, {"x": 1})
    run_jobs([job], LocalExecutor(1), cache=cache)
    results, summary = run_jobs([job], LocalExecutor(1), cache=ContentCache(tmp_path / "c"))
    assert summary.n_cached == 0 and results["b"].status == "failed"


def test_same_bytes_elsewhere_hit_the_cache(tmp_path) -> None:
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    a.write_text("same")
    b.write_text("same")
    c = ContentCache(tmp_path / "c")
    ja = Job("k", jobs_mod.square, {"x": 2}, inputs=(str(a),))
    jb = Job("k", jobs_mod.square, {"x": 2}, inputs=(str(b),))
    assert c.key(ja) == c.key(jb)
    b.write_text("diff")
    assert c.key(ja) != c.key(jb)


def test_mtime_index_detects_changed_files(tmp_path) -> None:
    f = tmp_path / "a.txt"
    f.write_text("one")
    c = ContentCache(tmp_path / "c")
    os.utime(f, ns=(1_000_000_000, 1_000_000_000))
    h1 = c.file_hash(f)
    f.write_text("two")  # same size
    os.utime(f, ns=(1_000_000_000, 1_000_000_000))
    assert c.file_hash(f) == h1  # same size and mtime: the index's hash, not re-read
    os.utime(f, ns=(2_000_000_000, 2_000_000_000))
    assert c.file_hash(f) != h1


def test_unreachable_scheduler_fails_fast_naming_the_address() -> None:
    t0 = time.perf_counter()
    with pytest.raises(IbiscapeError, match=r"tcp://127\.0\.0\.1:9"):
        DaskExecutor("tcp://127.0.0.1:9", timeout_s=1.0)
    assert time.perf_counter() - t0 < 30  # not a speed assertion: it must not hang


def test_code_version_follows_the_source(tmp_path, monkeypatch) -> None:
    from ibiscape_eval.batch import code_version

    pkg = tmp_path / "mypkg_cv"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "helper.py").write_text("K = 1\n")
    (pkg / "jobs.py").write_text("def f(**_):\n    return {}\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    from mypkg_cv.jobs import f  # type: ignore[import-not-found]

    v1 = code_version(f)
    assert v1 == code_version(f)
    (pkg / "helper.py").write_text("K = 2\n")  # a module the job may call, not the job's own
    assert code_version(f) != v1
