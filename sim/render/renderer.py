"""The renderer: rays -> hits (static scene + movers) -> textures -> light -> weather -> sensor.

One :class:`Renderer` per sequence holds the static scene (built once), the cameras and the
weather log.  Per view it casts one ray per pixel (``cast_rays(nthreads=0)``), takes the nearer of
the static and the movers' hit, interpolates the hit triangle's texture coordinates with the
barycentric coordinates open3d returns, shades (one shadow ray toward the sun per lit pixel, an
``test_occlusions`` any-hit query), adds the weather and, for RGB, the sensor's noise.  Pixels that
see a calibration target are rendered again with ``s x s`` rays each and averaged (antialiasing
where it matters, at a fraction of the cost of supersampling the whole image).
"""

from __future__ import annotations

import threading
import warnings
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.rotations import matrix_from_quat

from .optics import _SKY_DISTANCE_M, add_sensor_noise, fog, fog_beta_per_m, puddles, rain_streaks
from .rays import camera_model, camera_rays, subpixel_rays, world_rays
from .scene import MAT, StaticScene, TriangleTables, build_static_scene, mover_mesh, open3d, tensor
from .shading import (
    _HORIZON,
    _OVERCAST,
    _ZENITH,
    Lighting,
    WeatherState,
    horizon_radiance,
    lighting,
    sky_radiance,
)
from .textures import albedo, noise_table, sample_bilinear

__all__ = ["RenderCamera", "RenderOptions", "RenderedView", "Renderer"]

F32 = npt.NDArray[np.float32]
GRAY_WEIGHTS = np.array([0.2989, 0.587, 0.114], np.float32)
_SHADOW_EPS_M = 0.02


@dataclass(frozen=True)
class RenderOptions:
    """What to render and how well.

    Attributes
    ----------
    shadows : bool
        Cast a shadow ray toward the sun from every lit pixel.
    target_supersample : int
        ``s``: pixels that see a calibration target get ``s x s`` rays (1 = off).
    noise : bool
        Sensor noise on RGB images (``False`` for ideal images).
    weather_optics : bool
        Fog, rain streaks and the wet road (``False``: clear optics whatever the weather).
    psf_sigma_px : float
        Lens blur: a Gaussian point-spread function of this standard deviation [px] (0 = none).
        Without it every edge is a perfect box-filtered step whose staircase biases corner
        detectors by up to ~0.07 px; 0.7 px is a sharp real lens.
    """

    shadows: bool = True
    target_supersample: int = 6
    noise: bool = True
    weather_optics: bool = True
    psf_sigma_px: float = 0.7

    def __post_init__(self) -> None:
        if not isinstance(self.target_supersample, int) or not 1 <= self.target_supersample <= 8:
            raise IbiscapeError(f"render: target_supersample must be an integer in 1..8, got "
                                f"{self.target_supersample!r}")
        if not (isinstance(self.psf_sigma_px, int | float) and 0.0 <= self.psf_sigma_px <= 5.0):
            raise IbiscapeError(f"render: psf_sigma_px must be in 0..5 px, got {self.psf_sigma_px!r}")


@dataclass(frozen=True, eq=False)
class RenderedView:
    """One rendered view.

    Attributes
    ----------
    rgb : ndarray (H, W, 3) uint8
    depth_m : ndarray (H, W) float32
        z-depth along the optical axis [m]; ``inf`` where the ray sees the sky.
    labels : ndarray (H, W) uint8
        CARLA semantic tag of the surface seen by the pixel centre.
    radiance : ndarray (H, W, 3) float32
        Noise-free 0..255 image before quantisation (what :meth:`Renderer.gray` converts).
    """

    rgb: npt.NDArray[np.uint8]
    depth_m: F32
    labels: npt.NDArray[np.uint8]
    radiance: F32

    def __repr__(self) -> str:
        h, w = self.labels.shape
        return f"RenderedView({w}x{h})"


@dataclass(frozen=True, eq=False)
class RenderCamera:
    """A camera of the rig: folder name, kind, optics and mounting."""

    name: str
    kind: str
    model: CameraModel
    T_body_cam: npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class _Hits:
    """Per-ray results of the nearer hit of the static and the movers' scene (``inf`` t: sky)."""

    t: F32
    mat: npt.NDArray[np.uint8]
    var: npt.NDArray[np.uint8]
    label: npt.NDArray[np.uint8]
    uv: F32
    normal: F32  # unit, facing the viewer
    facing: npt.NDArray[np.bool_]  # the geometric normal faced the viewer
    points: F32
    dn: F32  # |d| of the ray (distance = t |d|)


class Renderer:
    """Render the cameras of one sequence (see the package docstring for the API).

    Parameters
    ----------
    world : World
        Static geometry (built into one open3d scene here, once) and the movers.
    cameras : tuple of RenderCamera
        The rig; :meth:`render` and :meth:`gray` take a camera name.
    motion : optional
        Anything with ``sample(stamps_ns)`` giving ``pos_m`` and ``quat_xyzw`` of ``T_world_body``.
    weather : WeatherLog, optional
        Weather per camera frame, interpolated in time (clear defaults without one).
    options : RenderOptions, optional
    seed : int
        Seeds the sensor noise and the rain drops.
    extra_cars : Boxes, optional
        Static cars added to the scene (the accident scenario's obstacle).

    Raises
    ------
    IbiscapeError
        A camera whose distortion does not invert over its image (naming pixels).
    """

    def __init__(self, world: Any, *, cameras: tuple[RenderCamera, ...] = (), motion: Any = None,
                 weather: Any = None, options: RenderOptions | None = None, seed: int = 0,
                 extra_cars: Any = None) -> None:
        self.world = world
        self.options = options or RenderOptions()
        self.seed = int(seed)
        self.motion = motion
        self.weather = weather
        self._cams = {c.name: c for c in cameras}
        self._cam_index = {c.name: i for i, c in enumerate(cameras)}
        for c in cameras:
            camera_rays(c.model)  # refuse a non-invertible distortion before any work
        self.static: StaticScene = build_static_scene(world, extra_cars=extra_cars)
        self._movers_t: int | None = None
        self._movers: tuple[Any, TriangleTables] | None = None
        self._lock = threading.Lock()  # views of one instant may render on parallel threads

    # ----------------------------------------------------------------------------- construction
    @classmethod
    def from_config(cls, cfg: Any, world: Any, motion: Any, weather: Any = None, *,
                    scenario: dict[str, Any] | None = None, options: RenderOptions | None = None
                    ) -> Renderer:
        """The renderer of a :class:`~ibiscape_eval.sim.config.SimConfig`'s cameras."""
        from ..rig import T_body_camera
        from ..world import Boxes

        cams = tuple(RenderCamera(c.name, c.kind, camera_model(c), T_body_camera(c)) for c in cfg.cameras)
        extra = None
        obstacle = (scenario or {}).get("obstacle")
        if obstacle:
            p, (L, W, H) = obstacle["position_m"], obstacle["size_m"]
            extra = Boxes.from_rows([(p[0], p[1], 0.0, L, W, H, obstacle["yaw_rad"], 3)])
        if options is None:
            r = cfg.render
            options = RenderOptions(shadows=r.shadows, target_supersample=r.target_supersample,
                                    noise=r.sensor_noise and not cfg.ideal,
                                    weather_optics=r.weather_optics, psf_sigma_px=r.psf_sigma_px)
        return cls(world, cameras=cams, motion=motion, weather=weather, options=options,
                   seed=cfg.seed, extra_cars=extra)

    # ---------------------------------------------------------------------------------- queries
    def camera(self, name: str) -> RenderCamera:
        """The camera called ``name``."""
        try:
            return self._cams[name]
        except KeyError:
            raise IbiscapeError(f"no camera {name!r}; the renderer has {sorted(self._cams)}") from None

    def T_world_cam(self, name: str, t_ns: int) -> npt.NDArray[np.float64]:
        """4x4 pose of camera ``name`` at ``t_ns`` (from the motion)."""
        if self.motion is None:
            raise IbiscapeError("the renderer has no motion: use render_pose with an explicit pose")
        st = self.motion.sample(np.array([int(t_ns)], dtype=np.int64))
        T = np.eye(4)
        T[:3, :3] = matrix_from_quat(st.quat_xyzw[0])
        T[:3, 3] = st.pos_m[0]
        return T @ self.camera(name).T_body_cam

    def weather_at(self, t_ns: int) -> WeatherState:
        """Weather state at ``t_ns``, linear between the logged frames (clear defaults without a log)."""
        log = self.weather
        if log is None or len(log) == 0:
            return WeatherState()
        from ..weather import WEATHER_COLUMNS

        st = log.stamps_ns.astype(np.float64)
        vals = {k: float(np.interp(float(t_ns), st, log.values[:, i])) for i, k in enumerate(WEATHER_COLUMNS)}
        names = {f.name for f in fields(WeatherState)}
        return WeatherState(**{k: v for k, v in vals.items() if k in names})

    # ---------------------------------------------------------------------------------- rendering
    def render(self, name: str, t_ns: int) -> RenderedView:
        """RGB (with sensor noise unless ideal), z-depth and labels of camera ``name`` at ``t_ns``."""
        cam = self.camera(name)
        return self.render_pose(cam.model, self.T_world_cam(name, t_ns), t_ns,
                                noise_key=self._cam_index[name])

    def gray(self, name: str, t_ns: int) -> F32:
        """Noise-free linear intensity ``(H, W)`` float32 0..255 (``0.2989 R + 0.587 G + 0.114 B`` of
        the RGB render, weather optics included) of camera ``name`` at ``t_ns``.

        Rain streaks are left out: the DVS model adds rain as its own noise events, and streaks
        moving a whole image width per millisecond would force it to render at its maximum rate.
        """
        cam = self.camera(name)
        rad = self._radiance_image(cam.model, self.T_world_cam(name, t_ns), int(t_ns), rain=False)[0]
        return (rad @ GRAY_WEIGHTS).astype(np.float32)

    def render_pose(self, model: CameraModel, T_world_cam: npt.ArrayLike, t_ns: int = 0, *,
                    noise_key: int = 0, weather: WeatherState | None = None) -> RenderedView:
        """Render any camera at any pose (``T_world_cam`` 4x4, OpenCV camera frame)."""
        T = np.asarray(T_world_cam, dtype=np.float64)
        rad, depth, labels = self._radiance_image(model, T, int(t_ns), weather)
        img = rad
        if self.options.noise:
            light = lighting(weather or self.weather_at(t_ns))
            key = int(np.random.default_rng([self.seed, 0x5E75, noise_key, int(t_ns) & 0xFFFFFFFFFFFF])
                      .integers(0, 2**63))
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", message=".*TBB threading layer.*")
                img = add_sensor_noise(rad, light.gain, key)
        rgb = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        return RenderedView(rgb, depth, labels, rad)

    # ------------------------------------------------------------------------------ internals
    def _radiance_image(self, model: CameraModel, T: np.ndarray, t_ns: int,
                        weather: WeatherState | None = None, *, rain: bool = True
                        ) -> tuple[F32, F32, npt.NDArray[np.uint8]]:
        # numba tries the TBB threading layer first and warns (once) that this machine's TBB is
        # too old before falling back to OpenMP: nothing a user can act on
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*TBB threading layer.*")
            return self._radiance_image_impl(model, T, t_ns, weather, rain=rain)

    def _radiance_image_impl(self, model: CameraModel, T: np.ndarray, t_ns: int,
                             weather: WeatherState | None = None, *, rain: bool = True
                             ) -> tuple[F32, F32, npt.NDArray[np.uint8]]:
        H, W = model.height_px, model.width_px
        w = weather or self.weather_at(t_ns)
        light = lighting(w)
        dirs = camera_rays(model)
        rays = world_rays(dirs, T).reshape(-1, 6)
        rad, hits, labels = self._radiance(rays, t_ns, w, light, self._mover_pixels(model, T, t_ns))
        s = self.options.target_supersample
        if s > 1 and self.static.targets:
            import cv2

            on = (hits.mat == MAT["target"]).reshape(H, W).astype(np.uint8)
            if on.any():
                # only where the pixel may cover an edge: the board's outline, or a 3x3
                # neighbourhood whose centre samples differ (inside a printed square the
                # pixel's average equals its centre sample)
                k = np.ones((3, 3), np.uint8)
                g = (rad @ GRAY_WEIGHTS).reshape(H, W)
                spread = cv2.dilate(g, k) - cv2.erode(g, k)
                grown = cv2.dilate(on, k)
                edge = (grown > 0) & ((spread > 0.004) | (cv2.erode(on, k) == 0))
                rows, cols = np.nonzero(edge)
                sub = world_rays(subpixel_rays(model, rows, cols, s), T).reshape(-1, 6)
                rs, _, _ = self._radiance(sub, t_ns, w, light)
                rad[rows * W + cols] = rs.reshape(len(rows), s * s, 3).mean(axis=1)
        img = (rad * np.float32(255.0 * light.gain)).reshape(H, W, 3)
        depth = hits.t.reshape(H, W)
        if rain and self.options.weather_optics and w.precipitation > 0:
            glow = float(np.clip(255.0 * light.gain * horizon_radiance(w, light).mean() * 1.3, 0, 255))
            cov = rain_streaks(model, T, depth, t_ns, w, seed=self.seed, brightness=1.0)
            if cov is not None:
                a = (0.45 * cov)[..., None]
                img = img * (1.0 - a) + a * np.float32(glow)
        if self.options.psf_sigma_px > 0:
            import cv2

            img = np.asarray(cv2.GaussianBlur(np.ascontiguousarray(img, dtype=np.float32), (0, 0),
                                              self.options.psf_sigma_px,
                                              borderType=cv2.BORDER_REFLECT), dtype=np.float32)
        return np.clip(img, 0.0, 255.0).astype(np.float32), depth, labels.reshape(H, W)

    def _mover_scene(self, t_ns: int) -> tuple[Any, TriangleTables] | None:
        if len(self.world.agents) == 0:
            return None
        with self._lock:
            if self._movers_t != t_ns:
                V, Tr, tables = mover_mesh(self.world, t_ns)
                sc = open3d().t.geometry.RaycastingScene()
                sc.add_triangles(tensor(V), tensor(Tr))
                self._movers, self._movers_t = (sc, tables), t_ns
            return self._movers

    def _cast(self, rays: F32, t_ns: int, mover_rays: npt.NDArray[np.bool_] | None = None) -> _Hits:
        """Nearer hit of the static scene and the movers for every ray.

        ``mover_rays`` (N,) bool limits the movers' cast to the rays that may see one (the renderer
        passes the pixels inside the movers' projected bounding boxes); ``None`` casts all.
        """
        from ._kernels import hit_attributes

        r = self.static.scene.cast_rays(tensor(rays), nthreads=0)
        n = len(rays)
        st = self.static.tables
        movers = self._mover_scene(t_ns)
        map2 = np.full(1, -1, np.int32)
        t2 = np.full(1, np.inf, np.float32)
        p2 = np.zeros(1, np.uint32)
        b2 = np.zeros((1, 2), np.float32)
        n2 = np.zeros((1, 3), np.float32)
        mt = st
        if movers is not None and (mover_rays is None or mover_rays.any()):
            sc, mt = movers
            sel = np.arange(n) if mover_rays is None else np.flatnonzero(mover_rays)
            m = sc.cast_rays(tensor(rays[sel]), nthreads=0)
            map2 = np.full(max(n, 2), -1, np.int32)
            map2[sel] = np.arange(len(sel), dtype=np.int32)
            t2 = m["t_hit"].numpy()
            p2 = m["primitive_ids"].numpy()
            b2, n2 = m["primitive_uvs"].numpy(), m["primitive_normals"].numpy()
        depth, mat, var, lab, uv, nrm, facing, pts, dn = hit_attributes(
            r["t_hit"].numpy(), r["primitive_ids"].numpy(), r["primitive_uvs"].numpy(),
            r["primitive_normals"].numpy(), rays, map2, t2, p2, b2, n2,
            st.material, st.variant, st.label, st.uv_m, mt.material, mt.variant, mt.label, mt.uv_m,
            self.static.n_triangles)
        return _Hits(depth, mat, var, lab, uv, nrm, facing, pts, dn)

    def _occluded(self, rays: F32, t_ns: int) -> npt.NDArray[np.bool_]:
        occ = self.static.scene.test_occlusions(tensor(rays), nthreads=0).numpy().astype(bool)
        movers = self._mover_scene(t_ns)
        if movers is not None:
            near = self._near_movers(rays[:, :3], t_ns)
            if near.any():
                sel = np.flatnonzero(near)
                occ[sel] |= movers[0].test_occlusions(tensor(rays[sel]), nthreads=0).numpy().astype(bool)
        return occ

    def _near_movers(self, pts: F32, t_ns: int, reach_m: float = 25.0) -> npt.NDArray[np.bool_]:
        """Points roughly within ``reach_m`` of a mover (where its shadow may fall): a grid of
        ``reach_m`` cells, each mover marking its cell and the eight around it."""
        pos, _ = self.world.agents.poses_at(np.array([t_ns], dtype=np.int64))
        c = pos[:, 0, :2]
        lo = c.min(axis=0) - 2 * reach_m
        nx, ny = (np.ceil((c.max(axis=0) + 2 * reach_m - lo) / reach_m)).astype(int) + 1
        grid = np.zeros((ny, nx), bool)
        ci = np.floor((c - lo) / reach_m).astype(int)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                grid[ci[:, 1] + dy, ci[:, 0] + dx] = True
        ix = np.floor((pts[:, 0] - np.float32(lo[0])) / np.float32(reach_m)).astype(np.int64)
        iy = np.floor((pts[:, 1] - np.float32(lo[1])) / np.float32(reach_m)).astype(np.int64)
        inside = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
        out = np.zeros(len(pts), bool)
        out[inside] = grid[iy[inside], ix[inside]]
        return out

    def _radiance(self, rays: F32, t_ns: int, w: WeatherState, light: Lighting,
                  mover_rays: npt.NDArray[np.bool_] | None = None
                  ) -> tuple[F32, _Hits, npt.NDArray[np.uint8]]:
        """Linear radiance (N, 3) of rays (N, 6) with fog and wet road, the hits, the labels."""
        from ._kernels import shade_all

        hits = self._cast(rays, t_ns, mover_rays)
        hit = np.isfinite(hits.t)
        n = len(rays)
        front = hits.facing
        tgt = hits.mat == MAT["target"]
        if tgt.any():
            flags = np.array([t.z_toward_observer for t in self.static.targets], bool)
            front = front.copy()
            front[tgt] = hits.facing[tgt] == flags[hits.var[tgt]]
        alb, lab_fix, paved = albedo(hits.mat, hits.var, hits.uv, self.static.ground,
                                     self.static.targets, front)
        labels = np.where(lab_fix > 0, lab_fix, hits.label).astype(np.uint8)
        visible = np.ones(n, bool)
        sun = np.asarray(light.sun_dir, np.float32)
        if self.options.shadows and light.e_sun > 0.0:
            lit = hit & ((hits.normal @ sun) > 0.0)
            li = np.flatnonzero(lit)
            if li.size:
                sr = np.empty((li.size, 6), np.float32)
                sr[:, :3] = hits.points[li] + np.float32(_SHADOW_EPS_M) * hits.normal[li]
                sr[:, 3:] = sun
                visible[li] = ~self._occluded(sr, t_ns)
        optics = self.options.weather_optics
        wet = w.wetness / 100.0 if optics else 0.0
        if wet > 0:
            alb *= (1.0 - np.float32(0.45 * wet) * paved)[:, None]
        c = np.float32(w.cloudiness / 100.0)
        level = np.float32(1.6 * light.e_sky + 0.25 * light.e_sun)
        beta = fog_beta_per_m(w.fog_density) if optics else 0.0
        wet_puddles = optics and w.precipitation_deposits > 0
        rad = shade_all(alb, hits.normal, visible, hits.t, rays, hits.dn, sun, np.float32(light.e_sun),
                        np.float32(light.e_sky), _ZENITH, _HORIZON, _OVERCAST, c, level,
                        np.float32(0.0 if wet_puddles else beta), horizon_radiance(w, light),
                        np.float32(_SKY_DISTANCE_M))
        if wet_puddles:
            pv = np.flatnonzero(paved > 0)
            if pv.size:
                uvp = hits.uv[pv]
                pn = sample_bilinear(noise_table(), uvp[:, 0] * 0.45 + 11.0, uvp[:, 1] * 0.45 + 5.0, wrap=True)
                d = rays[pv, 3:]
                refl = sky_radiance(-d[:, 2] / hits.dn[pv], w, light)
                rad[pv] = puddles(rad[pv], paved[pv], pn, refl, w)
        if wet_puddles and beta > 0:
            dist = np.where(hit, hits.t * hits.dn, np.float32(np.inf)).astype(np.float32)
            rad = fog(rad, dist, beta, horizon_radiance(w, light))
        return rad, hits, labels

    def _mover_pixels(self, model: CameraModel, T: np.ndarray, t_ns: int) -> npt.NDArray[np.bool_] | None:
        """Pixels (H W,) inside the projected bounding boxes of the movers (with a margin), or
        ``None`` when a mover straddles the camera plane (then every ray is cast)."""
        H, W = model.height_px, model.width_px
        mask = np.zeros((H, W), bool)
        ag = self.world.agents
        if len(ag) == 0:
            return mask.ravel()
        pos, _ = ag.poses_at(np.array([t_ns], dtype=np.int64))
        r = 0.5 * np.hypot(ag.size_m[:, 0], ag.size_m[:, 1])
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (0, 1)], float)
        pts = pos[:, 0, None, :] + corners[None] * np.stack([r, r, ag.size_m[:, 2]], -1)[:, None, :]
        Tcw = np.linalg.inv(T)
        pc = pts @ Tcw[:3, :3].T + Tcw[:3, 3]  # (A, 8, 3)
        dist = np.linalg.norm(pc, axis=2).min(axis=1)
        front = (pc[..., 2] > 0.05).all(axis=1)
        behind = (pc[..., 2] <= 0.05).all(axis=1)
        if np.any(~front & ~behind & (dist < 1e4)):
            return None
        margin = 2 + 0.02 * max(H, W)
        for k in np.flatnonzero(front):
            uv = model.project(pc[k])
            if not np.isfinite(uv).all():
                return None
            u0, v0 = np.floor(uv.min(axis=0) - margin).astype(int)
            u1, v1 = np.ceil(uv.max(axis=0) + margin).astype(int)
            if u1 < 0 or v1 < 0 or u0 >= W or v0 >= H:
                continue
            mask[max(v0, 0):min(v1 + 1, H), max(u0, 0):min(u1 + 1, W)] = True
        return mask.ravel()

