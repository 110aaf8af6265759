"""Lazy package exports (PEP 562): a package names its public objects and the modules defining
them; each is imported on first access, so importing the package loads nothing heavy.

::

    _EXPORTS = {"Renderer": "renderer", ...}
    __all__ = sorted(_EXPORTS)
    __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

Standard library only: ``import ibiscape_eval`` must not load numpy.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(module_name: str, exports: Mapping[str, str], *, relative: bool = True
                 ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of the package ``module_name``.

    ``exports`` maps a public name to the module defining it: a submodule name (``"renderer"``,
    ``relative=True``) or a full module path (``relative=False``), optionally followed by
    ``:attribute`` when the module names the object differently (``"sim.generator:generate"``).
    A loaded name is cached in the package's namespace, so the next access does not come back
    here.  ``dir()`` lists the exports and the package's public dunders (``__version__``), not
    the names the package module itself imported (``annotations``, ``TYPE_CHECKING`` ...) unless
    its ``__all__`` names them (a light import such as the error types).
    """

    def get_attr(name: str) -> Any:
        if name in exports:
            where, _, attr = exports[name].partition(":")
            target = f"{module_name}.{where}" if relative else where
            value = getattr(importlib.import_module(target), attr or name)
            setattr(sys.modules[module_name], name, value)
            return value
        raise AttributeError(f"module {module_name!r} has no attribute {name!r}")

    def dir_names() -> list[str]:
        module = vars(sys.modules[module_name])
        own = {n for n in module if n in ("__version__", "__all__")}
        return sorted(own | set(exports) | set(module.get("__all__", ())))

    return get_attr, dir_names
