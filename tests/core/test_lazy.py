"""Lazy package exports: first access imports and caches, unknown names raise AttributeError,
and importing the packages loads no numpy."""

from __future__ import annotations

import subprocess
import sys
import types

import pytest

from ibiscape_eval.core.lazy import lazy_exports


def test_lazy_exports_load_cache_and_refuse(monkeypatch: pytest.MonkeyPatch) -> None:
    mod = types.ModuleType("fake_pkg")
    monkeypatch.setitem(sys.modules, "fake_pkg", mod)
    get, names = lazy_exports("fake_pkg", {"dumps": "json", "sqrt": "math"}, relative=False)
    assert get("dumps") is __import__("json").dumps
    assert mod.dumps is __import__("json").dumps  # cached in the package namespace
    assert {"dumps", "sqrt"} <= set(names())
    with pytest.raises(AttributeError, match="module 'fake_pkg' has no attribute 'nope'"):
        get("nope")


def test_packages_resolve_their_exports() -> None:
    import ibiscape_eval
    import ibiscape_eval.core
    import ibiscape_eval.vio
    import sim
    import sim.render

    for pkg in (ibiscape_eval, ibiscape_eval.core, ibiscape_eval.vio, sim, sim.render):
        assert set(pkg.__all__) <= set(dir(pkg))
        with pytest.raises(AttributeError):
            pkg.no_such_name  # noqa: B018
    assert ibiscape_eval.Trajectory is ibiscape_eval.core.Trajectory


def test_import_loads_no_numpy() -> None:
    code = ("import sys, ibiscape_eval, ibiscape_eval.core, sim, sim.render, ibiscape_eval.vio\n"
            "print([m for m in ('numpy', 'scipy') if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"
