"""The suite of the paper's sequence table (``sim suite``): entries, scaling, jobs, manifest."""

from __future__ import annotations

import json
import math
import re
from collections import Counter
from dataclasses import replace

import pytest
from hypothesis import given
from hypothesis import strategies as st
from shared_data import PAPER, require_path

from ibiscape_eval.batch import LocalExecutor, run_jobs
from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.sim.suite import (
    FULL_DURATION_S,
    MIN_DURATION_S,
    SuiteEntry,
    generate_entry,
    read_manifest,
    run_suite,
    scaled_duration_s,
    scaled_side_px,
    suite_entries,
    suite_jobs,
)

# table:ibiscape_sequences, typed from the paper: (setup, kind) -> clear, moderate, dynamic
EXPECTED = {("imu", "calibration"): (1, 0, 0), ("svi", "calibration"): (2, 0, 0),
            ("esvi", "calibration"): (2, 0, 0), ("rgbd", "calibration"): (2, 0, 0),
            ("full", "calibration"): (2, 0, 0), ("svi", "slam"): (2, 2, 3),
            ("esvi", "slam"): (2, 2, 2), ("rgbd", "slam"): (2, 2, 2), ("full", "slam"): (2, 2, 2)}


def _counts(entries):
    c = Counter((e.setup, e.kind, e.weather) for e in entries)
    return {k: tuple(c[(*k, w)] for w in ("clear", "moderate", "dynamic")) for k in EXPECTED}


def test_full_scale_suite_is_the_papers_table() -> None:
    es = suite_entries(1.0)
    assert len(es) == 34
    assert _counts(es) == EXPECTED
    w = Counter(e.weather for e in es)
    assert (w["clear"], w["moderate"], w["dynamic"]) == (17, 8, 9)  # the table's "Total" row
    names = [e.name for e in es]
    assert len(set(names)) == 34
    assert {"IMU_calib_1", "SVI_calib_1", "ESVI_slam_dyn_2", "FULL_slam_mod_1",
            "SVI_slam_dyn_3", "RGBD_slam_clear_2"} <= set(names)
    for e in es:
        assert re.fullmatch(r"(IMU|SVI|ESVI|RGBD|FULL)_(calib|slam_(clear|mod|dyn))_\d", e.name)
        cfg = e.config()
        assert (cfg.setup, cfg.kind, cfg.weather) == (e.setup, e.kind, e.weather)
        assert cfg.duration_s == (604_800.0 if e.setup == "imu" else 60.0)
        assert all(c.width_px == c.height_px == 1024 for c in cfg.cameras)
    # half of the calibration drives toward each target, and every seed differs
    targets = Counter(e.target for e in es if e.kind == "calibration" and e.setup != "imu")
    assert targets == {"checkerboard": 4, "aprilgrid": 4}
    assert len({e.seed for e in es}) == 34
    assert next(e for e in es if e.setup == "imu").still_format == "npy"


def test_counts_match_the_paper_source_when_present() -> None:
    tex = require_path(PAPER).read_text(encoding="utf-8")  # fails under CI when missing
    body = tex[tex.index(r"\label{table:ibiscape_sequences}"):]
    body = body[:body.index(r"\end{tabular}")]
    rows = re.findall(r"\{([^{}]*?)\}\s*&\s*\{([\d-])\}\s*&\s*\{([\d-])\}\s*&\s*\{([\d-])\}", body)
    label = {"IMU": "imu", "2xRGB+IMU (SVI)": "svi", "2xDVS+2xIMU (ESVI)": "esvi",
             "RGB-D": "rgbd", "Full Sensor Setup": "full"}
    parsed: dict[tuple[str, str], tuple[int, ...]] = {}
    for i, (name, *vals) in enumerate(rows):
        kind = "calibration" if i < 5 else "slam"
        parsed[(label[name.strip()], kind)] = tuple(0 if v == "-" else int(v) for v in vals)
    assert parsed == _counts(suite_entries(1.0))


@pytest.mark.parametrize("scale", [1.0, 0.5, 0.25, 0.05, 0.01, 1e-6])
def test_scaling_rules(scale) -> None:
    side = scaled_side_px(scale)
    assert 128 <= side <= 1024 and side % 16 == 0
    assert side == min(1024, max(128, 16 * round(1024 * math.sqrt(scale) / 16)))
    calib_side = scaled_side_px(scale, "calibration")
    assert calib_side == max(320, side)
    for kind in ("calibration", "slam", "imu"):
        d = scaled_duration_s(kind, scale)
        assert d == max(MIN_DURATION_S[kind], round(scale * FULL_DURATION_S[kind], 3))
    for e in suite_entries(scale):
        cfg = e.config()
        want = side if e.kind != "calibration" else (
            max(512, side) if e.target == "aprilgrid" else calib_side)
        assert all((c.width_px, c.height_px) == (want, want) for c in cfg.cameras)
        if e.kind == "calibration" and e.setup != "imu":
            assert cfg.motion.calibration_drive == "shuttle" and cfg.duration_s >= 12.0


def test_known_scaled_values() -> None:
    assert scaled_side_px(0.25) == 512 and scaled_side_px(0.05) == 224
    assert scaled_duration_s("slam", 0.25) == 15.0 and scaled_duration_s("slam", 0.01) == 3.0
    assert scaled_duration_s("imu", 0.05) == 30_240.0 and scaled_duration_s("imu", 1e-4) == 1800.0
    e = {x.name: x for x in suite_entries(0.05)}
    assert e["SVI_calib_1"].side_px == 320 and e["SVI_calib_1"].duration_s == 12.0
    assert e["SVI_calib_2"].side_px == 512 and e["SVI_calib_2"].target == "aprilgrid"
    assert e["SVI_slam_clear_1"].side_px == 224 and e["SVI_slam_clear_1"].duration_s == 3.0
    assert e["IMU_calib_1"].still_format == "npy"
    assert suite_entries(0.005)[0].still_format == "csv"  # 1800 s: the IBISCape csv


@pytest.mark.parametrize("bad", [0.0, -0.1, 1.5, math.nan, math.inf, True, "0.5"])
def test_bad_scale_is_refused(bad) -> None:
    with pytest.raises(IbiscapeError, match="scale must be a number in"):
        suite_entries(bad)


@given(st.sampled_from(suite_entries(0.05)), st.integers(0, 10_000))
def test_entry_dict_round_trip(entry, seed) -> None:
    e = replace(entry, seed=seed)
    assert SuiteEntry.from_dict(json.loads(json.dumps(e.to_dict()))) == e


def test_entry_dict_with_unknown_keys_is_refused() -> None:
    d = suite_entries(0.05)[0].to_dict()
    with pytest.raises(IbiscapeError, match="expected keys"):
        SuiteEntry.from_dict({**d, "colour": "red"})


def _tiny(name: str = "SVI_slam_clear_1") -> SuiteEntry:
    e = next(x for x in suite_entries(0.01) if x.name == name)
    return replace(e, duration_s=1.0)


def test_generate_entry_writes_once_and_reuses(tmp_path) -> None:
    e = _tiny()
    out = tmp_path / e.name
    first = generate_entry(e.to_dict(), str(out), render=False)
    assert first["reused"] is False and (out / "sequence.yaml").is_file()
    assert first["summary"]["duration_s"] == pytest.approx(1.0)
    stamp = (out / "sequence.yaml").stat().st_mtime_ns
    again = generate_entry(e.to_dict(), str(out), render=False)
    assert again["reused"] is True and again["summary"] == first["summary"]
    assert (out / "sequence.yaml").stat().st_mtime_ns == stamp
    # another entry (seed) in the same folder: generated again
    other = generate_entry(replace(e, seed=e.seed + 1).to_dict(), str(out), render=False)
    assert other["reused"] is False


def test_suite_jobs_run_locally_and_record_failures(tmp_path) -> None:
    good = _tiny()
    bad = replace(_tiny("RGBD_slam_clear_1"), duration_s=-1.0)  # the config refuses it
    jobs = suite_jobs([good, bad], tmp_path, render=False)
    assert [j.key for j in jobs] == [good.name, bad.name]
    res, summary = run_jobs(jobs, LocalExecutor(1))
    assert res[good.name].ok and not res[bad.name].ok
    assert "duration_s" in (res[bad.name].error or "")
    assert summary.n_failed == 1 and (tmp_path / good.name / "sequence.yaml").is_file()
    assert not (tmp_path / bad.name).exists()


def test_run_suite_only_writes_the_manifest(tmp_path) -> None:
    res = run_suite(tmp_path / "s", scale=1e-6, render=False, executor=LocalExecutor(1),
                    only=["RGBD_slam_clear_1"])
    assert [s["name"] for s in res.sequences] == ["RGBD_slam_clear_1"]
    assert res.summary["n_ok"] == 1 and not res.failed
    doc, entries = read_manifest(tmp_path / "s")
    assert doc["scale"] == 1e-6 and [e.name for e in entries] == ["RGBD_slam_clear_1"]
    assert doc["sequences"][0]["config"]["cameras"]["rgb"]["width_px"] == 128
    with pytest.raises(IbiscapeError, match="unknown suite sequence"):
        run_suite(tmp_path / "s", scale=1e-6, render=False, only=["SVI_calib_9"])


def test_read_manifest_errors(tmp_path) -> None:
    with pytest.raises(IbiscapeError, match=r"suite\.json: not found"):
        read_manifest(tmp_path)
    (tmp_path / "suite.json").write_text('{"sequences": [{"name": 1}]}')
    with pytest.raises(IbiscapeError, match="not a suite manifest"):
        read_manifest(tmp_path)
