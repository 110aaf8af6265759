"""Renderer speed: stereo steps per second per image size, where the time goes, and a rendered SVI
sequence.

    .venv/bin/python benchmarks/bench_render.py                  # sizes 256, 512, 1024; SVI 10 s
    .venv/bin/python benchmarks/bench_render.py --svi-seconds 60 # the issue's 60 s sequence
    .venv/bin/python benchmarks/bench_render.py --sizes 1024 --stages --svi-seconds 0
    # issue #25 in one command: 1024 step with stages, 30 s calibration drive before/after
    .venv/bin/python benchmarks/bench_render.py --sizes 1024 --stages --svi-seconds 0 \
        --calib-seconds 30 --cli /path/to/old/.venv/bin/ibiscape-eval

A *stereo step* renders two RGB views (left and right camera of the SVI rig, 0.4 m apart) with
depth and segmentation: rays, static + movers casts, textures, shadows, weather, sensor noise (PNG
writing is not part of it: the SVI row includes it).  It runs once with the views one after the
other and once on two threads as ``sim`` does per frame.  Every row gives the best wall time and
the CPU time of that run (all threads; what an idle machine would need when other jobs share this
one: on two idle cores the two-thread step takes about half its CPU time).  The peer is open3d's
raycaster alone: ``cast_rays(nthreads=0)`` of the same rays against the same static scene, twice
(one per view).  RATIO = render time / raw cast time (1 would be a renderer that adds nothing to
the ray cast; the renderer finds the pixels' surfaces with its own z-buffer, ``sim.render.raster``,
and casts only the supersamples and the movers).  ``--stages`` adds the CPU time per stage of the
sequential 1024 step (the raster, the casts, the fused numba passes, the shadow rays' grid across the sun, blur, noise, target supersampling and its
board-plane path; inclusive times, benchmark-only instrumentation of internals) and, outside the
step's total, the PNG encoding of its two RGB views as ``sim`` writes them (``write_png(photo=True)``)
and with the default settings, and the build of the shadow rays' grid (``sim.render.sun_grid``: the
step reuses it; a sequence builds one whenever the sun has moved 0.5 deg, every ~2 s of a drive).

The sequence row runs the command line (``ibiscape-eval sim --setup svi --resolution 1024``, PNG
writing included) in fresh processes, once for 0.5 s and once for ``--svi-seconds``: the difference
is the cost per stereo frame, the short run the fixed cost (imports, world, scene), and a 60 s
sequence (1201 frames) extrapolates to fixed + 1201 x per frame.  ISSUE TARGETS: a stereo step at
1024 x 1024 <= 0.3 s, a 60 s SVI sequence at 1024 x 1024 <= 10 min.

The calibration-drive row (``--calib-seconds S``) runs ``ibiscape-eval sim --setup svi --kind
calibration --resolution 384 --duration-s S`` (the shuttle drive, the board in view all the time,
PNG writing included) in a fresh process: wall, CPU, peak RSS and CPU per stereo frame, against
the peer's raw cast of the same 384 x 384 stereo rays (per frame, measured in this run).
``--cli PATH`` times another build's ``ibiscape-eval`` for the same row (a before/after pair:
``--cli /path/to/old/.venv/bin/ibiscape-eval``).  ISSUE TARGET (#25): a 30 s drive at least 2x
faster than 196 s; a 1024 x 1024 stereo step within 1.5x the raw cast.
"""

from __future__ import annotations

import argparse
import collections
import functools
import os
import resource
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _runner import run

CLI = str(Path(sys.executable).with_name("ibiscape-eval"))
T_NS = 1_000_000_000_000


def _stereo_poses(world_kind: str) -> tuple[np.ndarray, np.ndarray]:
    R = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    TL, TR = np.eye(4), np.eye(4)
    TL[:3, :3] = TR[:3, :3] = R
    if world_kind == "slam":  # along an eastbound lane, buildings on both sides
        TL[:3, 3], TR[:3, 3] = (100.0, 78.45, 2.8), (100.0, 78.05, 2.8)
    else:  # calibration approach: both boards ahead
        TL[:3, 3], TR[:3, 3] = (70.0, 0.2, 2.8), (70.0, -0.2, 2.8)
    return TL, TR


def _time(fn: Callable[[], Any], repeat: int) -> tuple[float, float]:
    """Best wall time and the CPU time (all threads) of that run [s]."""
    fn()  # warm up (caches: rays, textures, compiled kernels)
    best, cpu = float("inf"), float("inf")
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall = time.perf_counter() - t0
        if wall < best:
            best, cpu = wall, time.process_time() - c0
    return best, cpu


def _stages(r: Any, step: Callable[[], None], repeat: int) -> list[tuple[str, float]]:
    """CPU time per stage of ``step`` [s per step], by wrapping the renderer's internals (the views
    must run one after the other: process CPU time is charged to the stage running)."""
    from ibiscape_eval.sim.render import _kernels, raster, renderer, sun_grid

    acc: dict[str, float] = collections.defaultdict(float)

    def timed(fn: Callable[..., Any], label: str) -> Callable[..., Any]:
        @functools.wraps(fn)
        def wrapper(*a: Any, **k: Any) -> Any:
            c0 = time.process_time()
            try:
                return fn(*a, **k)
            finally:
                acc[label] += time.process_time() - c0
        return wrapper

    class Scene:  # the static scene's casts
        def __init__(self, scene: Any) -> None:
            self.scene = scene
            self.cast_rays = timed(scene.cast_rays, "open3d: primary rays, static scene")
            self.test_occlusions = timed(scene.test_occlusions, "open3d: shadow rays, static scene")

    patches = [(renderer, "world_rays", "world rays"), (renderer, "subpixel_rays", "target supersample rays"),
               (renderer, "rain_streaks", "rain streaks"), (renderer, "board_albedo", "board textures"),
               (renderer, "sensor_output", "sensor noise + 8 bit (quantize)"),
               (raster, "cast_camera", "raster: primary visibility, static scene"),
               (_kernels, "surfaces", "numba: hits, albedo, shadow rays (surfaces)"),
               (_kernels, "finish_into", "numba: shading, wet road, fog (finish)"),
               (renderer.Renderer, "_occluded", "shadow rays (static + movers)"),
               (sun_grid.SunGrid, "occluded", "sun grid: shadow rays, static scene"),
               (renderer.Renderer, "_mover_pixels", "movers' pixels"),
               (renderer.Renderer, "_radiance", "per-ray work (casts + kernels)"),
               (renderer.Renderer, "_supersample_targets", "target supersampling (all of it)"),
               (_kernels, "board_texels", "numba: board texels"),
               (_kernels, "board_plane_means", "numba: supersamples on the board's plane"),
               (renderer.Renderer, "_plane_supersamples", "supersamples on the board's plane (coarse cast + numba)"),
               (renderer.Renderer, "render_pose", "whole view")]
    import cv2

    patches.append((cv2, "GaussianBlur", "lens blur (cv2.GaussianBlur)"))
    saved = [(obj, name, getattr(obj, name)) for obj, name, _ in patches]
    static = r.static
    try:
        for obj, name, label in patches:
            setattr(obj, name, timed(getattr(obj, name), label))
        object.__setattr__(static, "scene", Scene(static.scene))
        step()
        acc.clear()
        c0 = time.process_time()
        for _ in range(repeat):
            step()
        acc["TOTAL stereo step"] = time.process_time() - c0
        acc.update(_png_stage(r, repeat))
        acc.update(_grid_stage(r, repeat))
    finally:
        for obj, name, fn in saved:
            setattr(obj, name, fn)
        object.__setattr__(static, "scene", static.scene.scene)
    return sorted(((k, v / repeat) for k, v in acc.items()), key=lambda kv: -kv[1])


def _png_stage(r: Any, repeat: int) -> dict[str, float]:
    """CPU time of writing the two RGB views of the last step as ``sim`` does (``write_png``
    ``photo=True``) and with the default settings, outside the step's total (``sim`` writes on
    a third thread while the next frame renders)."""
    from ibiscape_eval.io.images import write_png

    views = getattr(r, "_bench_views", [])
    out: dict[str, float] = {}
    with tempfile.TemporaryDirectory(prefix="bench_render_png_") as d:
        for label, photo in (("(not in TOTAL) PNG, 2 RGB views as sim writes them", True),
                             ("(not in TOTAL) PNG, 2 RGB views, default zlib level 1", False)):
            c0 = time.process_time()
            for _ in range(repeat):
                for i, v in enumerate(views):
                    write_png(Path(d) / f"{i}.png", v.rgb, photo=photo)
            out[label] = time.process_time() - c0
    return out


def _grid_stage(r: Any, repeat: int) -> dict[str, float]:
    """CPU time of building the static scene's shadow grid for the step's sun (outside the step's
    total: the step reuses the grid)."""
    from ibiscape_eval.sim.render import sun_grid
    from ibiscape_eval.sim.render.scene import MAT

    grid, st = r._sun_grid_cache, r.static
    if grid is None:
        return {}
    terrain = st.tables.material[-1 - len(st.occluder_triangles):-1] == MAT["ground"]
    c0 = time.process_time()
    for _ in range(repeat):
        sun_grid.build_sun_grid(st.occluder_vertices, st.occluder_triangles, grid.s0, terrain=terrain)
    return {"(not in TOTAL) sun grid build, once per 0.5 deg of sun motion": time.process_time() - c0}


def _svi(seconds: float) -> tuple[float, float, float, int]:
    """Wall, CPU [s], peak RSS [MB] and stereo frames of ``sim --setup svi`` at 1024 px."""
    with tempfile.TemporaryDirectory(prefix="bench_render_") as d:
        out = Path(d) / "svi"
        ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        res = run([CLI, "sim", "--setup", "svi", "--kind", "slam", "--duration-s", str(seconds),
                   "--resolution", "1024", "--seed", "1", "--out", str(out)])
        ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        if not res.ok:
            raise SystemExit("ibiscape-eval sim --setup svi failed")
        frames = len(list((out / "rgbL" / "frames").glob("*.png")))
        shutil.rmtree(out, ignore_errors=True)
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    return res.wall_s, cpu, res.peak_mb, frames


def _calib_drive(cli: str, seconds: float) -> tuple[float, float, float, int]:
    """Wall, CPU [s], peak RSS [MB] and stereo frames of a 384 px SVI calibration drive."""
    with tempfile.TemporaryDirectory(prefix="bench_render_calib_") as d:
        out = Path(d) / "calib"
        ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        res = run([cli, "sim", "--setup", "svi", "--kind", "calibration", "--duration-s", str(seconds),
                   "--resolution", "384", "--seed", "1", "--out", str(out)])
        ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        if not res.ok:
            raise SystemExit(f"{cli} sim --setup svi --kind calibration failed")
        frames = len(list((out / "rgbL" / "frames").glob("*.png")))
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    return res.wall_s, cpu, res.peak_mb, frames


def _calib_rows(seconds: float, clis: list[str], repeat: int, pairs: int = 1) -> None:
    """The calibration-drive rows: every ``cli`` against the raw cast of the drive's rays, ``pairs``
    rounds alternating between them."""
    from ibiscape_eval.core.camera import CameraModel
    from ibiscape_eval.sim.render import Renderer
    from ibiscape_eval.sim.render.rays import camera_rays, world_rays
    from ibiscape_eval.sim.render.scene import tensor
    from ibiscape_eval.sim.world import build_world

    r = Renderer(build_world(kind="calibration", seed=1, scene="clear"))
    model = CameraModel.from_fov(384, 384, 90.0)
    rays = [tensor(world_rays(camera_rays(model), T).reshape(-1, 6)) for T in _stereo_poses("calibration")]

    def cast() -> None:
        for rt in rays:
            r.static.scene.cast_rays(rt, nthreads=0)

    t_cast, c_cast = _time(cast, repeat)
    print(f"\nSVI calibration drive, 384x384, {seconds:g} s (fresh process, PNG writing included); peer: "
          f"open3d raw cast of one 384x384 stereo step {1000 * t_cast:.1f} ms wall, {1000 * c_cast:.1f} ms CPU")
    print(f"{'ibiscape-eval':<44} {'frames':>6} {'wall [s]':>9} {'load':>5} {'cpu [s]':>8} {'peak [MB]':>10} "
          f"{'cpu/frame [ms]':>15} {'RATIO cpu':>10} {'cpu/52.0 s':>10}")
    for _ in range(pairs):  # alternating: every cli once per round
        for cli in clis:
            wall, cpu, peak, frames = _calib_drive(cli, seconds)
            per = cpu / max(frames, 1)
            base = f"{cpu / (52.0 * seconds / 10.0):>10.2f}"  # the session-8 drive: 52.0 s CPU per 10 s
            print(f"{cli[-44:]:<44} {frames:>6} {wall:>9.1f} {os.getloadavg()[0]:>5.1f} {cpu:>8.1f} {peak:>10.0f} "
                  f"{1000 * per:>15.1f} {per / c_cast:>10.1f} {base}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="256,512,1024")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--stages", action="store_true", help="CPU time per stage of the largest step")
    ap.add_argument("--svi-seconds", type=float, default=10.0,
                    help="duration of the rendered SVI sequence (0: skip)")
    ap.add_argument("--calib-seconds", type=float, default=0.0,
                    help="duration of the 384 px SVI calibration drive row (0: skip)")
    ap.add_argument("--cli", action="append", default=[],
                    help="another ibiscape-eval to time on the calibration drive (repeatable)")
    ap.add_argument("--calib-pairs", type=int, default=1,
                    help="rounds of the calibration drive, alternating between this build and every --cli")
    a = ap.parse_args()
    if a.calib_seconds > 0:
        _calib_rows(a.calib_seconds, [CLI, *a.cli], a.repeat, a.calib_pairs)
    if not a.sizes:
        return

    from ibiscape_eval.core.camera import CameraModel
    from ibiscape_eval.sim.render import Renderer
    from ibiscape_eval.sim.render.rays import camera_rays, world_rays
    from ibiscape_eval.sim.render.scene import tensor
    from ibiscape_eval.sim.render.shading import WeatherState
    from ibiscape_eval.sim.world import build_world

    sizes = [int(s) for s in a.sizes.split(",")]
    rows = []
    stages: dict[str, list[tuple[str, float]]] = {}
    for kind, scene in (("slam", "dynamic"), ("calibration", "clear")):
        world = build_world(kind=kind, seed=1, scene=scene)
        t0 = time.perf_counter()
        r = Renderer(world)
        build_s = time.perf_counter() - t0
        TL, TR = _stereo_poses(kind)
        for n in sizes:
            model = CameraModel.from_fov(n, n, 90.0)
            w = WeatherState(fog_density=20.0, precipitation=30.0, wetness=40.0) if scene == "dynamic" else None

            def step(model: Any = model, w: Any = w, r: Any = r, TL: Any = TL, TR: Any = TR) -> None:
                r._bench_views = [r.render_pose(model, TL, T_NS, weather=w),
                                  r.render_pose(model, TR, T_NS, noise_key=1, weather=w)]

            rays = [tensor(world_rays(camera_rays(model), T).reshape(-1, 6)) for T in (TL, TR)]

            def cast(rays: Any = rays, r: Any = r) -> None:
                for rt in rays:
                    r.static.scene.cast_rays(rt, nthreads=0)

            t_step, c_step = _time(step, a.repeat)
            t_cast, c_cast = _time(cast, a.repeat)
            rows.append((f"{kind} ({scene}) {n}x{n}", t_step, c_step, t_cast, c_cast))
            with ThreadPoolExecutor(max_workers=2) as pool:  # as ``sim`` does: one thread per view

                def step2(model: Any = model, w: Any = w, r: Any = r, TL: Any = TL, TR: Any = TR,
                          pool: Any = pool) -> None:
                    a_ = pool.submit(r.render_pose, model, TL, T_NS, weather=w)
                    b_ = pool.submit(r.render_pose, model, TR, T_NS, noise_key=1, weather=w)
                    a_.result()
                    b_.result()

                t_par, c_par = _time(step2, a.repeat)
            rows.append(("  same, views on two threads", t_par, c_par, t_cast, c_cast))
            if n == max(sizes):  # what the shadow rays cost
                from dataclasses import replace

                keep = r.options
                r.options = replace(keep, shadows=False)
                t_flat, c_flat = _time(step, a.repeat)
                r.options = keep
                rows.append(("  same without shadows", t_flat, c_flat, t_cast, c_cast))
                if a.stages:
                    stages[f"{kind} ({scene}) {n}x{n}"] = _stages(r, step, a.repeat)
        print(f"{kind} world: {r.static.n_triangles} triangles, scene built in {build_s:.2f} s", flush=True)
    _print_steps(rows, stages)
    if a.svi_seconds > 0:
        _svi_rows(a.svi_seconds)


def _print_steps(rows: list[tuple[str, float, float, float, float]],
                 stages: dict[str, list[tuple[str, float]]]) -> None:
    """The stereo-step table, this process's peak RSS and the stages."""
    print(f"\n{'stereo step (2 RGB + depth + seg)':<36} {'step [s]':>9} {'cpu [s]':>8} {'steps/s':>8} "
          f"{'raw cast x2 [s]':>16} {'cpu [s]':>8} {'RATIO wall':>11} {'RATIO cpu':>10}")
    for name, ts, cs, tc, cc in rows:
        print(f"{name:<36} {ts:>9.3f} {cs:>8.3f} {1 / ts:>8.2f} {tc:>16.3f} {cc:>8.3f} {ts / tc:>11.1f} "
              f"{cs / cc:>10.1f}")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS of this process (both worlds, every size): {peak:.0f} MB")
    for name, st in stages.items():
        print(f"\nCPU per stage, {name} stereo step, views one after the other (inclusive) [ms]")
        for label, v in st:
            print(f"  {label:<58} {1000 * v:8.1f}")


def _svi_rows(seconds: float) -> None:
    """The SVI sequence rows: fixed cost and cost per frame from a 0.5 s and a long run."""
    w0, c0, _, f0 = _svi(0.5)
    w1, c1, peak, f1 = _svi(seconds)
    per_w, per_c = (w1 - w0) / (f1 - f0), (c1 - c0) / (f1 - f0)
    fix_w, fix_c = w0 - f0 * per_w, c0 - f0 * per_c
    print(f"\nSVI at 1024x1024: {seconds:g} s ({f1} stereo frames) {w1:.1f} s wall, {c1:.1f} s CPU, "
          f"{peak:.0f} MB peak; 0.5 s ({f0} frames) {w0:.1f} s wall, {c0:.1f} s CPU")
    print(f"  per stereo frame (PNG writing included): {per_w:.3f} s wall, {per_c:.3f} s CPU; fixed "
          f"{fix_w:.1f} s wall, {fix_c:.1f} s CPU")
    print(f"  a 60 s sequence (1201 frames) extrapolates to {(fix_w + 1201 * per_w) / 60:.1f} min wall here, "
          f"{(fix_c + 1201 * per_c) / 60:.1f} min of CPU (on two idle cores about half of that in wall "
          "time; target <= 10 min wall)")


if __name__ == "__main__":
    main()
