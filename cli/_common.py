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

__all__ = ["echo_json", "fail", "info", "user_errors"]


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
        except MemoryError:
            fail("out of memory; process the input in smaller pieces")
        finally:
            warnings.showwarning = old

    return wrapper  # type: ignore[return-value]


def echo_json(doc: Any) -> None:
    """Write one JSON document on stdout (NaN written as null, numpy scalars converted)."""

    def default(o: Any) -> Any:
        import numpy as np

        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, np.generic):
            return o.item()
        raise TypeError(f"not JSON serialisable: {type(o).__name__}")

    def clean(o: Any) -> Any:
        if isinstance(o, float) and o != o:
            return None
        if isinstance(o, dict):
            return {k: clean(v) for k, v in o.items()}
        if isinstance(o, list | tuple):
            return [clean(v) for v in o]
        return o

    text = json.dumps(clean(json.loads(json.dumps(doc, default=default))), indent=2)
    click.echo(text)
