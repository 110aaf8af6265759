"""ibiscape-eval ``ate``/``rpe`` against evo's ``evo_ape``/``evo_rpe`` on generated trajectories.

Both tools run as fresh command-line processes on the same TUM files in the same run; the table
gives wall time, peak memory (the process's own max RSS) and the ratio, and checks that both
report the same RMSE.  Our commands are timed warm (numba's compiled kernels already cached on
disk) as the best of ``--repeat`` runs (the machine may be shared); evo, which takes tens of
seconds, runs once.  A last row times one cold run, with an empty numba cache (every kernel
compiled, as on the very first run after installation).
Run: ``.venv/bin/python benchmarks/bench_trajectory.py [--sizes 100000,1000000] [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).parent))
from _runner import Run, run

from ibiscape_eval.core import Trajectory
from ibiscape_eval.core.rotations import quat_from_rotvec, quat_multiply
from ibiscape_eval.io import write_trajectory

BIN = Path(sys.executable).parent


def make_pair(n: int, seed: int = 0) -> tuple[Trajectory, Trajectory]:
    """A smooth 200 Hz ground truth (random-walk velocity, sinusoidal attitude) and a drifting,
    noisy estimate with the same stamps."""
    rng = np.random.default_rng(seed)
    dt_ns = 5_000_000
    stamps = 1_403_715_000_000_000_000 + np.arange(n, dtype=np.int64) * dt_ns
    vel = np.cumsum(rng.normal(0, 0.02, (n, 3)), axis=0)
    vel -= np.linspace(0, 1, n)[:, None] * vel[-1]  # keep it bounded
    pos = np.cumsum(vel * 0.005, axis=0)
    t = np.arange(n) * 0.005
    angles = np.stack(
        [0.3 * np.sin(2 * np.pi * f * t + ph) for f, ph in ((0.01, 0), (0.05, 1), (0.07, 2))], 1
    )
    q = Rotation.from_euler("zyx", angles).as_quat()
    gt = Trajectory(stamps, pos, q, "gt")
    est_pos = pos + np.cumsum(rng.normal(0, 1e-4, (n, 3)), axis=0) + rng.normal(0, 0.01, (n, 3))
    est_q = quat_multiply(q, quat_from_rotvec(rng.normal(0, 0.002, (n, 3))))
    return Trajectory(stamps, est_pos, est_q, "est"), gt


def write_pair(n: int, seed: int, est_path: Path, ref_path: Path) -> None:
    """Write :func:`make_pair` as two TUM files from a child process.

    Peak memory is read from ``wait4``, and a child started with ``vfork`` (what subprocess
    uses) inherits its parent's peak RSS: the generated poses must never live in this process.
    """
    import subprocess

    subprocess.run([sys.executable, __file__, "--write-pair", str(n), str(seed), str(est_path),
                    str(ref_path)], check=True)


def evo_rmse(out: str) -> float:
    m = re.search(r"^\s*rmse\s+([0-9.eE+-]+)", out, re.M)
    return float(m.group(1)) if m else float("nan")


def ours_rmse(out: str) -> float:
    try:
        return float(json.loads(out)["translation_m"]["rmse"])
    except (ValueError, KeyError):
        return float("nan")


def row(name: str, ours: Run, evo: Run | None, r_ours: float, r_evo: float) -> str:
    if evo is None:
        return f"{name:<34}{ours.wall_s:>9.2f}{'-':>9}{'-':>9}{ours.peak_mb:>10.0f}{'-':>10}{r_ours:>12.6g}{'-':>12}"
    ratio = evo.wall_s / ours.wall_s
    return (
        f"{name:<34}{ours.wall_s:>9.2f}{evo.wall_s:>9.2f}{ratio:>8.1f}x{ours.peak_mb:>10.0f}"
        f"{evo.peak_mb:>10.0f}{r_ours:>12.6g}{r_evo:>12.6g}"
    )


def best_of(cmd: list[str], repeat: int) -> Run:
    """The fastest of ``repeat`` runs (its peak memory is the largest seen)."""
    runs = [run(cmd) for _ in range(max(repeat, 1))]
    best = min(runs, key=lambda r: r.wall_s)
    return Run(best.wall_s, max(r.peak_mb for r in runs), best.stdout, best.returncode)


def cold(cmd: list[str], tmp: Path) -> Run:
    """One run with an empty numba cache: the kernels are compiled, as on a first run."""
    old = os.environ.get("NUMBA_CACHE_DIR")
    os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="numba_cold_", dir=tmp)
    try:
        return run(cmd)
    finally:
        if old is None:
            del os.environ["NUMBA_CACHE_DIR"]
        else:
            os.environ["NUMBA_CACHE_DIR"] = old


def allpairs_cmd(est: Path, ref: Path) -> list[str]:
    """``ibiscape-eval rpe`` over 1 m, every start pose (the all-pairs case)."""
    return [str(BIN / "ibiscape-eval"), "rpe", str(est), str(ref), "--format", "tum", "--delta", "1",
            "--delta-unit", "metres", "--pairs", "all", "--json"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", default="100000,1000000")
    ap.add_argument(
        "--allpairs-evo-size",
        type=int,
        default=10000,
        help="evo's all-pairs RPE is quadratic: its size for the side-by-side run",
    )
    ap.add_argument("--filter-evo-max", type=int, default=100000,
                    help="largest size of the --motion-filter / --downsample side-by-side runs")
    ap.add_argument("--timeout-s", type=float, default=600)
    ap.add_argument("--repeat", type=int, default=3, help="runs of our commands (best is kept)")
    ap.add_argument("--write-pair", nargs=4, help=argparse.SUPPRESS)  # N SEED EST REF (child)
    args = ap.parse_args()
    if args.write_pair:
        n, seed, est_path, ref_path = args.write_pair
        est, gt = make_pair(int(n), seed=int(seed))
        write_trajectory(est_path, est, "tum")
        write_trajectory(ref_path, gt, "tum")
        return
    ours_bin, evo_ape, evo_rpe = (
        str(BIN / "ibiscape-eval"),
        str(BIN / "evo_ape"),
        str(BIN / "evo_rpe"),
    )
    tmp = Path(tempfile.mkdtemp(prefix="bench_traj_"))
    last_ate: tuple[list[str], int] | None = None
    print(
        f"{'case':<34}{'ours s':>9}{'evo s':>9}{'ratio':>9}{'ours MB':>10}{'evo MB':>10}"
        f"{'rmse ours':>12}{'rmse evo':>12}"
    )
    try:
        help_ours = min(run([ours_bin, "--help"]).wall_s for _ in range(5))
        help_evo = min(run([evo_ape, "--help"]).wall_s for _ in range(3))
        print(
            f"{'--help start-up':<34}{help_ours:>9.3f}{help_evo:>9.3f}{help_evo / help_ours:>8.1f}x"
        )
        for n in (int(s) for s in args.sizes.split(",")):
            fe, fg = tmp / f"est_{n}.txt", tmp / f"gt_{n}.txt"
            write_pair(n, 0, fe, fg)
            ate_cmd = [ours_bin, "ate", str(fe), str(fg), "--format", "tum", "--align", "se3",
                       "--json"]
            run(ate_cmd)  # warm-up: numba's kernels compiled and cached if they were not
            last_ate = (ate_cmd, n)
            o = best_of(ate_cmd, args.repeat)
            e = run([evo_ape, "tum", str(fg), str(fe), "-a"], timeout_s=args.timeout_s)
            print(row(f"ate se3, {n:,} poses", o, e, ours_rmse(o.stdout), evo_rmse(e.stdout)))
            o = best_of(
                [ours_bin, "rpe", str(fe), str(fg), "--format", "tum", "--delta", "1", "--json"],
                args.repeat,
            )
            e = run(
                [evo_rpe, "tum", str(fg), str(fe), "--delta", "1", "--delta_unit", "f"],
                timeout_s=args.timeout_s,
            )
            print(row(f"rpe 1 frame, {n:,} poses", o, e, ours_rmse(o.stdout), evo_rmse(e.stdout)))
            # evo's pose selection: a motion filter (a sequential rule; ours is one compiled
            # pass, evo loops over the poses in Python) and an even downsampling, then ATE.
            # Both keep the same poses; evo's float-second association may accept a pair a few
            # microseconds beyond --max-diff-s that ours (exact ns) refuses, so the RMSEs of the
            # filtered (sparse, on a 5 ms grid) sets can differ slightly.
            if n <= args.filter_evo_max:
                o = best_of([*ate_cmd, "--motion-filter", "0.05", "5"], args.repeat)
                e = run([evo_ape, "tum", str(fg), str(fe), "-a", "--motion_filter", "0.05", "5"],
                        timeout_s=args.timeout_s)
                print(row(f"ate --motion-filter, {n:,} poses", o, e, ours_rmse(o.stdout),
                          evo_rmse(e.stdout)))
                o = best_of([*ate_cmd, "--downsample", str(n // 10)], args.repeat)
                e = run([evo_ape, "tum", str(fg), str(fe), "-a", "--downsample", str(n // 10)],
                        timeout_s=args.timeout_s)
                print(row(f"ate --downsample N/10, {n:,} poses", o, e, ours_rmse(o.stdout),
                          evo_rmse(e.stdout)))
            if n <= 100_000:
                o = best_of(allpairs_cmd(fe, fg), args.repeat)
                print(row(f"rpe 1 m all pairs, {n:,} poses", o, None, ours_rmse(o.stdout), 0))
        n = args.allpairs_evo_size
        fe, fg = tmp / f"est_{n}.txt", tmp / f"gt_{n}.txt"
        write_pair(n, 1, fe, fg)
        o = best_of(allpairs_cmd(fe, fg), args.repeat)
        e = run(
            [evo_rpe, "tum", str(fg), str(fe), "--delta", "1", "--delta_unit", "m", "--all_pairs"],
            timeout_s=args.timeout_s,
        )
        print(row(f"rpe 1 m all pairs, {n:,} poses", o, e, ours_rmse(o.stdout), evo_rmse(e.stdout)))
        if last_ate is not None:
            o = cold(last_ate[0], tmp)
            print(row(f"ate se3 cold (compiles), {last_ate[1]:,}", o, None, ours_rmse(o.stdout), 0))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
