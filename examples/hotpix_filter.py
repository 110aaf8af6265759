"""Hot pixels in a DVS recording: detect, filter, plot (notebook-style; runs in well under a minute).

Builds a synthetic IBISCape-like DVS stream (a moving edge, background activity and a few planted
hot pixels firing at high rates, as rain and fog make CARLA's DVS pixels do), finds the hot pixels
with the IBISCape paper's two criteria, removes their events, and draws the paper's figure
``fig:histo_hot_pixel`` (per-pixel count histograms before/after, log scale) with a heat map.

Run: ``.venv/bin/python examples/hotpix_filter.py [--out DIR]``.  The same from the shell::

    ibiscape-eval hotpix DIR/davisL --n-sigma 5 --hot-out hot_pixels.txt \\
        --filtered-out DIR/davisL_filtered --plot hotpix.png
"""

# %%
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from ibiscape_eval import detect_hot_pixels, hot_pixel_mask, hot_pixels
from ibiscape_eval.events import accumulate_frames, filter_arrays, filter_events, synthetic_events
from ibiscape_eval.events.pipeline import HotPixelCriteria
from ibiscape_eval.io.events import read_events, write_events, write_hot_pixels
from ibiscape_eval.io.figure import save_figure

ap = argparse.ArgumentParser(description=__doc__)
ap.add_argument("--out", type=Path, default=Path(tempfile.mkdtemp(prefix="hotpix_demo_")))
args, _ = ap.parse_known_args()
out: Path = args.out
out.mkdir(parents=True, exist_ok=True)

# %% 1. A synthetic recording: 346x260 DAVIS-like sensor, 2 s, 12 planted hot pixels
sensor = (346, 260)
s = synthetic_events(sensor_size=sensor, duration_s=2.0, edge_rate_hz=1_000_000, noise_rate_hz=2.0,
                     n_hot=12, hot_rate_hz=4000.0, seed=7)
print(f"{len(s.events):,} events; planted hot pixels:\n{s.hot_pixels}")
write_events(out / "davisL", s.events, fmt="ibiscape")  # the IBISCape layout, 50 ms windows

# %% 2. Read it back as one stream and detect: mean + 5 std (dvs_tools' default) and top-N
ev = read_events(out / "davisL")
by_sigma = detect_hot_pixels(ev.x, ev.y, sensor_size=sensor, n_sigma=5)
by_rank = detect_hot_pixels(ev.x, ev.y, sensor_size=sensor, top_n=12)
print(by_sigma.to_frame().head(12))
print(f"threshold {by_sigma.threshold:.0f} events (mean {by_sigma.mean:.1f}, std {by_sigma.std:.1f})")
planted = {tuple(p) for p in s.hot_pixels.tolist()}
print("n-sigma finds the planted set:", {tuple(p) for p in by_sigma.pixels.tolist()} == planted)
print("top-N finds the planted set:  ", {tuple(p) for p in by_rank.pixels.tolist()} == planted)

# %% 3. Filter: the boolean keep-mask for notebooks, or the one-pass compaction
keep = hot_pixel_mask(ev.x, ev.y, by_sigma.pixels, sensor_size=sensor)
clean = filter_events(ev, by_sigma.pixels, sensor_size=sensor)
assert np.array_equal(clean.t_ns, ev.t_ns[keep])
# large streams: threads= splits the work; inplace=True on arrays of your own compacts them
# into themselves (no new arrays, whose first-touch page faults cost as much as the compaction)
t, x, y, p = (a.copy() for a in (ev.t_ns, ev.x, ev.y, ev.p))
t, x, y, p = filter_arrays(t, x, y, p, by_sigma.pixels, sensor_size=sensor, threads=2, inplace=True)
assert np.array_equal(t, clean.t_ns) and np.array_equal(x, clean.x) and np.array_equal(p, clean.p)
print(f"discarded {by_sigma.n_discarded:,} events ({100 * by_sigma.fraction_discarded:.2f} %)")
write_hot_pixels(out / "hot_pixels.txt", by_sigma.pixels)
write_events(out / "davisL_filtered", clean, fmt="ibiscape")

# %% 4. The paper's histogram figure and a sensor heat map; accumulation frames before/after
save_figure(by_sigma.plot(title="synthetic DVS stream with 12 planted hot pixels"), out / "hotpix.png")
before = accumulate_frames(ev, sensor_size=sensor, rate_hz=10, signed=False)
after = accumulate_frames(clean, sensor_size=sensor, rate_hz=10, signed=False)
print(f"frame 0: {int(before.frames[0].sum())} events before, {int(after.frames[0].sum())} after")
print(f"outputs in {out}: davisL/, davisL_filtered/, hot_pixels.txt, hotpix.png")

# %% 5. The whole command in one call, streamed (recordings larger than memory): what
# ``ibiscape-eval hotpix DIR/davisL --n-sigma 5`` runs
run = hot_pixels(out / "davisL", HotPixelCriteria(n_sigma=5))
print(run.result, "sensor size from", run.size_from)
assert {tuple(p) for p in run.result.pixels.tolist()} == {tuple(p) for p in by_sigma.pixels.tolist()}
