"""Camera calibration views rendered in the simulator's calibration world: any camera rig at varied
poses in front of the checkerboard or the AprilGrid, written as an IBISCape-layout sequence.

The simulator's calibration *drive* (``ibiscape-eval sim --kind calibration``) approaches the board
head-on, as in the paper; its views are nearly fronto-parallel, which leaves focal length and
principal point weakly determined.  A camera calibration wants the board tilted and seen across the
whole image: ``render_calibration_views`` places the rig (a hand-held calibration session) at
``n_views`` seeded poses 3-15 m from the board, viewing it from up to ``tilt_max_deg`` off its
normal, rolled, off-centre, with the whole pattern inside every camera, and renders each view with
:meth:`ibiscape_eval.sim.render.Renderer.render_pose` (same shading, supersampled board edges, lens
blur and sensor noise as the simulator's sequences).

The folder holds ``<camera>/frames/<ns>.png`` with ``timestamps.csv`` per camera and a
``sequence.yaml`` with the true cameras (``T_body_cam``: the body is the first camera) and the
target's Kalibr description, so ``ibiscape-eval calib FOLDER`` reports every estimate beside its truth.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import IbiscapeError

__all__ = ["calibration_view_poses", "render_calibration_views"]

FloatArray = npt.NDArray[np.float64]


def _look_at(eye: FloatArray, at: FloatArray, roll_rad: float) -> FloatArray:
    """``T_world_cam`` (OpenCV frame: z forward, y down) at ``eye`` looking at ``at``, rolled."""
    z = at - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    c, s = math.cos(roll_rad), math.sin(roll_rad)
    R = np.stack((x, y, z), axis=1) @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = eye
    return T


def calibration_view_poses(target: Any, cameras: Mapping[str, CameraModel],
                           T_cam0_cam: Mapping[str, npt.ArrayLike], n_views: int, *, seed: int = 0,
                           distance_m: tuple[float, float] = (3.0, 15.0),
                           tilt_max_deg: float = 35.0, roll_max_deg: float = 25.0,
                           min_eye_height_m: float = 0.5,
                           max_tries: int = 20_000) -> list[FloatArray]:
    """``n_views`` poses ``T_world_cam0`` that show every corner of ``target`` (a simulator
    :class:`~ibiscape_eval.sim.targets.Target`) inside every camera, 4 px from the border."""
    if n_views < 1:
        raise IbiscapeError(f"n_views must be >= 1, got {n_views}")
    rng = np.random.default_rng([int(seed), 0xCA1B])
    X = target.corners_world_m()
    centre = target.centre_world_m
    normal = target.observer_normal_world
    side = np.cross(normal, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    up = np.cross(side, normal)
    names = list(cameras)
    T0c = {k: np.asarray(T_cam0_cam[k], dtype=np.float64) for k in names}
    poses: list[FloatArray] = []
    for _ in range(max_tries):
        d = rng.uniform(*distance_m)
        tilt = math.radians(rng.uniform(0.0, tilt_max_deg))
        az = rng.uniform(-math.pi, math.pi)
        view = math.cos(tilt) * normal + math.sin(tilt) * (math.cos(az) * side + math.sin(az) * up)
        eye = centre + d * view
        if eye[2] < min_eye_height_m:
            continue
        # aim off the centre so the board lands anywhere in the image, roll the rig
        aim = centre + rng.uniform(-0.3, 0.3) * d * side + rng.uniform(-0.2, 0.2) * d * up
        T = _look_at(eye, aim, math.radians(rng.uniform(-roll_max_deg, roll_max_deg)))
        ok = True
        for k in names:
            T_wc = T @ T0c[k]
            pc = (X - T_wc[:3, 3]) @ T_wc[:3, :3]
            cam = cameras[k]
            with np.errstate(invalid="ignore"):
                uv = cam.project(pc)
            if not (np.all(pc[:, 2] > 0.5) and np.all(np.isfinite(uv))
                    and np.all((uv >= 4.0) & (uv <= np.array([cam.width_px, cam.height_px]) - 5.0))):
                ok = False
                break
        if ok:
            poses.append(T)
            if len(poses) == n_views:
                return poses
    raise IbiscapeError(f"found only {len(poses)} of {n_views} views showing the whole board in every "
                        "camera; widen distance_m or the field of view")


def render_calibration_views(out: str | os.PathLike[str], cameras: Mapping[str, CameraModel],
                             T_cam0_cam: Mapping[str, npt.ArrayLike] | None = None, *,
                             target: str = "checkerboard", n_views: int = 16, seed: int = 0,
                             distance_m: tuple[float, float] = (3.0, 15.0),
                             tilt_max_deg: float = 35.0, noise: bool = True,
                             start_ns: int = 1_000_000_000, period_ns: int = 50_000_000,
                             overwrite: bool = False) -> Path:
    """Render ``n_views`` calibration views of every camera in ``cameras`` (a rigid rig; camera k
    at ``T_cam0_cam[k]`` in the first camera's frame) into the sequence folder ``out`` (created
    atomically).  Returns ``out``."""
    from ibiscape_eval.io.atomic import atomic_output_dir
    from ibiscape_eval.io.images import write_frame_timestamps, write_png
    from ibiscape_eval.io.sequence import write_sequence_yaml

    from .render import Renderer, RenderOptions
    from .world import build_world

    names = list(cameras)
    if not names:
        raise IbiscapeError("render_calibration_views needs at least one camera")
    rel = {k: np.eye(4) for k in names}
    rel.update({k: np.asarray(v, dtype=np.float64) for k, v in (T_cam0_cam or {}).items()})
    world = build_world(kind="calibration", seed=seed, target=target, bumps=False)
    board = world.target_named(target)
    poses = calibration_view_poses(board, cameras, rel, n_views, seed=seed, distance_m=distance_m,
                                   tilt_max_deg=tilt_max_deg)
    renderer = Renderer(world, options=RenderOptions(noise=noise), seed=seed)
    stamps = start_ns + period_ns * np.arange(n_views, dtype=np.int64)
    out_p = Path(out)
    with atomic_output_dir(out_p, overwrite=overwrite) as tmp:
        for k, name in enumerate(names):
            (tmp / name / "frames").mkdir(parents=True)
            for T, t in zip(poses, stamps, strict=True):
                view = renderer.render_pose(cameras[name], T @ rel[name], int(t), noise_key=k)
                write_png(tmp / name / "frames" / f"{int(t)}.png", view.rgb, photo=True)
            write_frame_timestamps(tmp / name / "timestamps.csv", stamps)
        cams = {name: {**cameras[name].to_kalibr(), "rostopic": f"/{name}/image_raw",
                       "T_body_cam": rel[name]} for name in names}
        doc = {"generator": {"name": "ibiscape_eval.sim.calib_views", "seed": int(seed),
                             "target": target, "n_views": int(n_views)},
               "conventions": {"body": f"the first camera ({names[0]}), OpenCV frame"},
               "imus": {}, "gnss": {}, "cameras": cams, "target": board.kalibr}
        write_sequence_yaml(tmp / "sequence.yaml", doc,
                            comments=["calibration views rendered by ibiscape_eval.sim.calib_views"])
    return out_p
