"""The VIO baseline on the paper's other setups: ESVI (stereo events + IMU) and RGB-D (+ IMU).

    .venv/bin/python examples/vio_setups.py                    # generate small ESVI and RGB-D drives
    .venv/bin/python examples/vio_setups.py ESVI_1 RGBD_1      # sequences you have

Notebook-style: each block can be pasted into a cell.
"""

# %% Imports
import sys
import tempfile
from pathlib import Path

import numpy as np

from ibiscape_eval import open_sequence
from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.metrics import ate
from ibiscape_eval.sim import generate, preset
from ibiscape_eval.sim.config import with_resolution
from ibiscape_eval.vio import run_vio
from ibiscape_eval.vio.depth import DepthOptions, DepthReader, depth_sigma_m
from ibiscape_eval.vio.events_input import EsviOptions, event_stereo_frames
from ibiscape_eval.vio.inputs import resolve_setup

# %% Sequences: the ones given, or two 6 s drives rendered at a low resolution (a minute or two)
if len(sys.argv) > 1:
    folders = [Path(a) for a in sys.argv[1:]]
else:
    root = Path(tempfile.mkdtemp(prefix="vio_setups_"))
    folders = []
    for setup in ("esvi", "rgbd"):
        out = root / f"{setup.upper()}_1_town"
        generate(with_resolution(preset(setup, "slam", "clear", duration_s=6.0, seed=3), 160, 120),
                 out, render=True)
        folders.append(out)

# %% Run each with the cameras of its setup (auto: davis pair -> esvi, rgb + depth -> rgbd)
for folder in folders:
    seq = open_sequence(folder)
    setup = resolve_setup(seq)
    res = run_vio(seq)  # setup="auto"; or setup="esvi" / "rgbd" / "full"
    s = res.stats
    print(f"{folder.name}: {setup}, {s.usable_frames}/{s.frames} usable frames, "
          f"{len(s.failures)} failure spans {[(f.kind, round(f.duration_s, 2)) for f in s.failures]}")
    gt = seq.ground_truth()
    if gt is not None:
        a = ate(res.trajectory, gt, align="yaw", max_diff_s=0.02)
        length = float(a.ref.path_length_m()[-1])
        print(f"  ATE {a.translation_m.rmse:.3f} m over {length:.1f} m "
              f"({100 * a.translation_m.rmse / length:.2f} %)")

# %% ESVI: another reconstruction of the event frames (the default: signed accumulation per window)
esvi = [f for f in folders if resolve_setup(open_sequence(f)) == "esvi"]
if esvi:
    seq = open_sequence(esvi[0])
    res = run_vio(seq, options=EsviOptions("log-intensity", tau_s=0.03))
    print(f"log-intensity (30 ms): {res.stats.usable_frames}/{res.stats.frames} usable frames")
    # the frames themselves, e.g. to look at one
    stamps, read_pair, labels = event_stereo_frames(seq, "davisL", "davisR", EsviOptions())
    left, right = read_pair(0)
    print(f"{len(stamps)} stereo event frames of {left.shape[1]}x{left.shape[0]} px")

# %% RGB-D: the virtual stereo baseline of the depth measurement
rgbd = [f for f in folders if resolve_setup(open_sequence(f)) == "rgbd"]
if rgbd:
    res = run_vio(open_sequence(rgbd[0]), options=DepthOptions(baseline_m=0.5, max_depth_m=30.0))
    print(f"RGB-D, 0.5 m virtual baseline, depth <= 30 m: {res}")

# %% Depth files of real sensors: the reader's units (mm: IBISCape's depth/mm/, Redwood, ORB-SLAM3's
# DepthMapFactor 1000; tum: the TUM RGB-D recordings, 5000 per metre; carla-log: CARLA's 8-bit log)
tum = Path(__file__).resolve().parents[1] / "tests" / "data" / "real" / "tum_rgbd_depth" / "TUM_depth.png"
if tum.is_file():
    kinect = CameraModel(640, 480, 517.3, 516.5, 318.6, 255.3)  # TUM freiburg1
    z = DepthReader([tum], "tum", kinect, np.eye(4), kinect, np.eye(4))(0)  # metres, NaN = none
    print(f"TUM depth frame: median {np.nanmedian(z):.2f} m, {np.isfinite(z).mean():.0%} of the "
          f"pixels; Kinect noise at 3 m {1e3 * depth_sigma_m(np.array([3.0]), 'tum')[0]:.0f} mm")

# %% The depth unit checked by physics: the RGB-D odometry's path against the IMU's from a
# standstill (a TUM file read as millimetres is 5x too far; run_vio refuses it with the unit to
# give, DepthOptions(depth_unit="tum") / --depth-unit tum)
if rgbd:
    from ibiscape_eval.vio.inputs import stereo_inputs
    from ibiscape_eval.vio.scale_check import measure_depth_scale

    seq = stereo_inputs(open_sequence(rgbd[0]), setup="rgbd")
    for scale in (1.0, 5.0):
        r = measure_depth_scale(seq, scale=scale)
        print(f"depth x{scale:g}: {r.status}, factor {r.factor:.2f} (sigma of ln {r.sigma_log:.2f}, "
              f"{r.start_s:.1f}-{r.end_s:.1f} s)")
