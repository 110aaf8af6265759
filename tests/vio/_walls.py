"""A tiny stand-in renderer for the VIO tests: a straight street of textured walls and a textured
road, imaged by the sequence's stereo rig along its exact ground truth (numpy ray casting and
``cv2.remap`` texture lookup).  Writes ``rgbL``/``rgbR`` with ``timestamps.csv`` and ``frames/``
like the IBISCape layout, and a Kalibr ``camchain-imucam.yaml`` of the rig at that resolution."""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import yaml
from scipy.spatial.transform import Rotation, Slerp

from ibiscape_eval.core.trajectory import Trajectory
from ibiscape_eval.vio.inputs import load_sequence
from ibiscape_eval.vio.rig import StereoRig

TEX_PX_PER_M = 40.0


def _texture(seed: int, h: int, w: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.zeros((h, w), np.float32)
    for sigma, amp in ((1.2, 1.0), (4.0, 1.5), (12.0, 1.5)):
        t += amp * cv2.GaussianBlur(rng.normal(0, 1, (h, w)).astype(np.float32), (0, 0), sigma)
    t = (t - t.min()) / (t.max() - t.min())
    return (40 + 180 * t).astype(np.float32)


def render_street(seq_dir: Path, gt: Trajectory, rig: StereoRig, stamps_ns: np.ndarray, *,
                  origin_xy: tuple[float, float], direction_xy: tuple[float, float],
                  half_width_m: float = 7.0, blank: bool = False) -> Path:
    """Render every stamp for both cameras; returns the camchain path."""
    tex_wall = _texture(1, 480, 6000)   # 12 m high, 150 m long (both walls)
    tex_road = _texture(2, 600, 6000)
    o = np.array([*origin_xy, 0.0])
    d = np.array([*direction_xy, 0.0]) / np.hypot(*direction_xy)
    n = np.array([-d[1], d[0], 0.0])
    t_rel = (gt.stamps_ns - gt.stamps_ns[0]) * 1e-9
    q_rel = (stamps_ns - gt.stamps_ns[0]) * 1e-9
    pos = np.stack([np.interp(q_rel, t_rel, gt.pos_m[:, i]) for i in range(3)], axis=1)
    rot = Slerp(t_rel, Rotation.from_quat(gt.quat_xyzw))(q_rel)
    w, h = rig.size
    chain = {}
    for ci, (name, cam, T_bc) in enumerate((("rgbL", rig.left, rig.T_body_left),
                                            ("rgbR", rig.right, rig.T_body_right))):
        folder = seq_dir / name / "frames"
        folder.mkdir(parents=True, exist_ok=True)
        rays_c = cam.pixel_rays().reshape(-1, 3)
        rows = []
        for k, t in enumerate(stamps_ns):
            R_wb = rot[k].as_matrix()
            T_wc = np.eye(4)
            T_wc[:3, :3] = R_wb @ T_bc[:3, :3]
            T_wc[:3, 3] = R_wb @ T_bc[:3, 3] + pos[k]
            c = T_wc[:3, 3]
            rd = rays_c @ T_wc[:3, :3].T
            # street frame: s along the street, l lateral, z up
            s0, l0 = (c - o) @ d, (c - o) @ n
            ds, dl, dz = rd @ d, rd @ n, rd[:, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                t_wall = np.where(dl > 0, (half_width_m - l0) / dl, (-half_width_m - l0) / dl)
                t_road = np.where(dz < 0, -c[2] / dz, np.inf)
            t_wall = np.where(t_wall > 0, t_wall, np.inf)
            use_road = t_road < t_wall
            th = np.where(use_road, t_road, t_wall)
            s_hit = s0 + th * ds
            l_hit = l0 + th * dl
            z_hit = c[2] + th * dz
            u = np.where(use_road, s_hit, s_hit + np.where(dl > 0, 0.0, 75.0)) * TEX_PX_PER_M
            v = np.where(use_road, (l_hit + half_width_m) * TEX_PX_PER_M * 0.5, z_hit * TEX_PX_PER_M)
            u = np.mod(u + 400.0, 6000.0)
            map_u = u.reshape(h, w).astype(np.float32)
            map_v = v.reshape(h, w).astype(np.float32)
            wall = cv2.remap(tex_wall, map_u, map_v, cv2.INTER_LINEAR, borderValue=128.0)
            road = cv2.remap(tex_road, map_u, map_v, cv2.INTER_LINEAR, borderValue=128.0)
            img = np.where(use_road.reshape(h, w), road, wall)
            img = np.where(np.isfinite(th).reshape(h, w), img, 200.0)  # sky
            if blank:
                img = np.full((h, w), 128.0)
            cv2.imwrite(str(folder / f"{int(t)}.png"), np.clip(img, 0, 255).astype(np.uint8))
            rows.append(f"{int(t)},{int(t)}.png")
        (seq_dir / name / "timestamps.csv").write_text("#timestamp [ns],filename\n" + "\n".join(rows) + "\n")
        entry = cam.to_kalibr()
        entry["T_cam_imu"] = np.linalg.inv(T_bc).tolist()
        entry["rostopic"] = f"/{name}/image_raw"
        chain[f"cam{ci}"] = entry
    calib = seq_dir / "camchain-imucam.yaml"
    calib.write_text(yaml.safe_dump(chain, sort_keys=False))
    return calib


W = 160
N_FRAMES = 120  # 6 s at 20 Hz


def render_street_sequence(src: Path, dst: Path, *, blank: bool = False) -> Path:
    """Copy the generated sequence ``src`` to ``dst`` and render a textured street (or blank
    images) for its first ``N_FRAMES`` frames at ``W`` px; returns the camchain."""
    shutil.copytree(src, dst)
    seq = load_sequence(dst, require_images=False)
    r = seq.rig
    rig = StereoRig(r.left.scaled(W, W), r.right.scaled(W, W), r.T_body_left, r.T_body_right)
    gt = seq.groundtruth
    assert gt is not None
    p0, p1 = gt.pos_m[0], gt.pos_m[-1]
    return render_street(dst, gt, rig, gt.stamps_ns[: 10 * N_FRAMES : 10],
                         origin_xy=(p0[0], p0[1]), direction_xy=(p1[0] - p0[0], p1[1] - p0[1]),
                         blank=blank)
