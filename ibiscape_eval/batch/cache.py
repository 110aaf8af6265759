"""Content cache of finished jobs: a re-run skips every job whose inputs and parameters are unchanged.

The key of a job is the SHA-256 of its function name, its parameters, the SHA-256 of every input
file's bytes (folders: of every file below them, with their relative names) and a code version
(the package version and the hash of every source file the job can reach, :func:`code_files`), so editing an input, an
option or the code that computes the result invalidates exactly the affected entries.  Entries are
JSON files (``<dir>/<k[:2]>/<k>.json``), written atomically; nothing is pickled.  Only successful
results are stored: failed jobs run again next time.

Hashing reads every input once per run; a small index (``files.json``: size, mtime and hash per
path) skips re-reading files whose size and modification time have not changed.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

from .files import atomic_write
from .jobs import Job, JobFunction, JobResult, canonical_json, function_name

__all__ = ["MAPPED_PACKAGES", "ContentCache", "code_files", "code_version", "default_cache_dir"]

_CHUNK = 1 << 20


def _file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


#: Packages of this project that live outside the ``ibiscape_eval/`` folder (``package-dir`` of
#: pyproject.toml: the simulator in ``sim/``, the command line in ``cli/``); their code computes
#: results too (``sim suite`` jobs, the benchmark's suite step), so it is part of the code version.
MAPPED_PACKAGES = ("ibiscape_eval.sim", "ibiscape_eval.cli")


def _package_dirs(name: str) -> list[Path]:
    """The folders of package ``name`` (its ``__path__``; a plain module: its file)."""
    import importlib
    import importlib.util
    import sys

    mod = sys.modules.get(name)
    if mod is not None:
        paths = getattr(mod, "__path__", None)
        file = getattr(mod, "__file__", None)
    else:  # not imported yet: locate it without running it
        spec = importlib.util.find_spec(name)
        paths = None if spec is None else spec.submodule_search_locations
        file = None if spec is None else spec.origin
    if paths:
        return [Path(p) for p in paths]
    return [Path(file)] if file else []


def code_files(func: JobFunction) -> dict[str, Path]:
    """Every ``.py`` file a job function can reach in this project, by its name relative to the
    folder above its package: its own package (all of it) and ``ibiscape_eval`` with the packages
    mapped from other folders (:data:`MAPPED_PACKAGES`)."""
    top = function_name(func).partition(":")[0].split(".", 1)[0]
    roots: list[Path] = []
    for name in sorted({top, "ibiscape_eval"}) + list(MAPPED_PACKAGES):
        roots += [d for d in _package_dirs(name) if d not in roots]
    files: dict[str, Path] = {}
    for r in roots:
        for f in sorted(r.rglob("*.py")) if r.is_dir() else [r]:
            files.setdefault(f.relative_to(r.parent).as_posix(), f)
    return files


def code_version(func: JobFunction) -> str:
    """``"<package version>+<hash>"``: the hash covers every file of :func:`code_files` (names
    and bytes), so any change to the code that computes a result (the job function, the metrics
    it calls, the simulator that wrote its inputs) invalidates the cached results."""
    from ibiscape_eval import __version__

    h = hashlib.sha256()
    for name, f in code_files(func).items():
        h.update(name.encode() + b"\0")
        h.update(f.read_bytes())
    return f"{__version__}+{h.hexdigest()[:16]}"


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/ibiscape-eval/jobs`` (``~/.cache/ibiscape-eval/jobs`` without it)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "ibiscape-eval" / "jobs"


class ContentCache:
    """Finished job results stored by content hash in ``directory`` (created on first write)."""

    def __init__(self, directory: str | os.PathLike[str]):
        self.directory = Path(directory)
        self._index_path = self.directory / "files.json"
        self._index: dict[str, list[Any]] | None = None
        self._index_dirty = False
        self._versions: dict[str, str] = {}

    def __repr__(self) -> str:
        return f"ContentCache({str(self.directory)!r})"

    # -- hashing -----------------------------------------------------------------------------
    def _load_index(self) -> dict[str, list[Any]]:
        if self._index is None:
            self._index = {}
            try:
                doc = json.loads(self._index_path.read_text(encoding="utf-8"))
                if isinstance(doc, dict):
                    self._index = doc
            except (OSError, ValueError):
                pass  # no index yet, or a damaged one: hashes are recomputed
        return self._index

    def file_hash(self, path: str | os.PathLike[str]) -> str:
        """SHA-256 of a file's bytes, or of a folder's files (relative names and bytes)."""
        p = Path(path)
        if p.is_dir():
            h = hashlib.sha256()
            for f in sorted(q for q in p.rglob("*") if q.is_file()):
                h.update(f.relative_to(p).as_posix().encode() + b"\0")
                h.update(self.file_hash(f).encode())
            return h.hexdigest()
        st = p.stat()
        index = self._load_index()
        name = str(p.resolve())
        hit = index.get(name)
        if isinstance(hit, list) and len(hit) == 3 and hit[:2] == [st.st_size, st.st_mtime_ns]:
            return str(hit[2])
        digest = _file_sha256(p)
        index[name] = [st.st_size, st.st_mtime_ns, digest]
        self._index_dirty = True
        return digest

    def key(self, job: Job) -> str:
        """The content key of ``job`` (hex SHA-256)."""
        name = job.func_name
        if name not in self._versions:
            self._versions[name] = code_version(job.func)
        doc = {
            "func": name,
            "params": dict(job.params),
            "inputs": [self.file_hash(p) for p in job.inputs],
            "code": self._versions[name],
        }
        return hashlib.sha256(canonical_json(doc).encode()).hexdigest()

    # -- entries -----------------------------------------------------------------------------
    def _entry(self, key: str) -> Path:
        return self.directory / key[:2] / f"{key}.json"

    def get(self, job: Job, key: str) -> JobResult | None:
        """The cached result of ``job`` under ``key``, or None (missing or unreadable entry)."""
        try:
            doc = json.loads(self._entry(key).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        if not isinstance(doc, dict) or not isinstance(doc.get("value"), dict):
            return None
        return JobResult(job.key, "ok", value=doc["value"], cached=True)

    def put(self, key: str, job: Job, result: JobResult) -> None:
        """Store a successful result (failed ones are not cached)."""
        if not result.ok or result.value is None:
            return
        entry = self._entry(key)
        entry.parent.mkdir(parents=True, exist_ok=True)
        with atomic_write(entry) as f:
            f.write(canonical_json({"job": job.to_dict(), "value": result.value}))

    def flush(self) -> None:
        """Write the file-hash index if it changed."""
        if self._index_dirty and self._index is not None:
            self.directory.mkdir(parents=True, exist_ok=True)
            with atomic_write(self._index_path) as f:
                f.write(canonical_json(self._index))
            self._index_dirty = False
