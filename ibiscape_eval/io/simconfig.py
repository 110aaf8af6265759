"""The simulator's YAML configuration file: parsing into plain mappings and commented output.

This module knows YAML, not the simulator: :func:`read_sim_config_yaml` returns the file's
mapping together with the line of every key, so that :mod:`ibiscape_eval.sim.config` (which builds
its typed dataclasses from the mapping) can name the file *and line* of a bad key or value;
:func:`render_commented_yaml` writes a tree of :class:`YamlItem` (built by the simulator from its
dataclasses) as YAML with a comment per key.  ``yaml.safe_load`` only.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from ibiscape_eval.core.errors import FormatError

from .atomic import atomic_write

__all__ = ["SimConfigDoc", "YamlItem", "read_sim_config_yaml", "render_commented_yaml",
           "write_sim_config_yaml"]


@dataclass(frozen=True)
class SimConfigDoc:
    """A parsed configuration file.

    Attributes
    ----------
    path : str
        The file read.
    data : dict
        The top-level mapping (``{}`` for an empty file), plain Python values.
    key_lines : mapping of tuple of str to int
        1-based line of every mapping key, by its path (``("cameras", "rgbL", "fov_deg")``).
    """

    path: str
    data: dict[str, Any]
    key_lines: Mapping[tuple[str, ...], int] = field(default_factory=dict, repr=False)

    def line_of(self, keys: Sequence[str]) -> int | None:
        """Line of the key path ``keys`` or of its nearest parent in the file, else None."""
        k = tuple(str(x) for x in keys)
        while k:
            if k in self.key_lines:
                return self.key_lines[k]
            k = k[:-1]
        return None

    def error(self, keys: Sequence[str], message: str) -> FormatError:
        """A :class:`FormatError` naming the file and the line of ``keys``."""
        return FormatError(self.path, message, line=self.line_of(keys))


#: A simulator config is a few KiB; anything much larger is not one (and not worth parsing).
_MAX_CONFIG_BYTES = 1 << 20


class _DuplicateKeyError(Exception):
    def __init__(self, key: tuple[str, ...], first: int, line: int) -> None:
        super().__init__(key)
        self.key, self.first, self.line = key, first, line


def _key_lines(node: Any, prefix: tuple[str, ...], out: dict[tuple[str, ...], int]) -> None:
    import yaml

    if isinstance(node, yaml.MappingNode):
        for knode, vnode in node.value:
            key = (*prefix, str(knode.value))
            line = knode.start_mark.line + 1
            if key in out:  # yaml.safe_load silently keeps the last value
                raise _DuplicateKeyError(key, out[key], line)
            out[key] = line
            _key_lines(vnode, key, out)


def read_sim_config_yaml(path: str | os.PathLike[str]) -> SimConfigDoc:
    """Read a simulator configuration file (``yaml.safe_load``).

    Raises
    ------
    FormatError
        Not valid YAML (with its line), or not a mapping at the top level.
    FileNotFoundError
        The file does not exist.
    """
    import yaml

    from .paths import check_input

    where = os.fspath(path)
    check_input(path, what="simulator config")
    with open(path, "rb") as fb:
        raw = fb.read(_MAX_CONFIG_BYTES + 1)
    if len(raw) > _MAX_CONFIG_BYTES:
        raise FormatError(where, f"larger than {_MAX_CONFIG_BYTES // 1024} KiB: not a simulator "
                          "config; start from --print-config")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        bad_line = raw[: e.start].count(b"\n") + 1
        raise FormatError(where, f"not UTF-8 text (byte 0x{raw[e.start]:02x}); save the file as "
                          "UTF-8", line=bad_line) from None
    try:
        doc = yaml.safe_load(text)
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except RecursionError:
        raise FormatError(where, "nested too deeply to be a simulator config; start from "
                          "--print-config") from None
    except yaml.YAMLError as e:
        line = getattr(getattr(e, "problem_mark", None), "line", None)
        raise FormatError(where, f"not valid YAML ({' '.join(str(e).split())})",
                          line=None if line is None else line + 1) from None
    if doc is None:
        doc = {}
    if not isinstance(doc, dict):
        raise FormatError(where, "expected a mapping of config keys at the top level")
    lines: dict[tuple[str, ...], int] = {}
    try:
        _key_lines(root, (), lines)
    except _DuplicateKeyError as e:
        raise FormatError(where, f"key {'.'.join(e.key)!r} given twice (first on line "
                          f"{e.first}); keep one", line=e.line) from None
    return SimConfigDoc(where, doc, lines)


@dataclass(frozen=True)
class YamlItem:
    """One key of :func:`render_commented_yaml`'s output.

    ``value`` is a plain value (written in YAML flow style) or a sequence of :class:`YamlItem`
    (a nested mapping).  A mapping's ``comment`` goes on its key's line, or on the line above
    when ``comment_above``.
    """

    key: str
    value: Any
    comment: str = ""
    comment_above: bool = False
    is_mapping: bool = False


def _flow(value: Any) -> str:
    import yaml

    text = yaml.safe_dump(value, default_flow_style=True, width=1000).strip()
    return text.removesuffix("\n...").removesuffix("...").strip()


def render_commented_yaml(header: Sequence[str], items: Sequence[YamlItem]) -> str:
    """YAML text: ``header`` lines as ``#`` comments, then ``items`` (two spaces per level)."""
    lines = [f"# {h}" for h in header]

    def emit(its: Sequence[YamlItem], indent: str) -> None:
        for it in its:
            if it.is_mapping:
                children = list(it.value)
                if it.comment_above:
                    lines.append(f"{indent}# {it.comment}")
                    lines.append(f"{indent}{it.key}:" + ("" if children else " {}"))
                elif it.comment:
                    lines.append(f"{indent}{it.key}:  # {it.comment}")
                else:
                    lines.append(f"{indent}{it.key}:")
                emit(children, indent + "  ")
            else:
                lines.append(f"{indent}{it.key}: {_flow(it.value)}  # {it.comment}")

    emit(items, "")
    return "\n".join(lines) + "\n"


def write_sim_config_yaml(path: str | os.PathLike[str], header: Sequence[str],
                          items: Sequence[YamlItem]) -> None:
    """Write :func:`render_commented_yaml`'s text to ``path``, atomically."""
    with atomic_write(path) as fh:
        fh.write(render_commented_yaml(header, items))
