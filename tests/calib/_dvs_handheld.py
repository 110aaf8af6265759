"""A stereo DVS waved in front of the simulator's calibration board (E2CALIB's use case), with truth.

The rig moves smoothly between ``n_keys`` varied key poses (``sim.calib_views.calibration_view_poses``:
the whole board in view of every camera, tilted up to 35 deg), ``segment_s`` seconds per segment
(rotation slerp, position and slerp parameter on a smoothstep), and never stops in between.  The
simulator's renderer gives the noise-free grey image at any time and its DVS model
(``sim.dvs.write_dvs_camera``, ESIM's adaptive sampling) turns it into IBISCape event folders; the
``sequence.yaml`` holds the true cameras (``T_body_cam``: body = the first camera) and the target.
Also used by ``benchmarks/bench_calib.py``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import yaml

from ibiscape_eval.core.camera import CameraModel


def handheld_poses(keys: list[np.ndarray], segment_s: float):
    """``pose(t_s)`` -> ``T_world_cam0`` along the key poses (``t_s`` in [0, (len(keys) - 1) * segment_s])."""
    from scipy.spatial.transform import Rotation, Slerp

    n = len(keys)
    rots = Rotation.from_matrix(np.stack([k[:3, :3] for k in keys]))
    slerp = Slerp(np.arange(n, dtype=np.float64), rots)
    pos = np.stack([k[:3, 3] for k in keys])

    def pose(t_s: float) -> np.ndarray:
        u = min(max(t_s / segment_s, 0.0), n - 1.0)
        i = min(int(u), n - 2)
        f = u - i
        # an ease that keeps moving at the key poses: ds/df = 1 - 0.5 cos(2 pi f), speed 1:3
        s = f - 0.5 * np.sin(2 * np.pi * f) / (2 * np.pi)
        T = np.eye(4)
        T[:3, :3] = slerp([i + s]).as_matrix()[0]
        T[:3, 3] = (1 - s) * pos[i] + s * pos[i + 1]
        return T

    return pose


def write_handheld_dvs_sequence(root: Path, cameras: Mapping[str, CameraModel],
                                T_cam0_cam: Mapping[str, np.ndarray], *, target: str = "checkerboard",
                                n_keys: int = 5, segment_s: float = 1.0, rate_hz: float = 20.0,
                                seed: int = 3, distance_m: tuple[float, float] = (4.0, 9.0),
                                max_internal_rate_hz: float = 2000.0) -> Path:
    """Write the sequence folder ``root`` (cameras named like ``davisL``) and return it."""
    from ibiscape_eval.sim.calib_views import calibration_view_poses
    from ibiscape_eval.sim.config import CameraSpec
    from ibiscape_eval.sim.dvs import DvsConfig, write_dvs_camera
    from ibiscape_eval.sim.render import Renderer, RenderOptions
    from ibiscape_eval.sim.world import build_world

    names = list(cameras)
    rel = {k: np.asarray(T_cam0_cam.get(k, np.eye(4)), np.float64) for k in names}
    world = build_world(kind="calibration", seed=seed, target=target, bumps=False)
    board = world.target_named(target)
    keys = calibration_view_poses(board, cameras, rel, n_keys, seed=seed, distance_m=distance_m)
    pose = handheld_poses(keys, segment_s)
    renderer = Renderer(world, options=RenderOptions(noise=False), seed=seed)
    t0 = 1_000_000_000
    dur_ns = round((n_keys - 1) * segment_s * 1e9)
    period = round(1e9 / rate_hz)
    stamps = t0 + period * np.arange(dur_ns // period + 1, dtype=np.int64)
    cfg = DvsConfig(max_internal_rate_hz=max_internal_rate_hz)
    root.mkdir(parents=True, exist_ok=False)
    dvs_docs = {}
    for k, name in enumerate(names):
        cam = cameras[name]

        def gray(t_ns: int, cam: CameraModel = cam, T_c0_c: np.ndarray = rel[name]) -> np.ndarray:
            rad = renderer.render_pose(cam, pose((t_ns - t0) / 1e9) @ T_c0_c, int(t_ns)).radiance
            return (0.2989 * rad[..., 0] + 0.587 * rad[..., 1] + 0.114 * rad[..., 2]).astype(np.float32)

        spec = CameraSpec(name=name, kind="dvs", width_px=cam.width_px, height_px=cam.height_px,
                          rate_hz=rate_hz)
        res = write_dvs_camera(gray, spec, stamps, root / name, dvs_config=cfg, rng=np.random.default_rng(k))
        dvs_docs[name] = res.to_dict()
    cams = {name: {**cameras[name].to_kalibr(), "rostopic": f"/{name}/image_raw", "kind": "dvs",
                   "T_body_cam": rel[name].tolist(), "dvs": dvs_docs[name]} for name in names}
    doc = {"generator": {"name": "tests/calib/_dvs_handheld.py", "seed": seed, "target": target},
           "conventions": {"body": f"the first camera ({names[0]}), OpenCV frame"}, "imus": {}, "gnss": {},
           "cameras": cams, "target": board.kalibr}
    (root / "sequence.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    return root
