"""What every command shares: error mapping, warnings on stderr, JSON output, format options.

No math here.  Commands parse options, call ``ibiscape_eval.io`` and one library function, print.
"""

from __future__ import annotations

import functools
import json
import sys
import warnings
from collections.abc import Callable
from typing import Any, TypeVar

import click

from ibiscape_eval.core.errors import IbiscapeError, IbiscapeWarning

F = TypeVar("F", bound=Callable[..., Any])

__all__ = ["echo_json", "fail", "info", "strict_json", "user_errors"]


def fail(message: str) -> None:
    """Print one line on stderr and exit with status 2."""
    click.echo(f"error: {' '.join(str(message).split())}", err=True)
    sys.exit(2)


def info(message: str) -> None:
    """A one-line note on stderr (format chosen, poses dropped ...), never on stdout."""
    click.echo(message, err=True)


def _show_warning(
    message: Any, category: Any, filename: Any, lineno: Any, file: Any = None, line: Any = None
) -> None:
    label = "warning" if issubclass(category, IbiscapeWarning) else category.__name__
    click.echo(f"{label}: {' '.join(str(message).split())}", err=True)


def user_errors(func: F) -> F:
    """Decorate a command: map :class:`IbiscapeError` and OS errors on user files to one stderr line
    and exit status 2; show library warnings as one line each on stderr."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        old = warnings.showwarning
        warnings.showwarning = _show_warning
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("always", IbiscapeWarning)
                warnings.showwarning = _show_warning
                return func(*args, **kwargs)
        except IbiscapeError as e:
            fail(str(e))
        except FileNotFoundError as e:
            fail(f"{e.filename}: no such file or directory; check the path")
        except IsADirectoryError as e:
            fail(f"{e.filename}: is a directory, expected a file")
        except PermissionError as e:
            fail(f"{e.filename}: permission denied")
        except OSError as e:  # symbolic-link loops, full disks, devices ...
            from ibiscape_eval.io.paths import os_error_message

            fail(os_error_message(e))
        except MemoryError:
            fail("out of memory; process the input in smaller pieces")
        finally:
            warnings.showwarning = old

    return wrapper  # type: ignore[return-value]


def echo_json(doc: Any) -> None:
    """Write one strict JSON document on stdout (``allow_nan=False``).

    numpy scalars and arrays are converted; a non-finite number becomes ``null`` and its place is
    listed under the top-level key ``"non_finite"`` (JSON pointer -> ``"nan"``, ``"inf"`` or
    ``"-inf"``), so a reader knows why the value is missing.
    """
    text = json.dumps(strict_json(doc), indent=2, allow_nan=False)
    click.echo(text)


def strict_json(doc: Any) -> Any:
    """``doc`` as plain JSON values with every non-finite float replaced by None; the replaced
    places are listed under ``"non_finite"`` when ``doc`` is a mapping."""
    import math

    import numpy as np

    missing: dict[str, str] = {}

    def clean(o: Any, where: str) -> Any:
        if isinstance(o, np.ndarray):
            o = o.tolist()
        elif isinstance(o, np.generic):
            o = o.item()
        if isinstance(o, float):
            if math.isfinite(o):
                return o
            missing[where or "/"] = "nan" if o != o else ("inf" if o > 0 else "-inf")
            return None
        if isinstance(o, dict):
            return {str(k): clean(v, f"{where}/{k}") for k, v in o.items()}
        if isinstance(o, list | tuple):
            return [clean(v, f"{where}/{i}") for i, v in enumerate(o)]
        if o is None or isinstance(o, bool | int | str):
            return o
        raise TypeError(f"not JSON serialisable: {type(o).__name__}")

    out = clean(doc, "")
    if missing and isinstance(out, dict):
        out = {**out, "non_finite": {**out.get("non_finite", {}), **missing}}
    return out
