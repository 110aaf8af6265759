"""Allan deviation: ibiscape-eval vs allantools.oadev, and the 168-hour streaming case.

    .venv/bin/python benchmarks/bench_allan.py             # both parts (the big one takes minutes)
    .venv/bin/python benchmarks/bench_allan.py --skip-big  # only the allantools comparison

Part 1: 10M samples of one axis, the same 100 log-spaced taus, one run of each; prints times,
the ratio and the largest relative difference of the deviations.
Part 3 (``--coverage``): how honest the reported one-sigma of the bias instability B is on a
record with a real flicker floor (white N + flicker B + random walk K; the generator below), as
the quantiles of |z| = |B_est - B| / sigma_B over seeds: 0.683 and 0.954 for an honest sigma.
Its result is ``BIAS_INSTABILITY_UNC_INFLATION`` in ``ibiscape_eval/imu/fit.py``.
Part 2: 168 h at 200 Hz (121M rows x 6 axes, ~5.8 GB) written by ``sim/noise.py`` into a temporary
folder under /tmp, analysed by ``ibiscape-eval allan`` in a fresh process (wall time and peak RSS
from ``wait4``), then deleted.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _runner import run


def part1(n: int = 10_000_000, rate: float = 200.0) -> None:
    import allantools

    from ibiscape_eval.imu import allan_deviation
    from ibiscape_eval.sim.noise import imu_noise

    y = imu_noise(n, rate, noise_density=0.004 / np.sqrt(rate), random_walk=1e-4, seed=1)[:, 0]
    taus = np.logspace(0, np.log10(n / 4), 100) / rate
    allan_deviation(y[:1000], rate)  # load the compiled kernel once (numba cache)
    t0 = time.perf_counter()
    ours = allan_deviation(y, rate, taus_s=taus)
    t_ours = time.perf_counter() - t0
    t0 = time.perf_counter()
    t_at, ad, _, ns = allantools.oadev(y, rate=rate, data_type="freq", taus=taus)
    t_ref = time.perf_counter() - t0
    same_taus = np.array_equal(t_at, ours.taus_s)
    rel = float(np.max(np.abs(ad / ours.adev[:, 0] - 1.0))) if same_taus else float("nan")
    print(f"\n1) overlapping ADEV, {n / 1e6:.0f}M samples, {taus.size} taus requested "
          f"({ours.taus_s.size} distinct after rounding to the sample grid)")
    print(f"{'tool':<28}{'time [s]':>10}")
    print(f"{'allantools.oadev':<28}{t_ref:>10.2f}")
    print(f"{'ibiscape_eval.allan_deviation':<28}{t_ours:>10.2f}")
    print(f"RATIO allantools / ibiscape-eval: {t_ref / t_ours:.1f}x   "
          f"same taus: {same_taus}   same n: {np.array_equal(ns, ours.n_terms)}   "
          f"max relative difference: {rel:.2e}")


def part2(hours: float = 168.0, rate: float = 200.0) -> None:
    from ibiscape_eval.io.imu import write_imu_npy
    from ibiscape_eval.sim.noise import imu_noise_chunks

    n = int(hours * 3600 * rate)
    N = [2.8e-4, 2.8e-4, 2.8e-4, 5e-3, 5e-3, 5e-3]
    K = [2e-5, 2e-5, 2e-5, 4e-4, 4e-4, 4e-4]
    tmp = Path(tempfile.mkdtemp(prefix="bench-allan-", dir="/tmp"))
    try:
        path = tmp / "still_168h.npy"
        t0 = time.perf_counter()
        write_imu_npy(path, imu_noise_chunks(n, rate, noise_density=N, random_walk=K,
                                             bias0=[0, 0, 0, 0, 0, 9.81], seed=7), width=6)
        t_gen = time.perf_counter() - t0
        size_gb = path.stat().st_size / 1e9
        exe = str(Path(sys.executable).with_name("ibiscape-eval"))
        r = run([exe, "allan", str(path), "--rate-hz", str(rate), "--json"])
        print(f"\n2) streaming: {hours:g} h at {rate:g} Hz = {n / 1e6:.1f}M rows x 6 axes "
              f"(.npy {size_gb:.2f} GB, generated in {t_gen:.0f} s)")
        print(f"{'case':<34}{'time [s]':>10}{'peak RSS [MB]':>15}{'limit':>16}")
        print(f"{'ibiscape-eval allan (.npy)':<34}{r.wall_s:>10.1f}{r.peak_mb:>15.0f}"
              f"{'180 s / 4096 MB':>16}")
        if r.ok:
            doc = json.loads(r.stdout)
            print(f"{'axis':<6}{'N true':>10}{'N est':>11}{'K true':>10}{'K est':>11}")
            for i, (name, a) in enumerate(doc["axes"].items()):
                print(f"{name:<6}{N[i]:>10.3g}{a['noise_density'] or float('nan'):>11.4g}"
                      f"{K[i]:>10.3g}{a['random_walk'] or float('nan'):>11.4g}")
        else:
            print(f"FAILED with exit status {r.returncode}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def flicker_noise(n: int, rate: float, b: float, rng: np.random.Generator) -> np.ndarray:
    """Flicker (1/f) rate noise of bias instability ``b``: one-sided PSD ``b^2 / (pi f)``
    (IEEE Std 952's two-sided ``b^2 / (2 pi f)``), whose Allan deviation is the flat
    ``sqrt(2 ln 2 / pi) b = 0.664 b``; shaped in the frequency domain over 8 n samples, of which
    the first n are kept, so that the floor holds up to a quarter of the record."""
    m = 8 * n
    spec = np.fft.rfft(rng.standard_normal(m))
    f = np.fft.rfftfreq(m, 1.0 / rate)
    gain = np.zeros_like(f)
    gain[1:] = np.sqrt(b**2 / (np.pi * f[1:]) * rate / 2.0)
    return np.fft.irfft(spec * gain, m)[:n]


def part3(seeds: int = 16, hours: float = 2.0, rate: float = 50.0) -> None:
    import ibiscape_eval.imu.fit as fit
    from ibiscape_eval.imu import allan_deviation, fit_noise_model
    from ibiscape_eval.sim.noise import imu_noise

    in_use = fit.BIAS_INSTABILITY_UNC_INFLATION
    n_true, b_true, k_true = 1e-3, 1e-3, 1e-5
    n = int(hours * 3600 * rate)
    z, ratio = [], []
    fit.BIAS_INSTABILITY_UNC_INFLATION = 1.0  # measure the raw sigma
    try:
        for seed in range(seeds):
            rng = np.random.default_rng(seed)
            y = imu_noise(n, rate, noise_density=[n_true] * 6, random_walk=[k_true] * 6,
                          seed=3000 + seed)
            y += np.column_stack([flicker_noise(n, rate, b_true, rng) for _ in range(6)])
            for a in fit_noise_model(allan_deviation(y, rate)).axes:
                if np.isfinite(a.bias_instability):
                    z.append((a.bias_instability - b_true) / a.bias_instability_unc)
                    ratio.append(a.bias_instability / b_true)
    finally:
        fit.BIAS_INSTABILITY_UNC_INFLATION = in_use
    za = np.abs(np.asarray(z))
    q68, q95 = float(np.quantile(za, 0.683)), float(np.quantile(za, 0.954))
    need = max(1.0, q68, q95 / 2.0)
    print(f"\n3) coverage of B: {seeds} seeds x 6 axes, {hours:g} h at {rate:g} Hz, N {n_true:g}, "
          f"B {b_true:g}, K {k_true:g}; B found on {za.size} axes")
    print(f"B_est / B: mean {np.mean(ratio):.3f}, sd {np.std(ratio):.3f}")
    print(f"raw sigma: |z| quantiles 68.3 % {q68:.2f}, 95.4 % {q95:.2f} (honest: 1.00, 2.00); "
          f"1 sigma covers {100 * np.mean(za < 1):.1f} %, 2 sigma {100 * np.mean(za < 2):.1f} %")
    print(f"inflation needed: {need:.2f}; in use: {in_use:g}, with it 1 sigma covers "
          f"{100 * np.mean(za < in_use):.1f} %, 2 sigma {100 * np.mean(za < 2 * in_use):.1f} %")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-big", action="store_true", help="skip the 168-hour streaming case")
    ap.add_argument("--only-big", action="store_true", help="only the 168-hour streaming case")
    ap.add_argument("--hours", type=float, default=168.0)
    ap.add_argument("--coverage", action="store_true",
                    help="only part 3: coverage of the bias-instability sigma (a few minutes)")
    ap.add_argument("--seeds", type=int, default=16)
    args = ap.parse_args()
    if args.coverage:
        part3(seeds=args.seeds)
        return
    if not args.only_big:
        part1()
    if not args.skip_big:
        part2(hours=args.hours)


if __name__ == "__main__":
    main()
