"""Data helpers shared by the command-line tests (imported by name: tests are not a package)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

SHARED = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "trajectories"
EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "data"


def write_tum(path: Path, stamps_s: np.ndarray, pos: np.ndarray, quat: np.ndarray) -> Path:
    """Write a TUM file with numpy only (independent of the writer under test)."""
    rows = np.column_stack([stamps_s, pos, quat])
    np.savetxt(path, rows, fmt="%.9f")
    return path
