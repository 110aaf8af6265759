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


def require_shared(*parts: str) -> Path:
    """The path ``SHARED_DATA/parts...``; skips the test when it is missing (fails under CI)."""
    p = SHARED_DATA.joinpath(*parts)
    if not p.exists():
        msg = (f"shared real data {p} is missing; check out ../shared/data beside the repository "
               "or set IBISCAPE_SHARED_DATA")
        if in_ci():
            pytest.fail(msg + " (CI=true: the cross-checks on real data must run)", pytrace=False)
        pytest.skip(msg)
    return p
