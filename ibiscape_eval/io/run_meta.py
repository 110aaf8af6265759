"""``run.yaml``: what a runs folder says about how one run (or every trial of an algorithm) is to be
evaluated.

A small YAML mapping beside a run's estimate (``RUNS_DIR/<sequence>/<algorithm>/<trial>/run.yaml``)
or in its algorithm folder (``RUNS_DIR/<sequence>/<algorithm>/run.yaml``, every trial)::

    align: sim3        # none, origin, se3, sim3 or yaw: a monocular run needs sim3

Unknown keys are refused (a misspelt ``alignment:`` would otherwise be ignored and the run
evaluated with the default); read with ``yaml.safe_load`` only.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from ibiscape_eval.core.errors import FormatError

from .yaml_file import read_yaml

__all__ = ["RUN_META_ALIGNMENTS", "RUN_META_NAME", "RunMeta", "read_run_meta"]

RUN_META_NAME = "run.yaml"
RUN_META_ALIGNMENTS = ("none", "origin", "se3", "sim3", "yaw")
_KEYS = ("align",)


@dataclass(frozen=True)
class RunMeta:
    """The content of a ``run.yaml``: ``align`` (None when the file does not set it) and the
    file's path."""

    path: str
    align: str | None = None


def read_run_meta(path: str | os.PathLike[str]) -> RunMeta:
    """Read a ``run.yaml`` (see the module docstring).

    Raises
    ------
    FormatError
        Not valid YAML, not a mapping, an unknown key or an unknown alignment (the message names
        the file and the accepted values).
    """
    doc = read_yaml(path, what="run.yaml")
    if doc is None:
        return RunMeta(str(path))
    if not isinstance(doc, dict):
        raise FormatError(path, f"expected a mapping such as 'align: sim3', got a "
                                f"{type(doc).__name__}")
    unknown = [str(k) for k in doc if k not in _KEYS]
    if unknown:
        raise FormatError(path, f"unknown key{'s' if len(unknown) > 1 else ''} "
                                f"{', '.join(map(repr, unknown))}; known: {', '.join(_KEYS)} "
                                "(e.g. 'align: sim3')")
    align = doc.get("align")
    if align is not None and (not isinstance(align, str) or align not in RUN_META_ALIGNMENTS):
        raise FormatError(path, f"align {align!r} is not one of "
                                f"{', '.join(RUN_META_ALIGNMENTS)}")
    return RunMeta(str(path), align)
