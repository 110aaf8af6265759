"""Render every camera of a sequence into the IBISCape layout (called by ``sim.generate``).

Per camera folder ``<name>/`` (``../shared/FORMATS.md``)::

    rgb:       frames/<ns>.png (8-bit RGB)
    depth:     frames/<ns>.png (CARLA's 8-bit logarithmic depth, like the dataset)
               mm/<ns>.png     (16-bit millimetres, ORB-SLAM3 / TUM RGB-D style, 0 = none)
    semantic:  frames/<ns>.png (CityScapes palette, like the dataset)
               labels/<ns>.png (raw CARLA tag per pixel)
    dvs:       events/<ns>.npz, frames/<ns>.png (``ibiscape_eval.sim.dvs.write_dvs_camera``)
    every one: timestamps.csv (``#timestamp [ns], filename``)

Cameras with the same optics, mounting and rate (the RGB-D housing: ``rgb``, ``depth``,
``semantic``) share one render per frame; the views of one instant (a stereo pair) render on two
threads and PNG encoding runs on a third, so the files do not depend on the threads.  An RGB camera and a depth camera in the same housing
also get ``association.txt`` (``t_rgb rgb/frames/<ns>.png t_depth depth/mm/<ns>.png``, seconds),
the file ORB-SLAM3's RGB-D examples read.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["export_problem", "render_cameras"]

Progress = Callable[[float, str], None]

def _stamps(cfg: Any, rate_hz: float) -> np.ndarray:
    from ..still import n_samples, uniform_stamps

    return uniform_stamps(cfg.start_ns, rate_hz, 0, n_samples(cfg.duration_s, rate_hz))


def shift_ns(cam: Any) -> int:
    """The camera's clock offset ``timeshift_cam_imu`` in integer nanoseconds."""
    return round(float(getattr(cam, "timeshift_cam_imu_s", 0.0)) * 1e9)


def camera_stamps(cfg: Any, cam: Any) -> np.ndarray:
    """Frame stamps of ``cam`` on its own clock: the uniform grid at its rate, without the frames
    whose scene instant ``t_cam + timeshift_cam_imu`` (Kalibr's ``t_imu = t_cam + shift``) falls
    outside the sequence (a shifted camera loses at most a frame at one end)."""
    st = _stamps(cfg, cam.rate_hz)
    d = shift_ns(cam)
    if d == 0:
        return st
    end = cfg.start_ns + round(cfg.duration_s * 1e9)
    keep = (st + d >= cfg.start_ns) & (st + d <= end)
    return st[keep]


def export_problem(cfg: Any, fmt: str) -> str | None:
    """Why the rendered cameras of ``cfg`` cannot fill the export ``fmt``, or ``None`` if they can
    (checked before generating, so a doomed export costs nothing)."""
    kinds = {c.kind for c in cfg.cameras}
    if fmt == "tum-rgbd" and not {"rgb", "depth"} <= kinds:
        return (f"--export tum-rgbd needs an RGB and a depth camera; setup {cfg.setup} has "
                f"{', '.join(sorted(kinds)) or 'no cameras'} (use --setup rgbd or full)")
    if fmt in ("euroc", "rosbag") and not kinds & {"rgb", "dvs"}:
        return f"--export {fmt} needs RGB or DVS cameras; setup {cfg.setup} has none"
    return None


class _Work:
    """Progress in work units (pixels rendered; a DVS camera renders ~3 times per frame)."""

    def __init__(self, cfg: Any, groups: list[list[Any]], progress: Progress | None) -> None:
        self.units = {c.name: len(camera_stamps(cfg, c)) * c.width_px * c.height_px
                      * (3 if c.kind == "dvs" else 1) for c in cfg.cameras}
        for g in groups:
            for c in g[1:]:  # rendered once for the whole group
                self.units[c.name] = 0
        self.total = max(1, sum(self.units.values()))
        self.done = 0.0
        self.progress = progress

    def report(self, label: str, frac_of_cam: float = 0.0, name: str = "") -> None:
        if self.progress is not None:
            extra = frac_of_cam * self.units[name] if name else 0.0
            self.progress(min(1.0, (self.done + extra) / self.total), label)


def _groups(cfg: Any, renderer: Any) -> list[list[Any]]:
    """Non-DVS cameras with the same optics, mounting, rate and clock offset: one render each."""
    groups: dict[tuple[Any, ...], list[Any]] = {}
    for c in cfg.cameras:
        if c.kind == "dvs":
            continue
        cam = renderer.camera(c.name)
        key = (cam.model, cam.T_body_cam.round(9).tobytes(), float(c.rate_hz), shift_ns(c))
        groups.setdefault(key, []).append(c)
    return list(groups.values())


def _write_view(out: Path, group: list[Any], t: int, view: Any) -> None:
    """The PNG files of every camera of ``group`` for the view at stamp ``t``."""
    from ibiscape_eval.io.images import (
        write_depth_carla_log,
        write_depth_mm,
        write_labels,
        write_labels_cityscapes,
        write_png,
    )

    name = f"{t}.png"
    for c in group:
        d = out / c.name
        if c.kind == "rgb":
            write_png(d / "frames" / name, view.rgb, photo=True)
        elif c.kind == "depth":
            write_depth_carla_log(d / "frames" / name, view.depth_m)
            write_depth_mm(d / "mm" / name, view.depth_m)
        elif c.kind == "semantic":
            write_labels_cityscapes(d / "frames" / name, view.labels)
            write_labels(d / "labels" / name, view.labels)


def _render_frames(cfg: Any, out: Path, renderer: Any, glist: list[list[Any]], work: _Work) -> None:
    """Render and write every frame of every group, instant by instant."""
    g_stamps = [camera_stamps(cfg, g[0]) for g in glist]
    g_shift = [shift_ns(g[0]) for g in glist]
    for g in glist:
        for c in g:
            for sub in ("frames", *{"depth": ("mm",), "semantic": ("labels",)}.get(c.kind, ())):
                (out / c.name / sub).mkdir(parents=True, exist_ok=True)
    lead_names = [sorted(g, key=lambda c: c.kind != "rgb")[0].name for g in glist]
    g_sets = [set(st.tolist()) for st in g_stamps]
    all_t = sorted(set().union(*g_sets)) if g_sets else []
    # the views of one instant (a stereo pair) render on two threads (the ray casts and the numba
    # kernels release the GIL), and PNG encoding runs on a third while the next instant renders;
    # at most a few frames wait, and a write error surfaces at once
    with ThreadPoolExecutor(max_workers=2) as views, ThreadPoolExecutor(max_workers=1) as writer:
        pending: deque[Future[None]] = deque()
        for k, t in enumerate(all_t):
            todo = [gi for gi in range(len(glist)) if t in g_sets[gi]]
            # a frame stamped t on the camera's clock shows the scene at t + timeshift_cam_imu
            rendered = list(views.map(lambda gi, t=t: renderer.render(lead_names[gi], t + g_shift[gi]),
                                      todo))
            for gi, view in zip(todo, rendered, strict=True):
                pending.append(writer.submit(_write_view, out, glist[gi], t, view))
                work.done += work.units[glist[gi][0].name] / len(g_stamps[gi])
            while len(pending) > 4 or (pending and pending[0].done()):
                pending.popleft().result()
            work.report(f"render {k + 1}/{len(all_t)}")
        while pending:
            pending.popleft().result()


def _frame_entries(cfg: Any, out: Path, glist: list[list[Any]]) -> dict[str, dict[str, Any]]:
    """``timestamps.csv`` and the ``sequence.yaml`` entry of every rendered non-DVS camera."""
    from ibiscape_eval.io.images import write_frame_timestamps

    result: dict[str, dict[str, Any]] = {}
    for g in glist:
        stamps = camera_stamps(cfg, g[0])
        for c in g:
            write_frame_timestamps(out / c.name / "timestamps.csv", stamps)
            entry: dict[str, Any] = {"folder": c.name, "frames": len(stamps), "timestamps": f"{c.name}/timestamps.csv"}
            if c.kind == "depth":
                entry["encoding"] = {"frames": "CARLA logarithmic depth, 8-bit, 3 equal channels",
                                     "mm": "16-bit PNG, millimetres, 0 = no depth (DepthMapFactor 1000)"}
            elif c.kind == "semantic":
                entry["encoding"] = {"frames": "CityScapes palette (CARLA 0.9.10-0.9.13 tags)",
                                     "labels": "raw CARLA tag per pixel, 8-bit"}
            result[c.name] = entry
    return result


def _render_dvs(cfg: Any, out: Path, renderer: Any, weather: Any, work: _Work) -> dict[str, dict[str, Any]]:
    """Events (and event frames) of every DVS camera, one after the other."""
    from ..dvs import write_dvs_camera
    from ..imu import sub_seed

    result: dict[str, dict[str, Any]] = {}
    for i, c in enumerate(cfg.cameras):
        if c.kind != "dvs":
            continue
        stamps = camera_stamps(cfg, c)
        name = c.name

        def gray(t_ns: int, name: str = name, d: int = shift_ns(c)) -> Any:
            return renderer.gray(name, t_ns + d)  # events stamped on the camera's clock

        def dvs_step(frac: float, label: str, name: str = name) -> None:
            work.report(label, frac, name)

        res = write_dvs_camera(gray, c, stamps, out / c.name, dvs_config=getattr(cfg, "dvs", None),
                               weather=weather, rng=np.random.default_rng(sub_seed(cfg.seed, "dvs", i)),
                               progress=dvs_step)
        result[c.name] = {"folder": c.name, "frames": len(stamps), "timestamps": f"{c.name}/timestamps.csv",
                          "dvs": res.to_dict()}
        work.done += work.units[c.name]
    return result


def render_cameras(cfg: Any, folder: str | Path, world: Any, motion: Any, weather: Any, *,
                   scenario: dict[str, Any] | None = None, progress: Progress | None = None
                   ) -> dict[str, dict[str, Any]]:
    """Render every camera of ``cfg`` into ``folder`` (the sequence's staging folder).

    Returns
    -------
    dict
        Camera name -> what was written (for ``sequence.yaml``: folders, frame count, DVS counts).
    """
    from .renderer import Renderer

    out = Path(folder)
    renderer = Renderer.from_config(cfg, world, motion, weather, scenario=scenario)
    glist = _groups(cfg, renderer)
    work = _Work(cfg, glist, progress)
    _render_frames(cfg, out, renderer, glist, work)
    result = _frame_entries(cfg, out, glist)
    result.update(_render_dvs(cfg, out, renderer, weather, work))
    _association(cfg, out, result)
    return result


def _association(cfg: Any, out: Path, result: dict[str, dict[str, Any]]) -> None:
    """``association.txt`` for an RGB camera and a depth camera sharing a housing."""
    from ibiscape_eval.io.images import write_association

    rgb = [c for c in cfg.cameras if c.kind == "rgb" and c.mount and c.name in result]
    depth = [c for c in cfg.cameras if c.kind == "depth" and c.name in result]
    for r in rgb:
        for d in depth:
            if d.mount == r.mount and d.rate_hz == r.rate_hz:
                st = camera_stamps(cfg, r).tolist()
                write_association(out / "association.txt", st, [f"{r.name}/frames/{t}.png" for t in st],
                                  st, [f"{d.name}/mm/{t}.png" for t in st])
                result[r.name]["association"] = "association.txt"
                return
