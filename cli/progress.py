"""The one progress display of the command line (public: every command uses it).

Library functions never print: long ones take an optional callback (see
:mod:`ibiscape_eval.core.progress`), and a command passes the bar's ``update`` (units done) or
:func:`fraction_callback` (for a ``(fraction, label)`` callback such as the simulator's)::

    from ibiscape_eval.cli.progress import progress_bar

    with progress_bar(n_samples, "allan", unit="sample") as bar:
        allan_deviation(rec, rate, progress=bar.update)

Everything goes to stderr (stdout stays clean for ``--json``), only once the work has run for
``delay_s`` seconds, so short runs and tests print nothing.  On a terminal it is a tqdm bar redrawn
in place; otherwise (a log file, CI) it is plain lines: one every ``LOG_INTERVAL_S`` seconds for a
bar, one per finished job for a batch (:class:`BatchBar`).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any

__all__ = ["LOG_INTERVAL_S", "BatchBar", "LogLines", "fraction_callback", "progress_bar"]

#: Seconds between two progress lines of a bar when stderr is not a terminal.
LOG_INTERVAL_S = 5.0


class LogLines:
    """The part of tqdm's interface the commands use, written as plain lines to stderr.

    A line (``desc: n/total unit [postfix]  elapsed s``) is written at most every ``interval_s``
    seconds once ``delay_s`` have passed, or on every update with ``every_update`` (a batch: one
    line per finished job); nothing is redrawn, so a log stays readable.
    """

    def __init__(self, total: int | None, desc: str, *, unit: str = "it", delay_s: float = 2.0,
                 interval_s: float = LOG_INTERVAL_S, every_update: bool = False) -> None:
        self.total, self.desc, self.unit = total, desc, unit
        self.delay_s, self.interval_s, self.every_update = delay_s, interval_s, every_update
        self.n = 0
        self.postfix = ""
        self.t0 = time.monotonic()
        self._last: float | None = None

    def __enter__(self) -> LogLines:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def set_description(self, desc: str, refresh: bool = True) -> None:
        self.desc = desc

    def set_postfix_str(self, s: str = "", refresh: bool = True) -> None:
        self.postfix = s

    def reset(self, total: int | None = None) -> None:
        """Start counting again (over ``total`` units)."""
        self.n, self.total = 0, total

    def update(self, n: float = 1) -> None:
        self.n += int(n)
        now = time.monotonic()
        if now - self.t0 < self.delay_s:
            return
        if self.every_update or now - (self._last if self._last is not None else self.t0) \
                >= self.interval_s:
            self.write(now)

    def write(self, now: float | None = None) -> None:
        """Write the current line now."""
        now = time.monotonic() if now is None else now
        self._last = now
        total = f"/{self.total}" if self.total else ""
        extra = f" ({self.postfix})" if self.postfix else ""
        print(f"{self.desc}: {self.n}{total} {self.unit}{extra}  {now - self.t0:.0f} s",
              file=sys.stderr, flush=True)

    def close(self) -> None:
        pass


def progress_bar(total: int | None, desc: str, *, unit: str = "it", unit_scale: bool = True,
                 delay_s: float = 2.0) -> Any:
    """A tqdm bar on stderr over ``total`` units (None: unknown) when stderr is a terminal, else
    :class:`LogLines` (a line every few seconds); nothing when the work ends within ``delay_s``.
    Use it as a context manager."""
    if not sys.stderr.isatty():
        return LogLines(total, desc, unit=unit, delay_s=delay_s)
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, unit_scale=unit_scale, file=sys.stderr,
                delay=delay_s, leave=False)


def fraction_callback(bar: Any, desc: str, steps: int = 1000) -> Callable[[float, str], None]:
    """A ``(fraction done, label)`` callback that drives ``bar`` (made with ``total=steps``)."""

    def update(frac: float, label: str) -> None:
        bar.set_description(f"{desc}: {label}", refresh=False)
        bar.update(max(0, int(frac * steps) - bar.n))

    return update


class BatchBar:
    """A bar driven by a batch's ``(done, failed, remaining)`` callback, the failures beside it.

    ``desc`` may change between calls (the benchmark's steps): a new description starts a new bar.
    When stderr is not a terminal, one line per finished job (once the batch has run ``delay_s``).
    Call :meth:`close` when the batch ends.
    """

    def __init__(self, desc: str, *, unit: str = "job", delay_s: float = 2.0) -> None:
        self.desc, self.unit, self.delay_s = desc, unit, delay_s
        self.bar: Any = None

    def __call__(self, done: int, failed: int, remaining: int) -> None:
        if self.bar is None:
            if sys.stderr.isatty():
                self.bar = progress_bar(done + remaining, self.desc, unit=self.unit,
                                        unit_scale=False, delay_s=self.delay_s)
            else:
                self.bar = LogLines(done + remaining, self.desc, unit=self.unit,
                                    delay_s=self.delay_s, every_update=True)
            if done == 0:  # the batch starts: nothing finished yet, no line
                self.bar.set_postfix_str(f"failed {failed}, remaining {remaining}", refresh=False)
                return
        self.bar.set_postfix_str(f"failed {failed}, remaining {remaining}", refresh=False)
        self.bar.update(done - self.bar.n)

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
