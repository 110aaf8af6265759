"""The fast paths for large files (parallel tokenizing, fused pose checks, split metric kernels)
give exactly what the plain paths give: values, warnings, errors and their line numbers.

The size thresholds are lowered so that small files take the large-file paths."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.io import _poses, _text, read_trajectory
from ibiscape_eval.metrics import _fast, ate, rpe


def tum_text(seed: int, n: int = 3000) -> str:
    """A TUM file with comments, blank lines, tabs, commas and CRLF sprinkled in."""
    rng = np.random.default_rng(seed)
    t = 1_305_031_102.0 + np.arange(n) * 0.01
    pos = np.cumsum(rng.normal(0, 0.01, (n, 3)), axis=0)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    lines = ["# timestamp tx ty tz qx qy qz qw"]
    for i in range(n):
        sep = (" ", "\t", ", ", "  ")[rng.integers(4)]
        lines.append(sep.join([f"{t[i]:.6f}", *(f"{v:.9f}" for v in (*pos[i], *q[i]))]))
        r = rng.random()
        if r < 0.01:
            lines.append("# a comment")
        elif r < 0.02:
            lines.append("")
    end = "\r\n" if seed % 2 else "\n"
    return end.join(lines) + ("" if seed % 3 == 0 else end)  # sometimes no final newline


def read_both(path: Path, monkeypatch: pytest.MonkeyPatch):
    """(sequential result, parallel result), each as (trajectory or error text, warnings)."""

    def attempt():
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            try:
                out = read_trajectory(path, "tum")
            except FormatError as e:
                out = str(e)
        return out, [str(x.message) for x in w]

    with monkeypatch.context() as m:
        m.setattr(_text, "_PARALLEL_BYTES", 1 << 40)
        m.setattr(_poses, "_FUSED_MIN_ROWS", 1 << 40)
        plain = attempt()
    with monkeypatch.context() as m:
        m.setattr(_text, "_PARALLEL_BYTES", 256)
        m.setattr(_text, "_workers", lambda: 2)
        m.setattr(_poses, "_FUSED_MIN_ROWS", 10)
        m.setattr(_poses, "_PARALLEL_ROWS", 20)
        m.setattr(_poses, "_workers", lambda: 2)
        fast = attempt()
    return plain, fast


def same(a, b) -> None:
    (ta, wa), (tb, wb) = a, b
    assert wa == wb
    if isinstance(ta, str) or isinstance(tb, str):
        assert ta == tb
        return
    assert np.array_equal(ta.stamps_ns, tb.stamps_ns)
    np.testing.assert_allclose(ta.pos_m, tb.pos_m, rtol=0, atol=0)
    np.testing.assert_allclose(ta.quat_xyzw, tb.quat_xyzw, rtol=0, atol=4e-16)


@pytest.mark.parametrize("seed", range(6))
def test_clean_files_parse_identically(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, seed: int
) -> None:
    p = tmp_path / "t.txt"
    p.write_text(tum_text(seed), newline="")
    plain, fast = read_both(p, monkeypatch)
    assert not isinstance(plain[0], str) and len(plain[0]) == 3000
    same(plain, fast)


@pytest.mark.parametrize("where", [5, 1500, 2990])
@pytest.mark.parametrize(
    "damage",
    ["abc", "nan", "extra", "zeroq", "backwards", "duplicate"],
)
def test_damaged_rows_report_the_same_lines(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, where: int, damage: str
) -> None:
    lines = tum_text(10).split("\n")
    k = next(i for i in range(where, len(lines)) if lines[i] and not lines[i].startswith("#"))
    f = lines[k].replace("\t", " ").replace(",", " ").split()
    if damage == "abc":
        f[2] = "abc"
    elif damage == "nan":
        f[1] = "nan"
    elif damage == "extra":
        f.append("1.0")
    elif damage == "zeroq":
        f[4:8] = ["0", "0", "0", "0"]
    elif damage == "backwards":
        f[0] = "1305031000.000000"
    else:  # duplicate: repeat the previous data row's stamp
        prev = next(
            lines[i] for i in range(k - 1, 0, -1) if lines[i] and not lines[i].startswith("#")
        )
        f[0] = prev.replace("\t", " ").replace(",", " ").split()[0]
    lines[k] = " ".join(f)
    p = tmp_path / "t.txt"
    p.write_text("\n".join(lines))
    plain, fast = read_both(p, monkeypatch)
    same(plain, fast)
    text = plain[0] if isinstance(plain[0], str) else " ".join(plain[1])
    assert str(k + 1) in text  # the 1-based line of the damaged row is named


def test_split_metric_kernels_match_unsplit(monkeypatch: pytest.MonkeyPatch) -> None:
    from ibiscape_eval.core import Trajectory

    rng = np.random.default_rng(3)
    n = 5000
    stamps = np.arange(n, dtype=np.int64) * 10_000_000
    pos = np.cumsum(rng.normal(0, 0.05, (n, 3)), axis=0)
    q = rng.normal(size=(n, 4))
    ref = Trajectory(stamps, pos, q / np.linalg.norm(q, axis=1, keepdims=True))
    dq = rng.normal(0, 0.01, (n, 4)) + np.array([0.0, 0.0, 0.0, 1.0])
    from ibiscape_eval.core.rotations import quat_multiply

    est = Trajectory(
        stamps,
        pos + rng.normal(0, 0.02, (n, 3)),
        quat_multiply(ref.quat_xyzw, dq / np.linalg.norm(dq, axis=1, keepdims=True)),
    )
    base_a, base_r = (
        ate(est, ref, align="sim3"),
        rpe(est, ref, delta=2.0, delta_unit="metres", pairs="all"),
    )
    with monkeypatch.context() as m:
        m.setattr(_fast, "_SPLIT_ROWS", 100)
        m.setattr(_fast, "_cpus", lambda: 2)
        a, r = (
            ate(est, ref, align="sim3"),
            rpe(est, ref, delta=2.0, delta_unit="metres", pairs="all"),
        )
    np.testing.assert_allclose(a.errors_m, base_a.errors_m, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a.errors_deg, base_a.errors_deg, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(r.errors_m, base_r.errors_m, rtol=1e-12, atol=1e-15)
    assert r.n_pairs == base_r.n_pairs
