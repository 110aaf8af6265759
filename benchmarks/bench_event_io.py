"""Event files through ``hotpix``: read-and-count speed and peak memory for AEDAT4 (the ``aedat``
decoder we use against iniVation's ``dv-processing``), HDF5 (DSEC layout) and our npz path
(an IBISCape DVS folder of ``events/<ns>.npz`` windows), each in a fresh process.

Run::

    .venv/bin/python benchmarks/bench_event_io.py                     # 2e7 events, quick
    nice .venv/bin/python benchmarks/bench_event_io.py --n-events 5e8 # a 30-minute recording

The same events (a 640x480 sensor, ~280 k events/s, 50 planted hot pixels) are written once in
each format under ``--tmp`` (AEDAT4 LZ4-compressed in 4096-event packets as DV writes it, HDF5
uncompressed in the DSEC layout with uint32 stamps after ``t_offset``, npz windows of 2^20
events) and deleted afterwards (about 30 bytes per event in all).  Every row reports wall and
CPU time (user + system, from GNU time: on a shared machine the CPU rate is the stable one),
events/s and peak RSS, net of the start-up (the same command on a 10 k-event copy); the
ratio column is against the npz path.  The decoder rows run the
decoder alone plus our counting kernel, so that the two AEDAT4 libraries are compared on the
same work.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

SENSOR = (640, 480)
GNU_TIME = "/usr/bin/time" if os.path.exists("/usr/bin/time") else shutil.which("time")


def timed(cmd: list[str]) -> tuple[float, float, float, str, int]:
    """(wall s, cpu s, peak RSS MB, stdout, exit status) of ``cmd`` in a fresh process."""
    with tempfile.NamedTemporaryFile(prefix="rss_", suffix=".txt") as f:
        argv = [GNU_TIME, "-q", "-f", "%M %U %S", "-o", f.name, *cmd] if GNU_TIME else cmd
        t0 = time.perf_counter()
        proc = subprocess.run(argv, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        parts = Path(f.name).read_text().split() if GNU_TIME else []
    if len(parts) >= 3:
        rss, cpu = int(parts[-3]) / 1024.0, float(parts[-2]) + float(parts[-1])
    else:
        rss, cpu = float("nan"), float("nan")
    return wall, cpu, rss, proc.stdout, proc.returncode


def generate(work: Path, n: int, seed: int = 0) -> dict[str, Path]:
    import h5py

    from ibiscape_eval.core.events import Events
    from ibiscape_eval.io.dvs_folder import DvsFolderWriter
    from ibiscape_eval.io.event_aedat4 import Aedat4Writer

    rng = np.random.default_rng(seed)
    w, h = SENSOR
    hot = np.stack([rng.integers(0, w, 50), rng.integers(0, h, 50)], axis=1)
    paths = {"aedat4": work / "rec.aedat4", "hdf5": work / "rec.h5", "npz": work / "davisL"}
    aw = Aedat4Writer(paths["aedat4"], SENSOR, compression="lz4", events_per_packet=4096,
                      source="DVXplorer_bench")
    fw = DvsFolderWriter(paths["npz"], frames=False)
    t0_us = 1_700_000_000_000_000
    step = 1 << 20
    with h5py.File(paths["hdf5"], "w") as f:
        ds = {k: f.create_dataset(f"events/{k}", shape=(n,), dtype=dt, chunks=(min(n, 1 << 18),))
              for k, dt in (("t", np.uint32), ("x", np.uint16), ("y", np.uint16), ("p", np.uint8))}
        f.create_dataset("t_offset", data=np.int64(t0_us))
        f.attrs["width"], f.attrs["height"] = SENSOR
        last = end = 0
        for s in range(0, n, step):
            k = min(n, s + step) - s
            rel = last + np.cumsum(rng.integers(0, 8, k))  # ~3.5 us apart: 280 k events/s
            last = int(rel[-1])
            x = rng.integers(0, w, k).astype(np.uint16)
            y = rng.integers(0, h, k).astype(np.uint16)
            sel = rng.random(k) < 0.02
            pick = rng.integers(0, len(hot), int(sel.sum()))
            x[sel], y[sel] = hot[pick, 0], hot[pick, 1]
            p = rng.random(k) < 0.5
            ds["t"][s:s + k], ds["x"][s:s + k], ds["y"][s:s + k], ds["p"][s:s + k] = rel, x, y, p
            ev = Events((rel.astype(np.int64) + t0_us) * 1000, x, y, p)
            aw.add(ev)
            start = int(ev.t_ns[0]) if s == 0 else end
            end = int(ev.t_ns[-1]) + 1
            fw.add(start, end, ev, None)
    aw.close()
    fw.close()
    return paths


DECODERS = {
    "aedat": """
import sys, aedat, numpy as np
from ibiscape_eval.events import _kernels
w, h = {w}, {h}; acc = np.zeros(h * (w + 16), np.uint32); n = 0
for pk in aedat.Decoder(sys.argv[1]):
    if "events" in pk:
        e = pk["events"]; n += len(e)
        _kernels.count_xy(e["x"], e["y"], w, h, w + 16, acc)
print(n, int(acc.sum()))
""",
    "dv-processing": """
import sys, dv_processing as dv, numpy as np
from ibiscape_eval.events import _kernels
w, h = {w}, {h}; acc = np.zeros(h * (w + 16), np.uint32); n = 0
rec = dv.io.MonoCameraRecording(sys.argv[1])
while (b := rec.getNextEventBatch()) is not None:
    e = b.numpy(); n += len(e)
    _kernels.count_xy(e["x"].astype(np.uint16), e["y"].astype(np.uint16), w, h, w + 16, acc)
print(n, int(acc.sum()))
""",
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n-events", type=float, default=2e7)
    ap.add_argument("--tmp", type=Path, default=Path(tempfile.gettempdir()))
    a = ap.parse_args()
    n = int(a.n_events)
    need = n * 32
    free = shutil.disk_usage(a.tmp).free
    if free < need * 1.2:
        sys.exit(f"{a.tmp}: {free / 1e9:.1f} GB free, {need / 1e9:.1f} GB needed")
    work = Path(tempfile.mkdtemp(prefix="bench_event_io_", dir=a.tmp))
    py = sys.executable
    exe = str(Path(py).with_name("ibiscape-eval"))
    try:
        t0 = time.perf_counter()
        (work / "tiny").mkdir()
        tiny = generate(work / "tiny", 10_000, seed=1)  # start-up cost (imports, numba cache)
        paths = generate(work, n)
        sizes = {k: (sum(f.stat().st_size for f in p.rglob("*")) if p.is_dir() else p.stat().st_size) / 1e9
                 for k, p in paths.items()}
        print(f"{n:,} events ({n / 280e3 / 60:.0f} min at 280 k ev/s) on {SENSOR[0]}x{SENSOR[1]}, "
              f"written in {time.perf_counter() - t0:.0f} s: "
              + ", ".join(f"{k} {v:.2f} GB" for k, v in sizes.items()))
        rows = []

        def net(cmd: list[str], small: list[str]) -> tuple[float, float, float, str, int]:
            """Times of ``cmd`` minus those of the same command on the 10 k-event files."""
            wall0, cpu0, _, _, _ = timed(small)
            wall, cpu, rss, out, rc = timed(cmd)
            return wall - wall0, cpu - cpu0, rss, out, rc

        for fmt in ("npz", "hdf5", "aedat4"):
            args = ["hotpix", "--top-n", "50", "--json"]
            wall, cpu, rss, out, rc = net([exe, *args, str(paths[fmt])], [exe, *args, str(tiny[fmt])])
            if rc != 0:
                print(f"hotpix on {fmt} failed ({rc})")
                continue
            doc = json.loads(out)
            assert doc["n_events"] == n, doc["n_events"]
            rows.append((f"hotpix {fmt}" + (" (aedat)" if fmt == "aedat4" else ""), wall, cpu, rss))
        for name, code in DECODERS.items():
            script = work / f"dec_{name}.py"
            script.write_text(code.format(w=SENSOR[0], h=SENSOR[1]))
            wall, cpu, rss, out, rc = net([py, str(script), str(paths["aedat4"])],
                                          [py, str(script), str(tiny["aedat4"])])
            if rc != 0:
                print(f"decoder {name}: not available (exit {rc})")
                continue
            assert out.split()[0] == str(n), out
            rows.append((f"AEDAT4 decode+count: {name}", wall, cpu, rss))
        base = next((r for r in rows if r[0] == "hotpix npz"), None)
        print(f"  {'step':34s} {'wall s':>7s} {'cpu s':>7s} {'Mev/s wall':>11s} {'Mev/s cpu':>10s} "
              f"{'peak RSS MB':>12s} {'RATIO (cpu, vs npz)':>20s}")
        for name, wall, cpu, rss in rows:
            ratio = f"{base[2] / cpu:19.2f}x" if base else ""
            print(f"  {name:34s} {wall:7.1f} {cpu:7.1f} {n / wall / 1e6:11.1f} {n / cpu / 1e6:10.1f} "
                  f"{rss:12.0f} {ratio}")
        dec = {r[0].split(": ")[1]: r[2] for r in rows if r[0].startswith("AEDAT4")}
        if len(dec) == 2:
            print(f"  aedat vs dv-processing (cpu): {dec['dv-processing'] / dec['aedat']:.2f}x")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
