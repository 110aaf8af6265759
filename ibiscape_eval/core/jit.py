"""numba compilation on first use: the project's one lazy-load helper for numba kernels.

numba takes about a second to import, so no module imports it at import time.  A standalone
kernel (one that calls no other kernel) is a plain Python function decorated with
:func:`lazy_njit`: it stays importable by name, and numba is imported and the function compiled
(``cache=True``: once per machine) on its first call.  Kernels that call each other live together
in a kernel module (``*_kernels.py``, decorated with numba's own ``njit``) that the code using
them imports inside a function.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from typing import Any

__all__ = ["LazyKernel", "lazy_njit"]

_DEFAULTS: dict[str, Any] = {"cache": True, "nogil": True}


class LazyKernel:
    """A function compiled with ``numba.njit(**options)`` on its first call.

    ``kernel.py_func`` is the plain Python function; ``kernel.compiled()`` the numba dispatcher
    (call it directly in a loop or a thread to skip this wrapper).
    """

    def __init__(self, py_func: Callable[..., Any], options: dict[str, Any]):
        self.py_func = py_func
        self.options = {**_DEFAULTS, **options}
        self._compiled: Any = None
        self._lock = threading.Lock()
        functools.update_wrapper(self, py_func)

    def compiled(self) -> Any:
        if self._compiled is None:
            with self._lock:
                if self._compiled is None:
                    from numba import njit

                    self._compiled = njit(**self.options)(self.py_func)
        return self._compiled

    def __call__(self, *args: Any) -> Any:
        return self.compiled()(*args)

    def __repr__(self) -> str:
        return f"<lazy numba kernel {self.py_func.__module__}.{self.py_func.__qualname__}>"


def lazy_njit(**options: Any) -> Callable[[Callable[..., Any]], LazyKernel]:
    """Decorator: compile with ``numba.njit(cache=True, nogil=True, **options)`` on first call."""

    def wrap(fn: Callable[..., Any]) -> LazyKernel:
        return LazyKernel(fn, options)

    return wrap
