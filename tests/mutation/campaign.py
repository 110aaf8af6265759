"""The mutation campaign: seeded mutants of every input family, run in-process through the CLI,
each checked against the bad-input contract.

Contract (per mutant): exit 0, or exit 2 with exactly one ``error:`` line on stderr that names the
input file; never a traceback or another exit status; with ``--json`` and exit 0, stdout is strict
JSON (no NaN/Infinity); after exit 2 the output folder is empty, and no hidden temporary file or
folder is left anywhere in the mutant's folder; no hang (a FIFO must be refused, not opened).

Run ``python tests/mutation/campaign.py [N]`` for a report of the hold rate by family and class.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import sys
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from families import FAMILIES, Family
from mutators import BYTE_MUTATORS, PATH_MUTATORS, TEXT_ONLY

#: Mutants per campaign (split evenly over the families) and the seed of every mutation.
#: (enough for every path mutator and every byte mutator once per family: derived, so that a new
#: family does not silently push mutators out of the others' plans)
N_MUTANTS = (len(PATH_MUTATORS) + len(BYTE_MUTATORS)) * len(FAMILIES)
SEED = 20261123
#: Seconds one mutant may run before it counts as a hang.
TIMEOUT_S = 30


class Hang(BaseException):
    """Raised by the alarm: a BaseException, so no ``except Exception`` in the code under test
    can swallow it."""


@dataclass(frozen=True)
class Outcome:
    family: str
    mutator: str
    index: int
    exit_code: int | None
    problem: str | None  # None: the contract held

    def __str__(self) -> str:
        return f"{self.family}/{self.mutator}#{self.index}: {self.problem}"


def plan(n_mutants: int = N_MUTANTS) -> list[tuple[str, str, int]]:
    """(family, mutator, index) of every mutant; every path mutator once per family, then the
    byte mutators that apply to the family in turn."""
    per = max(1, n_mutants // len(FAMILIES))
    out: list[tuple[str, str, int]] = []
    for name, fam in FAMILIES.items():
        muts = [m for m in BYTE_MUTATORS if fam.text or m not in TEXT_ONLY]
        kinds = list(PATH_MUTATORS) + [muts[k % len(muts)] for k in range(max(0, per - 3))]
        out.extend((name, m, k) for k, m in enumerate(kinds[:per]))
    return out


def _strict_json(text: str) -> Any:
    def bad(token: str) -> Any:
        raise ValueError(f"non-finite number {token} in JSON")

    return json.loads(text, parse_constant=bad)


def _hidden(root: Path) -> list[str]:
    found = []
    for dirpath, dirnames, filenames in os.walk(root):
        found += [os.path.join(dirpath, n) for n in dirnames + filenames if n.startswith(".")]
    return found


def _alarm(signum: int, frame: Any) -> None:
    raise Hang()


class _Watchdog:
    """Send SIGALRM to the main thread after ``timeout_s`` and again every second until stopped
    (``signal.alarm`` may be delivered to another thread, leaving a blocking ``open()`` of a FIFO
    in the main thread uninterrupted)."""

    def __init__(self, timeout_s: float) -> None:
        self._stop = threading.Event()
        self._main = threading.main_thread().ident
        self._thread = threading.Thread(target=self._run, args=(timeout_s,), daemon=True)
        self._thread.start()

    def _run(self, timeout_s: float) -> None:
        if self._stop.wait(timeout_s):
            return
        while not self._stop.is_set():
            signal.pthread_kill(self._main, signal.SIGALRM)  # type: ignore[arg-type]
            self._stop.wait(1.0)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def check(fam: Family, res: Any, inp: Path, target: Path, out: Path, mutant_dir: Path) -> str | None:
    """The contract's verdict on one run: None if it held, else what broke."""
    exc = res.exception
    if exc is not None and not isinstance(exc, SystemExit):
        return f"traceback: {type(exc).__name__}: {str(exc)[:120]}"
    stderr = res.stderr
    if "Traceback" in stderr or "Traceback" in res.stdout:
        return "traceback printed"
    hidden = _hidden(mutant_dir)
    if hidden:
        return f"leftover hidden output {hidden[0]}"
    if res.exit_code == 0:
        if fam.json:
            try:
                _strict_json(res.stdout)
            except ValueError as e:
                return f"exit 0 but invalid JSON: {str(e)[:100]}"
        return None
    if res.exit_code != 2:
        return f"exit {res.exit_code}: {stderr.strip()[:160]}"
    lines = [ln for ln in stderr.splitlines() if ln.startswith("error:")]
    if "Usage:" in stderr or len(lines) != 1:
        return f"not one error line: {stderr.strip()[:160]!r}"
    if not any(n in lines[0] for n in (inp.name, target.name, *fam.also_names)):
        return f"error does not name the file: {lines[0][:160]}"
    if out.exists() and any(out.iterdir()):
        return f"partial output left: {sorted(p.name for p in out.iterdir())}"
    return None


_SEEDS: dict[tuple[str, str], Path] = {}


def prepare(seeds: Path, name: str) -> Path:
    """Build the family's seed once per campaign folder; the seed input's path."""
    key = (str(seeds), name)
    if key not in _SEEDS:
        folder = seeds / name
        folder.mkdir(parents=True)
        _SEEDS[key] = FAMILIES[name].build(folder)
    return _SEEDS[key]


def run_one(seeds: Path, work: Path, name: str, mutator: str, index: int) -> Outcome:
    from click.testing import CliRunner

    from ibiscape_eval.cli.main import cli

    fam = FAMILIES[name]
    seed = prepare(seeds, name)
    mdir = work / f"{name}-{index:03d}-{mutator}"
    shutil.copytree(seed.parent, mdir, symlinks=True)
    inp = mdir / seed.name
    target = fam.mutable(inp)
    if mutator in PATH_MUTATORS:
        target = inp
        shutil.rmtree(inp) if inp.is_dir() else inp.unlink()
        PATH_MUTATORS[mutator](inp)
    else:
        rng = np.random.default_rng([SEED, list(FAMILIES).index(name), index])
        target.write_bytes(BYTE_MUTATORS[mutator](target.read_bytes(), rng))
    out = mdir / "out"
    out.mkdir()
    old = signal.signal(signal.SIGALRM, _alarm)
    watchdog = _Watchdog(TIMEOUT_S)
    try:
        res = CliRunner().invoke(cli, fam.argv(inp, out))
        problem = check(fam, res, inp, target, out, mdir)
        code = res.exit_code
    except Hang:
        problem, code = f"hang (> {TIMEOUT_S} s)", None
    finally:
        watchdog.stop()
        signal.signal(signal.SIGALRM, old)
    shutil.rmtree(mdir, ignore_errors=True)
    return Outcome(name, mutator, index, code, problem)


def campaign(root: Path, n_mutants: int = N_MUTANTS) -> Iterator[Outcome]:
    seeds, work = root / "seeds", root / "work"
    work.mkdir(parents=True, exist_ok=True)
    for name, mutator, index in plan(n_mutants):
        yield run_one(seeds, work, name, mutator, index)


def main(argv: list[str]) -> int:
    import tempfile
    import time

    n = int(argv[0]) if argv else N_MUTANTS
    t0 = time.perf_counter()
    broke: list[Outcome] = []
    total = 0
    with tempfile.TemporaryDirectory() as tmp:
        for o in campaign(Path(tmp), n):
            total += 1
            if o.problem:
                broke.append(o)
                print(o, flush=True)
    print(f"{total} mutants, {len(broke)} broke the contract "
          f"({100 * (total - len(broke)) / max(total, 1):.1f} % held) in "
          f"{time.perf_counter() - t0:.1f} s")
    by: dict[str, int] = {}
    for o in broke:
        by[f"{o.family}/{o.mutator}"] = by.get(f"{o.family}/{o.mutator}", 0) + 1
    for k, v in sorted(by.items()):
        print(f"  {k}: {v}")
    return 1 if broke else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
