"""Simulated DVS events in dynamic weather, and the hot pixels rain and fog leave behind
(notebook-style; well under a minute).

A stereo-like DVS camera watches a moving texture (the renderer's output can replace it: any
``render_gray(t_ns) -> (H, W) float32`` 0..255 works) through the IBISCape paper's "dynamic"
weather (rain ~45 %, fog ~70 %).  The ESIM/CARLA event model turns log-intensity changes into
events, rendering adaptively between the 20 Hz camera frames; rain and fog add spurious events on
a few "noisy" pixels, about a quarter of all events as in the paper's FULL Dynamic-1.  Then
``ibiscape-eval hotpix``'s detector (mean + 5 std, dvs_tools' default) finds those pixels, checked
against the list the simulator recorded.

Run: ``.venv/bin/python examples/dvs_events.py [--out DIR]``.  From the shell, on a generated
ESVI/Full sequence::

    ibiscape-eval hotpix ESVI_1_town/davisL --n-sigma 5 --hot-out hot_pixels.txt
"""

# %%
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from ibiscape_eval.events import detect_hot_pixels
from ibiscape_eval.io.events import read_events
from ibiscape_eval.sim import preset
from ibiscape_eval.sim.config import CameraSpec
from ibiscape_eval.sim.dvs import DvsConfig, write_dvs_camera
from ibiscape_eval.sim.dvs.scenes import translating_texture
from ibiscape_eval.sim.weather import simulate_weather

ap = argparse.ArgumentParser(description=__doc__)
ap.add_argument("--out", type=Path, default=Path(tempfile.mkdtemp(prefix="dvs_demo_")))
ap.add_argument("--size", type=int, default=256, help="sensor width = height [px]")
ap.add_argument("--duration", type=float, default=2.0, help="seconds")
args, _ = ap.parse_known_args()
out: Path = args.out
out.mkdir(parents=True, exist_ok=True)

# %% 1. Camera, frame stamps (20 Hz windows) and the dynamic weather over them
cam = CameraSpec(name="davisL", kind="dvs", width_px=args.size, height_px=args.size,
                 position_m=(0.0, 0.1, 2.8), mount="davisL")
t0 = 1_000_000_000_000
stamps = t0 + 50_000_000 * np.arange(round(args.duration * 20) + 1, dtype=np.int64)
weather = simulate_weather(preset("esvi", "slam", "dynamic").weather_model, stamps, seed=1)
print(f"rain {weather.column('precipitation').mean():.0f} %, fog "
      f"{weather.column('fog_density').mean():.0f} % on average")

# %% 2. Events: CARLA's DVS parameters (C = 0.3, sigma 0, no refractory period), adaptive renders
scene = translating_texture((args.size, args.size), t0, speed_px_s=90.0, seed=3)
res = write_dvs_camera(scene, cam, stamps, out / "davisL", dvs_config=DvsConfig(),
                       weather=weather, rng=np.random.default_rng(7))
print(res)
print(f"{res.n_renders} internal renders for {res.n_windows} windows of 50 ms; "
      f"{100 * res.noise_fraction:.1f} % of the events come from rain and fog")

# %% 3. Hot pixels as the paper removes them (n_sigma = 5), against the simulator's list
ev = read_events(out / "davisL")
found = detect_hot_pixels(ev.x, ev.y, sensor_size=(args.size, args.size))
truth = {tuple(p) for p in res.noisy_pixels}
hits = {tuple(map(int, p)) for p in found.pixels} & truth
print(f"hot pixels: {len(found.pixels)} found, {len(truth)} made noisy; precision "
      f"{len(hits) / max(len(found.pixels), 1):.3f}, recall {len(hits) / max(len(truth), 1):.3f}; "
      f"{100 * found.fraction_discarded:.1f} % of the events discarded (paper: 26.39 %)")
print(f"outputs in {out}: davisL/events/<ns>.npz, davisL/timestamps.csv, davisL/frames/<ns>.png")

# %% 4. The same events in the files people have (AEDAT4 as DV writes it, DSEC-layout HDF5, a
# ROS 1 bag of dvs_msgs/EventArray): every file reads back the same stream and the same hot pixels;
# the sensor size travels with the file.  Then a real DVXplorer recording (tonic's test sample).
from ibiscape_eval.core.events import Events
from ibiscape_eval.io.events import open_events, write_events

ev_us = Events(ev.t_ns // 1000 * 1000, ev.x, ev.y, ev.p)  # AEDAT4 and HDF5 hold microseconds
for name, fmt in (("davisL.aedat4", "aedat4"), ("davisL.h5", "hdf5"), ("davisL.bag", "bag")):
    write_events(out / name, ev_us, fmt=fmt, sensor_size=(args.size, args.size))
    src = open_events(out / name)
    back = read_events(out / name)
    again = detect_hot_pixels(back.x, back.y, sensor_size=src.sensor_size)
    same = np.array_equal(back.t_ns, ev_us.t_ns) and np.array_equal(again.pixels, found.pixels)
    print(f"{name:14s} {src.fmt:7s} sensor {src.sensor_size} (from {src.size_from}); "
          f"same events and hot pixels: {same}")

real = Path(__file__).resolve().parents[1] / "tests" / "data" / "real" / "tonic_dvxplorer" / "sample.aedat4"
if real.is_file():
    src = open_events(real)
    dvx = read_events(real)
    hot = detect_hot_pixels(dvx.x, dvx.y, sensor_size=src.sensor_size, top_n=5)
    print(f"real DVXplorer file: {len(dvx):,} events, {src.sensor_size[0]}x{src.sensor_size[1]} from "
          f"the stream table (streams {src.meta['streams']}); 5 busiest pixels: "
          f"{[tuple(map(int, p)) for p in hot.pixels]}")
