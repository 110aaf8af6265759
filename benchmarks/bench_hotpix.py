"""Hot-pixel counting and filtering: ibiscape-eval's numba kernels against the plain numpy
bincount-and-mask baseline, in the same run: on one thread (best CPU time) and with
``threads=2`` (wall time, best and median, with the load average: the machine may be shared;
and the CPU time over both threads), with the peak memory each step adds over the events
already in memory.  The filter both into new arrays and in place (``filter_arrays(...,
inplace=True)`` on copies of the events, made outside the timing; one pass on one or two
threads, returning views of the kept events wherever they lie in the arrays, checked equal to
numpy's on one and two threads before the timing).  Then ``ibiscape-eval
hotpix`` streaming an IBISCape DVS folder from disk (count + write the filtered folder), its
wall time and peak memory.

Run::

    .venv/bin/python benchmarks/bench_hotpix.py                       # 5e7 in memory, 1e7 streamed
    .venv/bin/python benchmarks/bench_hotpix.py --n-events 1e8 --stream-events 1e9 --tmp /tmp
    .venv/bin/python benchmarks/bench_hotpix.py --against /tmp/main --repeat 7   # before / after

(``git worktree add --detach /tmp/main main`` makes that checkout; its ``hotpix.py`` and
``_kernels.py`` run beside ours, every run interleaved.)

The streamed folder is generated with the synthetic builder under ``--tmp`` (~13 bytes per
event on disk, twice: input and filtered output) and deleted afterwards.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _runner import run

from ibiscape_eval.core.events import Events
from ibiscape_eval.events import (
    count_events,
    filter_events,
    hot_pixels_from_counts,
    synthetic_windows,
)

SENSOR = (1024, 1024)  # IBISCape's DVS resolution


def _rss_bytes() -> int:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def peak_added_mb(fn: Callable[..., object], setup: Callable[[], Any] | None = None) -> float:
    """Peak resident memory added while ``fn`` runs (its result included), MB, sampled every
    millisecond by a thread (the kernels release the GIL); ``setup()``'s result, made before,
    is not counted."""
    import gc
    import threading

    arg = () if setup is None else (setup(),)
    gc.collect()
    try:  # hand memory freed by earlier runs back to the OS, or reusing it hides the peak
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except OSError:
        pass
    base = _rss_bytes()
    peak = [base]
    done = threading.Event()

    def sample() -> None:
        while not done.is_set():
            peak[0] = max(peak[0], _rss_bytes())
            time.sleep(0.001)

    th = threading.Thread(target=sample)
    th.start()
    out = fn(*arg)
    peak[0] = max(peak[0], _rss_bytes())
    done.set()
    th.join()
    del out, arg
    return (peak[0] - base) / 1e6


def make_stream(n_events: int, seed: int = 0) -> tuple[Events, np.ndarray]:
    rate = 1e7  # events per second, as in the paper's recordings
    hot, windows = synthetic_windows(
        sensor_size=SENSOR, duration_s=n_events / rate, window_s=0.05, edge_rate_hz=0.9 * rate,
        noise_rate_hz=0.02 * rate / (SENSOR[0] * SENSOR[1]), n_hot=200,
        hot_rate_hz=0.08 * rate / 200, seed=seed,
    )
    parts = [e for _, _, e in windows]
    return Events.concatenate(parts), hot


def _steps(ev: Events, hot: np.ndarray, m: Any) -> list[tuple[str, Callable[..., object], Callable[..., object], bool]]:
    """(name, numpy, ours(threads, [copies]), in place) of every measured step; ``m`` is the
    hot-pixel module measured (this checkout's, or another's: see ``--against``)."""
    w, h = SENSOR
    x, y, t, p = ev.x, ev.y, ev.t_ns, ev.p
    hot_bool = np.zeros(w * h, bool)
    hot_bool[hot[:, 1] * w + hot[:, 0]] = True

    def np_count(*_: object) -> np.ndarray:
        return np.bincount(y.astype(np.int64) * w + x, minlength=w * h)

    def np_mask() -> np.ndarray:
        return ~hot_bool[y.astype(np.int64) * w + x]

    def np_filter(*_: object) -> tuple[np.ndarray, ...]:
        keep = np_mask()
        return t[keep], x[keep], y[keep], p[keep]

    def np_both(*_: object) -> object:
        np_count()
        return np_filter()

    def ib_both(th: int) -> object:
        m.count_events(x, y, sensor_size=SENSOR, threads=th)
        return m.filter_events(ev, hot, sensor_size=SENSOR, threads=th)

    def ib_inplace(th: int, cols: list[np.ndarray]) -> object:
        tc, xc, yc, pc = cols
        return m.filter_arrays(tc, xc, yc, pc, hot, sensor_size=SENSOR, threads=th, inplace=True)

    def ib_both_inplace(th: int, cols: list[np.ndarray]) -> object:
        m.count_events(cols[1], cols[2], sensor_size=SENSOR, threads=th)
        return ib_inplace(th, cols)

    return [
        ("count (per-pixel histogram)", np_count,
         lambda th: m.count_events(x, y, sensor_size=SENSOR, threads=th), False),
        ("keep-mask", np_mask, lambda th: m.hot_pixel_mask(x, y, hot, sensor_size=SENSOR, threads=th), False),
        ("filter, new arrays", np_filter, lambda th: m.filter_events(ev, hot, sensor_size=SENSOR, threads=th),
         False),
        ("filter in place (inplace=True)", np_filter, ib_inplace, True),
        ("count + filter, new arrays", np_both, ib_both, False),
        ("count + filter in place", np_both, ib_both_inplace, True),
    ]


def _check_same(ev: Events, hot: np.ndarray, steps: list[Any]) -> None:
    """Our counts, mask and kept events (new arrays and in place) are numpy's."""
    by = {name: (a, b) for name, a, b, _ in steps}
    np_count, ib_count = by["count (per-pixel histogram)"]
    assert np.array_equal(np_count(), ib_count(1).ravel())
    np_mask, ib_mask = by["keep-mask"]
    assert np.array_equal(np_mask(), ib_mask(2))
    want = by["filter, new arrays"][0]()
    for th in (1, 2):
        fe = by["filter, new arrays"][1](th)
        got = by["filter in place (inplace=True)"][1](th, [a.copy() for a in (ev.t_ns, ev.x, ev.y, ev.p)])
        for a, b, c in zip((fe.t_ns, fe.x, fe.y, fe.p), got, want, strict=True):
            assert np.array_equal(a, c) and np.array_equal(b, c)


def interleaved(fns: list[Callable[..., object]], repeat: int,
                setup: Callable[[], Any] | None = None) -> list[tuple[float, float, float]]:
    """Best CPU time, best and median wall time of ``repeat`` runs of every function of ``fns``
    after a warm-up round, run in turn round by round (a busy machine slows them alike); with
    ``setup``, each run is ``fn(setup())`` and the setup is not timed."""
    times: list[list[tuple[float, float]]] = [[] for _ in fns]
    for r in range(repeat + 1):  # round 0 warms up
        for f, out in zip(fns, times, strict=True):
            arg = () if setup is None else (setup(),)
            t0, w0 = time.process_time(), time.perf_counter()
            f(*arg)
            if r:
                out.append((time.process_time() - t0, time.perf_counter() - w0))
    res = []
    for out in times:
        cpu, wall = zip(*out, strict=True)
        res.append((min(cpu), min(wall), float(np.median(wall))))
    return res


def in_memory(n_events: int, repeat: int, before: Any = None) -> None:
    from functools import partial

    from ibiscape_eval.events import hotpix

    t0 = time.process_time()
    ev, planted = make_stream(n_events)
    n = len(ev)
    print(f"in memory: {n:,} events on a {SENSOR[0]}x{SENSOR[1]} sensor "
          f"(generated in {time.process_time() - t0:.1f} s), {repeat} runs after a warm-up")
    cols = (ev.t_ns, ev.x, ev.y, ev.p)
    ev_mb = sum(a.nbytes for a in cols) / 1e6
    hot = hot_pixels_from_counts(count_events(ev.x, ev.y, sensor_size=SENSOR), top_n=200).pixels
    mods = [("ours", hotpix)] + ([("before", before)] if before is not None else [])
    all_steps = {who: _steps(ev, hot, m) for who, m in mods}
    for steps in all_steps.values():
        _check_same(ev, hot, steps)
    kept = len(filter_events(ev, hot, sensor_size=SENSOR))
    print(f"  planted hot pixels found by top-200: {len({tuple(r) for r in planted} & {tuple(r) for r in hot})}/200; "
          f"discarded {100 * (1 - kept / n):.2f} %; the same counts, mask and kept events as numpy"
          + (" (before too)" if before is not None else ""))
    threads = 2
    print(f"  Mev/s: numpy and ours on one thread by best CPU time; on threads={threads} by wall time, best / "
          f"median (load average {os.getloadavg()[0]:.1f}: on a shared machine only CPU times are stable), and "
          f"by CPU time over the threads (events / CPU s x {threads}: the wall time of a quiet machine at perfect "
          f"scaling); RATIO = numpy's time / ours (CPU, one thread); peak MB added over the {ev_mb:.0f} MB of "
          "events (in place: over their copies)" + ("; 'before' = --against, every run interleaved with ours"
                                                    if before is not None else ""))
    print(f"  {'step':31s} {'who':6s} {'numpy':>6s} {'1T':>6s} {'RATIO':>6s} {f'{threads}T wall best/med':>17s} "
          f"{f'{threads}T CPU':>7s} {'peak MB numpy/1T/' + str(threads) + 'T':>22s}")

    def copies() -> list[np.ndarray]:
        return [a.copy() for a in cols]

    for k, (name, a, _, inplace) in enumerate(all_steps["ours"]):
        setup = copies if inplace else None
        fns = [a] + [partial(all_steps[who][k][2], th) for th in (1, threads) for who, _ in mods]
        res = interleaved(fns, repeat, setup)
        ta = res[0][0]
        pa = peak_added_mb(a, setup)
        for q, (who, _) in enumerate(mods):
            tb = res[1 + q][0]
            cb, wb, mb = res[1 + len(mods) + q]
            pb, pc = (peak_added_mb(partial(all_steps[who][k][2], th), setup) for th in (1, threads))
            print(f"  {name if not q else '':31s} {who:6s} {n / ta / 1e6:6.0f} {n / tb / 1e6:6.0f} {ta / tb:5.1f}x "
                  f"{n / wb / 1e6:8.0f} / {n / mb / 1e6:4.0f} {threads * n / cb / 1e6:7.0f} {pa:10.0f}/{pb:.0f}/{pc:.0f}")
    print(f"  (load average at the end {os.getloadavg()[0]:.1f})")
    roofline(n, cols, repeat, threads)


def roofline(n: int, cols: tuple[np.ndarray, ...], repeat: int, threads: int) -> None:
    """The machine's memory speed on the same bytes: numpy copying every column (what a filter
    that keeps everything must do), into existing and into new arrays, on one thread (CPU time)
    and split over ``threads`` Python threads (wall time, and CPU time over the threads; numpy
    releases the GIL while copying; into new arrays each thread first-touches its part)."""
    from concurrent.futures import ThreadPoolExecutor

    into = [np.empty_like(a) for a in cols]
    nbytes = sum(a.itemsize for a in cols)

    def copy_into(parts: int = 1, k: int = 0, dst: list[np.ndarray] = into) -> None:
        for o, a in zip(dst, cols, strict=True):
            m = a.shape[0]
            np.copyto(o[m * k // parts : m * (k + 1) // parts], a[m * k // parts : m * (k + 1) // parts])

    def copy_new() -> list[np.ndarray]:
        return [a.copy() for a in cols]

    pool = ThreadPoolExecutor(threads)

    def copy_into_threads() -> None:
        list(pool.map(lambda k: copy_into(threads, k), range(threads)))

    def copy_new_threads() -> list[np.ndarray]:
        dst = [np.empty_like(a) for a in cols]
        list(pool.map(lambda k: copy_into(threads, k, dst), range(threads)))
        return dst

    (c1, _, _), (c2, _, _), (ci, wi, _), (cn, wn, _) = interleaved(
        [copy_into, copy_new, copy_into_threads, copy_new_threads], repeat)
    pool.shutdown()
    print(f"  roofline: numpy copying t, x, y, p ({nbytes} B/event), Mev/s: into existing arrays "
          f"{n / c1 / 1e6:.0f} ({n * nbytes / c1 / 1e9:.1f} GB/s) on one thread, {n / wi / 1e6:.0f} wall / "
          f"{threads * n / ci / 1e6:.0f} CPU on {threads} threads; into new arrays {n / c2 / 1e6:.0f} on one "
          f"thread, {n / wn / 1e6:.0f} wall / {threads * n / cn / 1e6:.0f} CPU on {threads} threads")


def _load_against(root: Path) -> object:
    """The hot-pixel module of another checkout (``root/ibiscape_eval/events``), imported as a
    package of its own (its ``_kernels`` beside it) from a temporary copy."""
    import importlib

    pkg = Path(tempfile.mkdtemp(prefix="bench_hotpix_against_")) / "hotpix_against"
    pkg.mkdir()
    for name in ("hotpix.py", "_kernels.py"):
        shutil.copy(root / "ibiscape_eval" / "events" / name, pkg / name)
    (pkg / "__init__.py").write_text("")
    sys.path.insert(0, str(pkg.parent))
    return importlib.import_module("hotpix_against.hotpix")


def streamed(n_events: int, tmp_root: Path) -> None:
    from ibiscape_eval.io.events import _Writer

    usage = shutil.disk_usage(tmp_root)
    need = int(n_events * 13 * 2.1)
    if usage.free < need:
        n_fit = int(usage.free / (13 * 2.2))
        print(f"streaming: only {usage.free / 1e9:.1f} GB free under {tmp_root}, {need / 1e9:.1f} GB "
              f"needed; using {n_fit:,} events instead of {n_events:,}")
        n_events = n_fit
    work = Path(tempfile.mkdtemp(prefix="bench_hotpix_", dir=tmp_root))
    try:
        src = work / "davisL"
        t0 = time.perf_counter()
        rate = 1e7
        # a pool of 40 generated 50 ms windows (2 s), replayed with shifted timestamps: the
        # same statistics as generating every window, at disk speed
        pool_n = 40
        _, windows = synthetic_windows(
            sensor_size=SENSOR, duration_s=pool_n * 0.05, window_s=0.05, edge_rate_hz=0.9 * rate,
            noise_rate_hz=0.02 * rate / (SENSOR[0] * SENSOR[1]), n_hot=200,
            hot_rate_hz=0.08 * rate / 200, seed=1,
        )
        pool = list(windows)
        n_win = max(1, round(n_events / rate / 0.05))
        span = pool[-1][1] - pool[0][0]
        wr = _Writer(src, "ibiscape", None)
        for k in range(n_win):
            a, b, e = pool[k % pool_n]
            shift = (k // pool_n) * span
            wr.add(Events(e.t_ns + shift, e.x, e.y, e.p), (a + shift, b + shift, Path(f"{a + shift}.npz")))
        wr.commit()
        size_gb = sum(f.stat().st_size for f in (src / "events").iterdir()) / 1e9
        print(f"streaming: {wr.n:,} events in {len(list((src / 'events').iterdir()))} windows, "
              f"{size_gb:.1f} GB (written in {time.perf_counter() - t0:.0f} s)")
        exe = str(Path(sys.executable).with_name("ibiscape-eval"))
        r = run([exe, "hotpix", str(src), "--sensor-size", f"{SENSOR[0]}x{SENSOR[1]}",
                 "--n-sigma", "5", "--filtered-out", str(work / "davisL_filtered"), "--json"])
        if not r.ok:
            print(f"  hotpix failed with exit {r.returncode}")
            return
        import json

        doc = json.loads(r.stdout)
        print(f"  {'command':40s} {'wall s':>8s} {'Mev/s':>7s} {'peak RSS MB':>12s} {'data GB':>8s}")
        print(f"  {'hotpix (count + filtered folder)':40s} {r.wall_s:8.1f} "
              f"{wr.n / r.wall_s / 1e6:7.1f} {r.peak_mb:12.0f} {size_gb:8.1f}")
        print(f"  hot pixels {doc['n_hot_pixels']}, discarded {100 * doc['fraction_discarded']:.2f} %; "
              f"peak memory / data size = {r.peak_mb / 1e3 / size_gb:.3f}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n-events", type=float, default=5e7, help="in-memory stream size (0: skip)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--stream-events", type=float, default=1e7, help="streamed folder size (0: skip)")
    ap.add_argument("--tmp", type=Path, default=Path(tempfile.gettempdir()))
    ap.add_argument("--against", type=Path, default=None,
                    help="another checkout: its rows ('before') beside ours in the in-memory table, every run "
                         "interleaved with ours")
    a = ap.parse_args()
    if a.n_events > 0:
        in_memory(int(a.n_events), a.repeat, None if a.against is None else _load_against(a.against))
    if a.stream_events > 0:
        streamed(int(a.stream_events), a.tmp)


if __name__ == "__main__":
    main()
