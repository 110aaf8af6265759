"""Data helpers shared by the command-line tests (imported by name: tests are not a package)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "data"


def write_tum(path: Path, stamps_s: np.ndarray, pos: np.ndarray, quat: np.ndarray) -> Path:
    """Write a TUM file with numpy only (independent of the writer under test)."""
    rows = np.column_stack([stamps_s, pos, quat])
    np.savetxt(path, rows, fmt="%.9f")
    return path


def assert_one_error_line(res, *needles: str, stdout_empty: bool = True) -> None:
    """A user error: exit status 2, exactly one ``error:`` line on stderr holding every needle,
    no traceback, and (unless the command legitimately printed a partial result) no stdout."""
    assert res.exit_code == 2, res.output
    lines = [s for s in res.stderr.splitlines() if s.startswith("error:")]
    assert len(lines) == 1, res.stderr
    for n in needles:
        assert n in lines[0], lines[0]
    assert "Traceback" not in res.output
    if stdout_empty:
        assert res.stdout == "", res.stdout
