"""The project's error and warning types.

Every error a user can cause derives from :class:`IbiscapeError`; the command line maps it to a
single line on stderr and exit status 2.  Messages name the file, the line when there is one, and
what to do about it.
"""

from __future__ import annotations

from os import PathLike

__all__ = [
    "CalibrationError",
    "DegenerateInputError",
    "FormatError",
    "IbiscapeError",
    "IbiscapeWarning",
]


class IbiscapeError(Exception):
    """Base class of every error caused by the user's input or options."""


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
    """

    def __init__(self, path: str | PathLike[str] | None, message: str, line: int | None = None):
        self.path = None if path is None else str(path)
        self.line = line
        self.detail = message
        where = "" if self.path is None else self.path
        if line is not None:
            where = f"{where}:{line}" if where else f"line {line}"
        super().__init__(f"{where}: {message}" if where else message)


class DegenerateInputError(IbiscapeError):
    """Valid data on which the requested computation is not defined (too few poses, collinear ...)."""


class CalibrationError(IbiscapeError):
    """A calibration could not be computed from the given data."""


class IbiscapeWarning(UserWarning):
    """Something was repaired or skipped; the result is still valid.  Printed by the CLI on stderr."""
