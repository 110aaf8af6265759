"""The explicit package list in pyproject.toml names every package folder (a wheel would lack the rest)."""

from __future__ import annotations

from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parents[1]


def test_every_package_folder_is_listed() -> None:
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    mapping: dict[str, str] = conf["package-dir"]
    found = set()
    for name, folder in mapping.items():
        base = ROOT / folder
        for init in base.rglob("__init__.py"):
            rel = init.parent.relative_to(base).parts
            found.add(".".join((name, *rel)))
    listed = set(conf["packages"])
    assert not (found - listed), f"packages missing from pyproject.toml: {sorted(found - listed)}"
    assert not (listed - found), f"listed packages without a folder: {sorted(listed - found)}"
