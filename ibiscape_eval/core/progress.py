"""Progress reporting convention of the library (the library never prints).

A long-running function takes ``progress: ProgressCallback | None = None`` and calls it with the
number of work units (samples, events, rows) done since its previous call; the caller decides how
to show it (the command line passes the ``update`` of
:func:`ibiscape_eval.cli.progress.progress_bar`; a notebook may pass ``tqdm(...).update``).
Functions whose total is not countable up front take a :data:`FractionCallback` instead
(fraction done in [0, 1], and a short label of the current stage).
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["FractionCallback", "ProgressCallback"]

#: Called with the units done since the previous call.
ProgressCallback = Callable[[int], None]
#: Called with the fraction done in [0, 1] and the current stage's label.
FractionCallback = Callable[[float, str], None]
