"""Content cache of finished jobs: a re-run skips every job whose inputs and parameters are unchanged.

The key of a job is the SHA-256 of its function name, its parameters, the SHA-256 of every input
file's bytes (folders: of every file below them, with their relative names) and a code version
(the package version and the hash of the job function's source file), so editing an input, an
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
from .jobs import Job, JobResult, canonical_json, resolve

__all__ = ["ContentCache", "code_version", "default_cache_dir"]

_CHUNK = 1 << 20


def _file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


def code_version(func: str) -> str:
    """``"<package version>+<hash>"``: the hash covers every ``.py`` file of the package that
    defines ``func`` (and of ``ibiscape_eval``), so any change to the code that computes a result
    (the job function or the metrics it calls) invalidates the cached results."""
    import importlib

    from ibiscape_eval import __version__

    resolve(func)  # fails clearly for a job function that cannot be imported
    h = hashlib.sha256()
    for top in sorted({func.partition(":")[0].split(".", 1)[0], "ibiscape_eval"}):
        root = getattr(importlib.import_module(top), "__file__", None)
        if not root:
            continue
        base = Path(root).parent
        files = sorted(base.rglob("*.py")) if Path(root).name == "__init__.py" else [Path(root)]
        for f in files:
            h.update(f.relative_to(base.parent).as_posix().encode() + b"\0")
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
        if job.func not in self._versions:
            self._versions[job.func] = code_version(job.func)
        doc = {
            "func": job.func,
            "params": dict(job.params),
            "inputs": [self.file_hash(p) for p in job.inputs],
            "code": self._versions[job.func],
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
