"""Where the shared real data lives (``../shared/data`` beside the checkout, or the folder named by
``IBISCAPE_SHARED_DATA``), and what a test does when it is missing: skip on a developer's machine,
FAIL under CI (``CI=true``), so that the cross-checks against evo and allantools cannot silently
stop running."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("IBISCAPE_SHARED_DATA") or ROOT.parent / "shared" / "data")
TRAJECTORIES = SHARED_DATA / "trajectories"


def in_ci() -> bool:
    return os.environ.get("CI", "").strip().lower() in ("1", "true", "yes")


#: The paper's LaTeX source, beside the data in the shared folder.
PAPER = SHARED_DATA.parent / "paper" / "ibiscape-paper.tex"


def require_path(p: Path) -> Path:
    """``p`` (a file of the shared folder); skips the test when it is missing (fails under CI)."""
    if not p.exists():
        msg = (f"shared real data {p} is missing; check out ../shared beside the repository "
               "or set IBISCAPE_SHARED_DATA to its data folder")
        if in_ci():
            pytest.fail(msg + " (CI=true: the cross-checks on real data must run)", pytrace=False)
        pytest.skip(msg)
    return p


def require_shared(*parts: str) -> Path:
    """The path ``SHARED_DATA/parts...``; skips the test when it is missing (fails under CI)."""
    return require_path(SHARED_DATA.joinpath(*parts))
