"""The public atomic writer: umask read without changing it, no partial output on failure."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from ibiscape_eval.io import atomic


def test_current_umask_matches_and_never_sets_it(monkeypatch: pytest.MonkeyPatch) -> None:
    old = os.umask(0o027)
    try:
        def refuse(_mask: int) -> int:
            raise AssertionError("os.umask must not be called while writing")

        monkeypatch.setattr(os, "umask", refuse)
        assert atomic.current_umask() == 0o027
    finally:
        monkeypatch.undo()
        os.umask(old)


def test_published_file_gets_umask_permissions_without_os_umask(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    old = os.umask(0o027)
    try:
        monkeypatch.setattr(os, "umask", lambda _m: (_ for _ in ()).throw(AssertionError("umask")))
        with atomic.atomic_write(tmp_path / "a.txt") as f:
            f.write("x")
        with atomic.atomic_output_dir(tmp_path / "d") as d:
            (d / "f").write_text("y")
    finally:
        monkeypatch.undo()
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "a.txt").stat().st_mode) == 0o640
    assert stat.S_IMODE((tmp_path / "d").stat().st_mode) == 0o750


def test_failure_leaves_nothing(tmp_path: Path) -> None:
    with pytest.raises(RuntimeError), atomic.atomic_write(tmp_path / "a.txt") as f:
        f.write("partial")
        raise RuntimeError("late error")
    assert list(tmp_path.iterdir()) == []
