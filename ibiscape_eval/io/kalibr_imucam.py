"""Write Kalibr's ``camchain-imucam.yaml`` (atomically; the document comes from
:func:`ibiscape_eval.calib.imu_camera.kalibr.camchain_imucam_document`)."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

from .atomic import atomic_write

__all__ = ["write_camchain_imucam"]


def write_camchain_imucam(path: str | os.PathLike[str], doc: Mapping[str, Any], *,
                          comments: Sequence[str] = ()) -> None:
    """Write the mapping as YAML (4x4 matrices one row per line), temp file then rename."""
    import yaml

    class _Dumper(yaml.SafeDumper):
        pass

    def _list(dumper: yaml.SafeDumper, data: list[Any]) -> Any:
        flow = all(not isinstance(v, list | dict) for v in data)
        return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)

    _Dumper.add_representer(list, _list)
    with atomic_write(path) as fh:
        for c in comments:
            fh.write(f"# {c}\n")
        fh.write(yaml.dump(dict(doc), Dumper=_Dumper, sort_keys=False))


def write_figures(folder: str | os.PathLike[str], figures: Sequence[tuple[str, Any]]) -> list[Any]:
    """Save ``(name, Figure)`` pairs into ``folder`` (created), each atomically."""
    from pathlib import Path

    from .atomic import atomic_output_path

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for name, fig in figures:
        with atomic_output_path(out / name) as tmp:
            fig.savefig(tmp, dpi=110, format=Path(name).suffix.lstrip(".") or "png")
        written.append(out / name)
    return written
