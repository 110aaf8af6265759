"""Property tests: the table's CSV round-trips its cells exactly, bold marks the row minimum, and
the job cache returns exactly what it stored."""

from __future__ import annotations

import csv
import io
import math
import statistics
import tempfile

from hypothesis import given
from hypothesis import strategies as st

from ibiscape_eval.batch import ContentCache, Job, JobResult
from ibiscape_eval.report.evaluate import box_stats
from ibiscape_eval.report.paper_table import DECIMALS, METRICS, PaperTable

finite = st.floats(min_value=0.0, max_value=1e4, allow_nan=False, allow_infinity=False)


@st.composite
def run_records(draw):
    seqs = draw(st.lists(st.sampled_from(["s1", "s2", "s3"]), min_size=1, max_size=3, unique=True))
    algs = draw(st.lists(st.sampled_from(["a", "b", "c"]), min_size=1, max_size=3, unique=True))
    runs = []
    for s in seqs:
        for a in algs:
            for k in range(draw(st.integers(1, 4))):
                ok = draw(st.booleans())
                rec = {"sequence": s, "algorithm": a, "trial": f"t{k}",
                       "status": "ok" if ok else "failed", "ate": None, "rpe": None,
                       "drift": None}
                if ok:
                    rec["ate"] = {"translation_m": {"rmse": draw(finite)}}
                    rec["rpe"] = {"translation_m": {"mean": draw(finite), "std": draw(finite)},
                                  "rotation_deg": {"mean": draw(finite), "std": draw(finite)}}
                runs.append(rec)
    return runs


@given(run_records())
def test_csv_round_trips_cells_and_bold_is_the_row_minimum(runs) -> None:
    t = PaperTable.from_runs(runs)
    rows = list(csv.DictReader(io.StringIO(t.to_csv())))
    assert len(rows) == len(t.cells)
    for r in rows:
        c = t.cells[(r["sequence"], r["algorithm"])]
        ok = [x for x in runs if (x["sequence"], x["algorithm"]) == (r["sequence"],
                                                                        r["algorithm"])
              and x["status"] == "ok"]
        assert (int(r["n_ok"]), int(r["n_trials"])) == (c.n_ok, c.n_trials) and c.n_ok == len(ok)
        want = statistics.median([x["ate"]["translation_m"]["rmse"] for x in ok]) if ok else None
        got = float(r["ate_rmse_m"]) if r["ate_rmse_m"] else None
        assert got == c.ate_m and (want is None) == (got is None)
        if want is not None and got is not None:
            assert math.isclose(got, want, rel_tol=1e-12, abs_tol=1e-12)
    for s in t.sequences:
        for m, _ in METRICS:
            vals = {a: c.value(m) for a in t.algorithms
                    if (c := t.cell(s, a)) is not None and c.value(m) is not None}
            if len(vals) < 2:  # nothing to compare with: nothing is best
                assert not any(t.is_best(s, a, m) for a in t.algorithms)
                continue
            low = min(round(v, DECIMALS) for v in vals.values())
            assert {a for a in t.algorithms if t.is_best(s, a, m)} == \
                {a for a, v in vals.items() if round(v, DECIMALS) == low}
    md = [ln for ln in t.to_markdown().splitlines() if ln.startswith("|")]
    assert len(md) == 2 + len(t.sequences)
    assert all(line.count(" | ") == md[0].count(" | ") for line in md[2:])


json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-10**12, 10**12) | st.text(max_size=8)
    | st.floats(allow_nan=False, allow_infinity=False),
    lambda kids: st.lists(kids, max_size=4) | st.dictionaries(st.text(max_size=6), kids,
                                                              max_size=4),
    max_leaves=20,
)


@given(st.dictionaries(st.text(max_size=6), json_values, max_size=5))
def test_cache_returns_exactly_what_it_stored(value) -> None:
    with tempfile.TemporaryDirectory() as d:
        cache = ContentCache(d)
        job = Job("k", box_stats, {"values": [1.0]})
        key = cache.key(job)
        cache.put(key, job, JobResult("k", "ok", value=value))
        hit = ContentCache(d).get(job, key)
        assert hit is not None and hit.cached and hit.value == value
