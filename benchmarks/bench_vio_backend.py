"""The stereo-VIO back end alone, on recorded front-end observations: CPU time per frame and ATE.

    .venv/bin/python benchmarks/bench_vio_backend.py --record SEQ ...      # once per sequence
    .venv/bin/python benchmarks/bench_vio_backend.py SEQ ... [--set NAME=VALUE ...] [--profile]

``--record`` runs the front end over a rendered SVI sequence (``bench_vio.py --keep DIR
--render-only`` makes them) with stereo matching at every frame and stores every frame's
observations in ``SEQ/.vio_obs.npz`` (the left tracks are the matches with ``uR`` NaN).  The
replay feeds the :class:`~ibiscape_eval.vio.Estimator` exactly like ``run_vio`` (the stereo
matches only for the frames that ``Estimator.needs_stereo`` asks for), so a back-end change is
measured without re-running image reading and KLT (about two thirds of the frame time).  The
replay's tracks are those of the recording: the gyro prior of the front end and the stereo
disparity guesses of a real run differ slightly, so the final numbers come from
``bench_vio.py``.  CPU time of the whole process (all threads), ATE after SE(3) alignment.
``--profile`` prints the top of a cProfile of the back end.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import resource
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_vio import _ate, _params

OBS_FILE = ".vio_obs.npz"


def record(seq: Path) -> None:
    """Front end over every frame of ``seq``, stereo matched at each; saved to ``OBS_FILE``."""
    from ibiscape_eval.io.stereo import read_gray_image
    from ibiscape_eval.vio import Estimator, StereoFrontEnd, VioParams, load_sequence

    s = load_sequence(seq)
    p = VioParams()
    fe = StereoFrontEnd(s.rig, p)
    est = Estimator(s.rig.rectified(), s.imu, s.noise, p, s.T_body_imu)
    cols: dict[str, list[Any]] = {"stamp": [], "n": [], "ids": [], "uL": [], "uR": [], "v": []}
    prev: int | None = None
    for i in range(s.n_frames):
        t_ns = int(s.frame_stamps_ns[i])
        R = None if prev is None else est.gyro_rotation(prev, t_ns)
        tracks = fe.track(t_ns, read_gray_image(s.left_files[i]), R)
        full = fe.match(read_gray_image(s.right_files[i]))
        est.process(full if est.needs_stereo(tracks) else tracks)
        prev = t_ns
        cols["stamp"].append(t_ns)
        cols["n"].append(len(full))
        for c in ("ids", "uL", "uR", "v"):
            cols[c].append(getattr(full, c))
    arrays: dict[str, Any] = {c: np.concatenate(cols[c]) for c in ("ids", "uL", "uR", "v")}
    arrays["stamp"] = np.asarray(cols["stamp"], dtype=np.int64)
    arrays["n"] = np.asarray(cols["n"], dtype=np.int64)
    np.savez_compressed(seq / OBS_FILE, **arrays)
    print(f"{seq}: {s.n_frames} frames recorded")


def load_obs(seq: Path) -> list[Any]:
    from ibiscape_eval.vio import StereoObservations

    with np.load(seq / OBS_FILE) as f:
        z = {k: f[k] for k in ("stamp", "n", "ids", "uL", "uR", "v")}  # each read decompresses
    edges = np.concatenate(([0], np.cumsum(z["n"])))
    return [StereoObservations(int(t), z["ids"][a:b], z["uL"][a:b], z["uR"][a:b], z["v"][a:b])
            for t, a, b in zip(z["stamp"], edges[:-1], edges[1:], strict=True)]


def replay(seq: Path, params: Any, profile: bool) -> dict[str, float]:
    from ibiscape_eval.io import read_trajectory
    from ibiscape_eval.vio import Estimator, StereoObservations, load_sequence

    s = load_sequence(seq)
    frames = load_obs(seq)
    est = Estimator(s.rig.rectified(), s.imu, s.noise, params, s.T_body_imu)
    prof = cProfile.Profile(time.process_time) if profile else None
    c0, w0 = time.process_time(), time.perf_counter()
    if prof:
        prof.enable()
    stereo = 0
    for full in frames:
        tracks = StereoObservations(full.stamp_ns, full.ids, full.uL, np.full(len(full), np.nan),
                                    full.v)
        if est.needs_stereo(tracks):
            stereo += 1
            est.process(full)
        else:
            est.process(tracks)
    est.finish()
    tr = est.trajectory()
    if prof:
        prof.disable()
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    gt = read_trajectory(seq / "vehicle_gt" / "groundtruth_sync.csv", "ibiscape")
    a, _ = _ate(tr, gt, max_diff_s=0.02)
    if prof:
        pstats.Stats(prof).sort_stats("tottime").print_stats(25)
    length = float(a.ref.path_length_m()[-1])
    return {"frames": len(frames), "keyframes": est.n_keyframes, "stereo": stereo,
            "back_ms": 1e3 * cpu / len(frames), "wall_s": wall, "ate_m": a.translation_m.rmse,
            "ate_pct": 100 * a.translation_m.rmse / length, "failures": len(est.failures),
            "landmarks": est.backend.n_landmarks}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sequences", nargs="+", type=Path)
    ap.add_argument("--record", action="store_true", help="record the front end's observations")
    ap.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    ap.add_argument("--profile", action="store_true", help="print a cProfile of the back end")
    a = ap.parse_args()
    if a.record:
        for seq in a.sequences:
            record(seq)
        return
    params = _params(a.set)
    print(f"{'sequence':<22}{'frames':>7}{'kf':>6}{'stereo':>7}{'lm':>7}{'back':>9}{'ATE':>9}"
          f"{'ATE %':>8}{'fail':>5}")
    for seq in a.sequences:
        r = replay(seq, params, a.profile)
        print(f"{seq.name:<22}{r['frames']:>7}{r['keyframes']:>6}{r['stereo']:>7}"
              f"{r['landmarks']:>7}{r['back_ms']:>7.2f}ms{r['ate_m']:>8.3f}m{r['ate_pct']:>7.3f}%"
              f"{r['failures']:>5}", flush=True)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS {peak:.0f} MB; set: {' '.join(a.set) or '(defaults)'}")


if __name__ == "__main__":
    main()
