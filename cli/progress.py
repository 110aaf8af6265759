"""The one progress bar of the command line (public: every command uses it).

Library functions never print: long ones take an optional callback (see
:mod:`ibiscape_eval.core.progress`), and a command passes the bar's ``update`` (units done) or
:func:`fraction_callback` (for a ``(fraction, label)`` callback such as the simulator's)::

    from ibiscape_eval.cli.progress import progress_bar

    with progress_bar(n_samples, "allan", unit="sample") as bar:
        allan_deviation(rec, rate, progress=bar.update)

The bar goes to stderr (stdout stays clean for ``--json``), only when stderr is a terminal, and
only once the work has run for ``delay_s`` seconds, so short runs and tests print nothing.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

__all__ = ["BatchBar", "fraction_callback", "progress_bar"]


def progress_bar(total: int | None, desc: str, *, unit: str = "it", unit_scale: bool = True,
                 delay_s: float = 2.0) -> Any:
    """A tqdm bar on stderr over ``total`` units (None: unknown), hidden when stderr is not a
    terminal or the work ends within ``delay_s``.  Use it as a context manager."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, unit_scale=unit_scale, file=sys.stderr,
                disable=not sys.stderr.isatty(), delay=delay_s, leave=False)


def fraction_callback(bar: Any, desc: str, steps: int = 1000) -> Callable[[float, str], None]:
    """A ``(fraction done, label)`` callback that drives ``bar`` (made with ``total=steps``)."""

    def update(frac: float, label: str) -> None:
        bar.set_description(f"{desc}: {label}", refresh=False)
        bar.update(max(0, int(frac * steps) - bar.n))

    return update


class BatchBar:
    """A bar driven by a batch's ``(done, failed, remaining)`` callback, the failures beside it.

    ``desc`` may change between calls (the benchmark's steps): a new description starts a new bar.
    Call :meth:`close` when the batch ends.
    """

    def __init__(self, desc: str, *, unit: str = "job", delay_s: float = 2.0) -> None:
        self.desc, self.unit, self.delay_s = desc, unit, delay_s
        self.bar: Any = None

    def __call__(self, done: int, failed: int, remaining: int) -> None:
        if self.bar is None:
            self.bar = progress_bar(done + remaining, self.desc, unit=self.unit, unit_scale=False,
                                    delay_s=self.delay_s)
        self.bar.update(done - self.bar.n)
        self.bar.set_postfix_str(f"failed {failed}, remaining {remaining}", refresh=False)

    def step(self, desc: str, done: int, failed: int, remaining: int) -> None:
        """The same for a batch of named steps: a bar per step."""
        if desc != self.desc:
            self.close()
            self.desc = desc
        self(done, failed, remaining)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
