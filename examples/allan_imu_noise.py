"""Allan deviation of a still IMU with known noise: generate, analyse, compare, plot.

Run:  .venv/bin/python examples/allan_imu_noise.py   (about half a minute; writes allan_example.png)

The gyro gets CARLA's per-sample sigma 0.004 rad/s at 200 Hz, i.e. a density of
0.004 / sqrt(200) = 2.83e-4 rad/s/sqrt(Hz); the random walks are the values the IBISCape paper's
calibration tool reported (its table ``imuvalues``), so that we can see whether they are recoverable.
"""

# %% generate 3 hours of still IMU at 100 Hz (gyro rad/s, accel m/s^2 with gravity on z)
import math
import os

import numpy as np

from ibiscape_eval import allan_deviation, fit_noise_model
from ibiscape_eval.sim.noise import imu_noise

rate_hz = 100.0
hours = 3.0 * float(os.environ.get("IBISCAPE_EXAMPLE_SCALE", "1"))  # the test suite runs 0.1
N_true = np.array([2.83e-4] * 3 + [0.07 / math.sqrt(200)] * 3)
K_true = np.array([7.0e-4 / 10] * 3 + [1.26e-2 / 10] * 3)
samples = imu_noise(int(hours * 3600 * rate_hz), rate_hz, noise_density=N_true,
                    random_walk=K_true, bias0=[0, 0, 0, 0, 0, 9.81], seed=42)
names = ["w_x", "w_y", "w_z", "a_x", "a_y", "a_z"]

# %% overlapping Allan deviation (exact, equal to allantools.oadev) and the N / K / B fit
res = allan_deviation(samples, rate_hz, names=names)
model = fit_noise_model(res)
print(model.to_frame()[["noise_density", "noise_density_unc", "random_walk", "random_walk_unc",
                        "bias_instability", "discrete_sigma"]].to_string(float_format="%.4g"))

# %% compare with the truth
for a, n, k in zip(model.axes, N_true, K_true, strict=True):
    print(f"{a.name}: N {100 * (a.noise_density / n - 1):+5.1f} %   K {100 * (a.random_walk / k - 1):+5.1f} %"
          f"   (white fit {a.white_range_s[0]:.3g}..{a.white_range_s[1]:.3g} s,"
          f" walk fit {a.walk_range_s[0]:.3g}..{a.walk_range_s[1]:.3g} s)"
          if a.white_range_s and a.walk_range_s else f"{a.name}: {a.notes}")

# %% plot: curves, one-sigma bands, the two fitted lines and their read-off points (N at 1 s,
# K at 3 s, B at the minimum); the result draws itself on a new matplotlib Figure
from ibiscape_eval.io.figure import save_figure

save_figure(res.plot(model), "allan_example.png")
print("wrote allan_example.png")

# %% Notebook-friendly results: a short repr, a table in Jupyter, strict-JSON dicts.
print(res)      # AllanResult(6 axes w_x, ...; taus; samples) - no arrays
print(model)    # one line per axis: N, K, B with uncertainties
print(model.kalibr())  # the usual six axes need no arguments

# %% A short record cannot show the random walk: give an explicit fallback (and inflate).
short = allan_deviation(samples[: int(600 * rate_hz)], rate_hz)
short_model = fit_noise_model(short)
vals, notes = short_model.kalibr_values(random_walk_fallback=(2e-5, 3e-3), inflate=2.0)
print(vals)
print("\n".join(notes))  # what the imu.yaml comments say

# %% Foreign files: columns by header name (any order, units converted), stamps in seconds.
# A phone logger's accelerometer-first CSV in g and deg/s, stamps in decimal seconds:
import tempfile
from pathlib import Path

from ibiscape_eval.io.imu import read_imu

tmp = Path(tempfile.mkdtemp())
n = int(120 * rate_hz)
t_ns = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * int(1e9 / rate_hz)
rows = [f"{t // 10**9}.{t % 10**9:09d}," + ",".join(f"{v:.9g}" for v in (*acc / 9.80665, *np.degrees(gy)))
        for t, gy, acc in zip(t_ns.tolist(), samples[:n, :3], samples[:n, 3:], strict=True)]
(tmp / "phone.csv").write_text("time,acc_x [g],acc_y [g],acc_z [g],gyro_x [deg/s],gyro_y [deg/s],gyro_z [deg/s]\n"
                               + "\n".join(rows) + "\n")
rec = read_imu(tmp / "phone.csv")
print(rec.layout)      # which column is which, the stamp unit and how it was decided
print(rec.notes)       # the conversions, one sentence each
assert np.allclose(rec.gyro_rad_s, samples[:n, :3], rtol=1e-6, atol=1e-12)

# %% Stillness: an Allan deviation is only meaningful for an IMU at rest.
from ibiscape_eval.imu import assess_stillness

print(assess_stillness(samples, rate_hz))                       # still: ratio well below 3
moving = samples.copy()
tt = np.arange(len(moving)) / rate_hz
moving[:, 2] += 0.2 * np.sin(2 * np.pi * tt / 20.0)             # a slow turn back and forth
report = assess_stillness(moving, rate_hz)
print(report.still, report.reasons)                             # False, with the numbers
# ibiscape_eval.imu.check_still raises DegenerateInputError instead (unless force=True); the
# allan command prints that one line and exits 2, or with --force marks every output.
