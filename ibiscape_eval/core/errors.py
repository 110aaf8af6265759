"""The project's error and warning types.

Every error a user can cause derives from :class:`IbiscapeError`; the command line maps it to a
single line on stderr and exit status 2.  Messages name the file, the line when there is one, and
what to do about it.

What to do is machine-readable when it is "set this option": the error carries a ``hint``, a tuple
of :class:`Remedy` (option name in the library's keyword spelling, suggested value).  The message
is a template whose ``{0}``, ``{1}`` ... are the remedies (other braces are left alone); ``str(error)`` spells them as keyword
arguments (``align="yaw"``), the command line as flags (``--align yaw``)::

    raise DegenerateInputError("the poses are collinear; use {0} or {1}",
                               hint=(Remedy("align", "yaw"), Remedy("align", "origin")))
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from os import PathLike

_SLOT = re.compile(r"\{(\d)\}")  # a remedy's place in a message: {0} ... {9}
_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")

__all__ = [
    "CalibrationError",
    "DegenerateInputError",
    "FormatError",
    "IbiscapeError",
    "IbiscapeWarning",
    "Remedy",
]


@dataclass(frozen=True)
class Remedy:
    """An option that fixes the problem: its keyword name (``"max_diff_s"``) and, if one is
    suggested, its value (``"yaw"``); ``flag=True`` for a switch (``force=True``, ``--force``)."""

    option: str
    value: str | None = None
    flag: bool = False

    def keyword(self) -> str:
        """The remedy as a Python keyword argument: ``align="yaw"``, ``rate_hz=200``,
        ``force=True``, or the bare name ``offset_s`` when no value is suggested."""
        if self.flag:
            return f"{self.option}=True"
        if self.value is None:
            return self.option
        return f"{self.option}={self.value}" if _NUMBER.fullmatch(self.value) else (
            f'{self.option}="{self.value}"')


class IbiscapeError(Exception):
    """Base class of every error caused by the user's input or options.

    ``message`` may name the remedies of ``hint`` as ``{0}``, ``{1}`` ...; they are spelt as
    keyword arguments in ``str(error)`` and by :meth:`render` in any other spelling.
    """

    prefix = ""

    def __init__(self, message: str = "", *args: object, hint: tuple[Remedy, ...] = ()) -> None:
        self.template = str(message)
        self.hint = tuple(hint)
        super().__init__(self.render(Remedy.keyword), *args)

    def render(self, spell: Callable[[Remedy], str]) -> str:
        """The message with each remedy spelt by ``spell`` (the CLI passes its flag speller)."""
        text = self.spelt(spell)
        return f"{self.prefix}: {text}" if self.prefix else text

    def spelt(self, spell: Callable[[Remedy], str]) -> str:
        """The message without the file prefix, remedies spelt by ``spell``."""
        if not self.hint:
            return self.template
        words = [spell(r) for r in self.hint]
        return _SLOT.sub(lambda m: words[int(m.group(1))], self.template)


class FormatError(IbiscapeError):
    """A data file does not follow its format.

    Parameters
    ----------
    path
        The file that is wrong.
    message
        What was expected and what to do, e.g. ``"expected 8 columns (t x y z qx qy qz qw), got 9"``.
    line
        1-based line number in the file, if the problem sits on one line.
    hint
        The options that fix it (see :class:`Remedy`).
    """

    def __init__(self, path: str | PathLike[str] | None, message: str, line: int | None = None,
                 *, hint: tuple[Remedy, ...] = ()):
        self.path = None if path is None else str(path)
        self.line = line
        where = "" if self.path is None else self.path
        if line is not None:
            where = f"{where}:{line}" if where else f"line {line}"
        self.prefix = where
        super().__init__(message, hint=hint)
        self.detail = self.spelt(Remedy.keyword)

class DegenerateInputError(IbiscapeError):
    """Valid data on which the requested computation is not defined (too few poses, collinear ...)."""


class CalibrationError(IbiscapeError):
    """A calibration could not be computed from the given data."""


class IbiscapeWarning(UserWarning):
    """Something was repaired or skipped; the result is still valid.  Printed by the CLI on stderr."""
