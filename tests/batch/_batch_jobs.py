"""Job functions for the batch tests (importable by spawned worker processes)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any


def square(*, x: float) -> dict[str, Any]:
    return {"x": x, "y": x * x}


def boom(*, x: float) -> dict[str, Any]:
    raise ValueError(f"no square for {x}")


def die(*, x: float) -> dict[str, Any]:
    os._exit(3)  # a crash that takes the worker process down


def file_size(*, path: str, log: str, **_: Any) -> dict[str, Any]:
    """Size of a file; appends a line to ``log`` each time it really runs."""
    with open(log, "a") as f:
        f.write(path + "\n")
    return {"size": Path(path).stat().st_size}


def not_a_dict(*, x: float) -> Any:
    return [x]


def nan_result(*, x: float) -> dict[str, Any]:
    return {"value": float("nan")}
