"""The renderer: rays -> hits (static scene + movers) -> textures -> light -> weather -> sensor.

One :class:`Renderer` per sequence holds the static scene (built once), the cameras and the
weather log.  Per view it finds the static scene's surface of every pixel's ray in a z-buffer
(:mod:`.raster`, open3d's ``cast_rays`` answer but at exact ties; ``RenderOptions(primary=
"open3d")`` casts instead), casts the rays that may see a mover into the movers' scene, takes the
nearer of the static and the movers' hit, interpolates the hit triangle's texture coordinates with the
barycentric coordinates open3d returns, shades (one shadow ray toward the sun per lit pixel
facing it: against the static scene through its grid across the sun, :mod:`.sun_grid`, exact
triangle tests; against the movers, an open3d ``test_occlusions`` any-hit query, only where a
mover's outline seen along the sun covers the point), adds the weather and, for RGB, the sensor's
noise.  Pixels that see a calibration target are rendered again with ``s x s`` rays each and
averaged (antialiasing where it matters, at a fraction of the cost of supersampling the whole
image).

The per-ray work around the casts is two fused numba passes (``_kernels.surfaces`` before the
shadow rays, ``_kernels.finish`` after them) and one for the sensor (``_kernels.quantize``).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.rotations import matrix_from_quat

from .optics import _SKY_DISTANCE_M, fog_beta_per_m, rain_streaks, sensor_output
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
)
from .textures import board_albedo, board_footprint_tables, board_tables, kernel_tables

if TYPE_CHECKING:
    from .raster import RasterMesh
    from .sun_grid import SunGrid

__all__ = ["RenderCamera", "RenderOptions", "RenderedView", "Renderer"]

F32 = npt.NDArray[np.float32]
GRAY_WEIGHTS = np.array([0.2989, 0.587, 0.114], np.float32)
_SHADOW_EPS_M = 0.02
_CAST_THREADS = 1  # open3d casts on the calling thread (see _radiance)


# the board code of a ray (``Renderer._radiance(board_code=True)``): 0 no board, else
# 1 + 4 board + 2 front + lit; the helpers below are its only encoding and decoding
def _board_code(var: npt.NDArray[Any], front: npt.NDArray[Any], lit: npt.NDArray[Any] | int) -> npt.NDArray[np.uint16]:
    """The code of rays seeing board ``var`` (uint), side ``front`` (bool), ``lit`` (bool or 0/1)."""
    return (1 + 4 * var.astype(np.uint16) + 2 * front.astype(np.uint16) + lit).astype(np.uint16)


def _code_board(code: npt.NDArray[np.uint16]) -> npt.NDArray[np.intp]:
    """The board index of codes > 0."""
    return ((code - 1) >> 2).astype(np.intp)


def _code_front(code: npt.NDArray[np.uint16]) -> npt.NDArray[np.bool_]:
    """Whether codes > 0 see a board's front side."""
    return ((code - 1) >> 1) % 2 == 1


def _code_lit(code: npt.NDArray[np.uint16]) -> npt.NDArray[np.uint16]:
    """The codes of lit board rays, 0 elsewhere (a lit code is even)."""
    return np.where((code > 0) & (code % 2 == 0), code, 0).astype(np.uint16)
_MOVER_SHADOW_MARGIN_M = 0.3  # a mover's outline seen along the sun, grown by this
_NEAR_PLANE_M = 0.05  # movers are clipped here when they straddle the camera plane


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
    primary : str
        How a view's one ray per pixel finds its surface in the static scene: ``"raster"`` (a
        z-buffer testing each pixel's own ray against the triangles that may cover it,
        :mod:`.raster`; open3d's hits but for exact ties between coplanar triangles) or
        ``"open3d"`` (Embree's ``cast_rays``, the oracle).  Movers, supersamples and shadow
        rays are ray cast either way.
    """

    shadows: bool = True
    target_supersample: int = 6
    noise: bool = True
    weather_optics: bool = True
    psf_sigma_px: float = 0.7
    primary: str = "raster"

    def __post_init__(self) -> None:
        if self.primary not in ("raster", "open3d"):
            raise IbiscapeError(f"render: primary must be 'raster' or 'open3d', got {self.primary!r}")
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
        self._local = threading.local()  # per thread: the kernels' reusable buffers
        self._sun_grid_cache: SunGrid | None = None  # numba loads with the first render, not here
        self._raster: RasterMesh | None = None
        self._raster_free: list[tuple[np.ndarray, ...]] = []  # the z-buffers of views done

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
        w = weather or self.weather_at(t_ns)
        rad, depth, labels = self._radiance_image(model, T, int(t_ns), w)
        key = 0
        if self.options.noise:
            key = int(np.random.default_rng([self.seed, 0x5E75, noise_key, int(t_ns) & 0xFFFFFFFFFFFF])
                      .integers(0, 2**63))
        rgb = sensor_output(rad, lighting(w).gain, key, noise=self.options.noise)
        return RenderedView(rgb, depth, labels, rad)

    # ------------------------------------------------------------------------------ internals
    def _radiance_image(self, model: CameraModel, T: np.ndarray, t_ns: int,
                             weather: WeatherState | None = None, *, rain: bool = True
                             ) -> tuple[F32, F32, npt.NDArray[np.uint8]]:
        H, W = model.height_px, model.width_px
        w = weather or self.weather_at(t_ns)
        light = lighting(w)
        rays = world_rays(camera_rays(model).reshape(-1, 3), T, out=self._buffer("rays", (H * W, 6)))
        scale = 255.0 * light.gain
        ss = self.options.target_supersample > 1 and bool(self.static.targets)
        blur = self.options.psf_sigma_px > 0  # the blur's output leaves, the radiance buffer stays
        work = self._raster_work(H * W) if self.options.primary == "raster" else None
        try:
            hits: tuple[Any, ...] | None = None
            if work is not None:
                from .raster import cast_camera

                hits = (*cast_camera(self._raster_mesh(), camera_rays(model), T, work, pixel_normals=False), True)
            rad, depth, mat, labels, code = self._radiance(
                rays, t_ns, w, light, self._mover_pixels(model, T, t_ns), scale=scale, board_code=ss,
                rad_buffer=self._buffer("radiance", (H * W, 3)) if blur else None, hits=hits)
        finally:
            if work is not None:
                with self._lock:
                    self._raster_free.append(work)
        if ss:
            self._supersample_targets(model, T, t_ns, w, light, scale, rad, mat, code)
        img = rad.reshape(H, W, 3)
        depth = depth.reshape(H, W)
        if rain and self.options.weather_optics and w.precipitation > 0:
            glow = float(np.clip(255.0 * light.gain * horizon_radiance(w, light).mean() * 1.3, 0, 255))
            cov = rain_streaks(model, T, depth, t_ns, w, seed=self.seed, brightness=1.0)
            if cov is not None:  # in place: ``rad`` is this view's own buffer
                from ._kernels import streaks_into

                streaks_into(rad, cov.reshape(-1), np.float32(glow))
        if blur:
            import cv2

            img = np.asarray(cv2.GaussianBlur(np.ascontiguousarray(img, dtype=np.float32), (0, 0),
                                              self.options.psf_sigma_px,
                                              borderType=cv2.BORDER_REFLECT), dtype=np.float32)
        img = np.asarray(img, dtype=np.float32)
        np.clip(img, 0.0, 255.0, out=img)
        return img, depth, labels.reshape(H, W)

    def _supersample_targets(self, model: CameraModel, T: np.ndarray, t_ns: int, w: WeatherState,
                             light: Lighting, scale: float, rad: F32, mat: npt.NDArray[np.uint8],
                             code: npt.NDArray[np.uint16]) -> None:
        """Replace ``rad`` (H W, 3) in place by the mean of ``s x s`` rays where a pixel that sees
        a calibration board may cover an edge: the board's outline, or a 3x3 neighbourhood whose
        centre samples differ (inside a printed square the pixel's average equals its centre
        sample).

        A pixel whose 3x3 neighbourhood sees one board side, lit alike (``code``, see
        :meth:`_radiance`), is decided from its ``s x s`` rays' footprint on that board's plane
        alone (:meth:`_uniform_board_pixels`): it keeps its centre sample when the footprint lies
        in one uniform patch of the print (a texel of margin; its rays would all return that
        sample's radiance), else it gets the mean of its rays on the plane when the footprint
        lies on the print (no cast at all: ~80 % of the candidates on the calibration drive).
        The others cast a coarse 3 x 3 subset of their rays first
        (:meth:`_plane_supersamples`): the pixels whose coarse rays all see one board side, lit
        alike, get all their rays on that board's plane (also beside the board's outline), those
        whose coarse rays see no board (the background beside the board's outline) the mean of
        the coarse rays, and only the rest cast their other rays (the coarse ones are kept).  The rays of a
        pixel whose neighbours all see one lit board side that meet that side are taken as lit
        without shadow rays.  Like the centre-sample test, this assumes no shadow edge, occluder
        or board corner inside a pixel that neither its neighbours' centre rays nor its coarse rays see."""
        import cv2

        from ._kernels import pixel_means

        H, W = model.height_px, model.width_px
        s = self.options.target_supersample
        on = (mat == MAT["target"]).reshape(H, W).astype(np.uint8)
        if not on.any():
            return
        k = np.ones((3, 3), np.uint8)
        g = (rad @ GRAY_WEIGHTS).reshape(H, W)
        spread = cv2.dilate(g, k) - cv2.erode(g, k)
        edge = (cv2.dilate(on, k) > 0) & ((spread > 0.004 * scale) | (cv2.erode(on, k) == 0))
        rows, cols = np.nonzero(edge)
        c2 = code.reshape(H, W)
        c = c2[rows, cols]
        uniform = (c > 0) & (cv2.dilate(c2, k)[rows, cols] == cv2.erode(c2, k)[rows, cols])
        n = s * s
        if uniform.any():
            cast = self._uniform_board_pixels(model, T, w, light, scale, rows, cols, c, uniform, rad)
            rows, cols, c, uniform = rows[cast], cols[cast], c[cast], uniform[cast]
        if not len(rows):
            return
        sub = world_rays(subpixel_rays(model, rows, cols, s), T).reshape(-1, 6)
        means, decided, clear, coarse_rad, coarse_idx = self._plane_supersamples(sub, s, c, uniform, t_ns, w,
                                                                                 light, scale)
        d = decided | clear
        rad[rows[d] * W + cols[d]] = means[d]
        m = np.flatnonzero(~d)
        others = np.ones(n, bool)
        others[coarse_idx] = False
        rest_idx = np.flatnonzero(others)
        rest = sub.reshape(-1, n, 6)[m[:, None], rest_idx[None, :]].reshape(-1, 6)  # one gather, C-contiguous
        lit = np.repeat(np.where(uniform[m], _code_lit(c[m]), 0).astype(np.uint16), len(rest_idx))
        full = np.empty((len(m), n, 3), np.float32)
        full[:, coarse_idx] = coarse_rad[m]
        full[:, rest_idx] = self._radiance(rest, t_ns, w, light, scale=scale, lit_code=lit)[0].reshape(len(m), -1, 3)
        pixel_means(full.reshape(-1, 3), n, rows[m] * W + cols[m], rad)

    def _uniform_board_pixels(self, model: CameraModel, T: np.ndarray, w: WeatherState, light: Lighting,
                              scale: float, rows: npt.NDArray[np.intp], cols: npt.NDArray[np.intp],
                              c: npt.NDArray[np.uint16], uniform: npt.NDArray[np.bool_], rad: F32
                              ) -> npt.NDArray[np.bool_]:
        """Decide the candidates (``rows``, ``cols``, board code ``c``) whose neighbourhood sees one
        board side (``uniform``) from their ``s x s`` rays' footprints on the board's plane alone
        (``_board_kernels.uniform_board_pixels``: the centre sample where the footprint lies in one
        uniform patch of the print, else the rays' mean on the plane into ``rad`` where the
        footprint lies on the print).  Returns which candidates are left to cast (all but those)."""
        from ._board_kernels import CAST, uniform_board_pixels, uniform_board_pixels_pinhole

        s = self.options.target_supersample
        u = np.flatnonzero(uniform)
        W = model.width_px
        poses, diffs = board_footprint_tables(self.static.targets)
        args = (c[u], poses, board_tables(self.static.targets), diffs, np.asarray(light.sun_dir, np.float64),
                *self._shading(w, light)[1:], np.float32(scale), rows[u] * W + cols[u], rad, np.empty(len(u), np.uint8))
        if model.distortion == "none":  # the rays made in the kernel, pixel by pixel (subpixel_rays' arithmetic)
            Tf = np.asarray(T, np.float64)
            state = uniform_board_pixels_pinhole(
                rows[u].astype(np.float64), cols[u].astype(np.float64), (np.arange(s) + 0.5) / s - 0.5,
                (float(model.fx), float(model.fy), float(model.cx), float(model.cy)), Tf[:3, :3].astype(np.float32),
                Tf[:3, 3].astype(np.float32), *args)
        else:
            state = uniform_board_pixels(world_rays(subpixel_rays(model, rows[u], cols[u], s), T).reshape(-1, 6), s * s,
                                         *args)
        cast = ~uniform
        cast[u[state == CAST]] = True
        return cast

    def _plane_supersamples(self, sub: F32, s: int, c: npt.NDArray[np.uint16], uniform: npt.NDArray[np.bool_],
                            t_ns: int, w: WeatherState, light: Lighting, scale: float
                            ) -> tuple[F32, npt.NDArray[np.bool_], npt.NDArray[np.bool_], F32, npt.NDArray[np.intp]]:
        """Cast a coarse 3 x 3 subset of the ``s x s`` rays ``sub`` (K s s, 6) of K pixels (board
        code ``c`` of their centre, ``uniform`` where their neighbours all see that side) and
        decide the pixels whose coarse rays agree.  Returns the mean radiance (K, 3) of the
        decided pixels (the coarse rays' mean where they see no board), which pixels are decided
        (K,), which see no board with any coarse ray (K,), the coarse rays' radiance (K, 9, 3)
        and their indices in the s x s grid (9,).

        Decided are the pixels whose coarse rays all see one board side lit alike: the mean of all
        ``s x s`` rays where they meet the board's plane, shaded like a cast hit (lit as the
        coarse rays say).  The coarse rays of a ``uniform`` pixel that see its lit board side
        skip their shadow rays and, when all of them do, their shading too
        (:meth:`_lit_side_seen`: such a pixel is decided by its rays' board codes alone)."""
        from ._kernels import board_plane_means, pixel_means

        n = s * s
        q = np.round(np.linspace(0, s - 1, 3)).astype(int)
        coarse_idx = (q[:, None] * s + q[None, :]).ravel()
        K, nc = len(c), len(coarse_idx)
        coarse = np.ascontiguousarray(sub.reshape(K, n, 6)[:, coarse_idx].reshape(-1, 6))
        lit_c = np.where(uniform, _code_lit(c), 0).astype(np.uint16)
        seen = np.repeat(lit_c[:, None], nc, axis=1)
        crad = np.zeros((K, nc, 3), np.float32)  # not needed where the codes alone decide
        cast = np.flatnonzero(~self._lit_side_seen(coarse, lit_c, nc, light))
        rays = np.ascontiguousarray(coarse.reshape(K, nc, 6)[cast].reshape(-1, 6))
        rc, _, _, _, sc = self._radiance(rays, t_ns, w, light, scale=scale, board_code=True,
                                         lit_code=np.repeat(lit_c[cast], nc))
        crad[cast], seen[cast] = rc.reshape(-1, nc, 3), sc.reshape(-1, nc)
        decided = (seen == seen[:, :1]).all(axis=1) & (seen[:, 0] > 0)
        means = np.zeros((K, 3), np.float32)
        done = np.flatnonzero(decided)
        poses, _ = board_footprint_tables(self.static.targets)
        board_plane_means(np.ascontiguousarray(sub.reshape(K, n, 6)[done].reshape(-1, 6)), n, seen[done, 0], poses,
                          board_tables(self.static.targets), np.asarray(light.sun_dir, np.float64),
                          *self._shading(w, light)[1:], np.float32(scale), done, means)
        clear = (seen == 0).all(axis=1)
        none = np.flatnonzero(clear)
        pixel_means(np.ascontiguousarray(crad.reshape(K, nc, 3)[none]).reshape(-1, 3), nc, none, means)
        return means, decided, clear, crad, coarse_idx

    def _lit_side_seen(self, rays: F32, lit_c: npt.NDArray[np.uint16], nc: int, light: Lighting
                       ) -> npt.NDArray[np.bool_]:
        """Which pixels (``nc`` rays each) see with every ray the lit board side ``lit_c`` (0: none)
        that all their neighbours see: from the static scene's cast alone (the board code, no
        shading, no shadow ray; what :meth:`_radiance` would find with ``lit_code``).  None in a
        world with movers."""
        from ._kernels import hit_board_codes

        ok = np.zeros(len(lit_c), bool)
        sel = np.flatnonzero(lit_c > 0)
        if len(self.world.agents) or not len(sel):
            return ok
        rr = np.ascontiguousarray(rays.reshape(-1, nc, 6)[sel].reshape(-1, 6))
        hit = self.static.scene.cast_rays(tensor(rr), nthreads=_CAST_THREADS)
        st = self.static.tables
        flip = np.array([not t.z_toward_observer for t in self.static.targets] or [False], bool)
        codes = hit_board_codes(rr, hit["t_hit"].numpy(), hit["primitive_ids"].numpy(),
                                hit["primitive_normals"].numpy(), st.material, st.variant, flip,
                                np.asarray(light.sun_dir, np.float32), np.empty(len(rr), np.uint16))
        ok[sel] = (codes.reshape(-1, nc) == lit_c[sel, None]).all(axis=1)
        return ok

    def _raster_work(self, n: int) -> tuple[np.ndarray, ...]:
        """A free :func:`.raster.workspace` of at least ``n`` rays (the caller gives it back to
        ``_raster_free``): as many exist as views ever rendered at once, whichever threads."""
        from .raster import workspace

        with self._lock:
            free = self._raster_free
            while free:
                work = free.pop()
                if len(work[0]) >= n:
                    return work
        return workspace(n, pixel_normals=False)

    def _raster_mesh(self) -> RasterMesh:
        """The static scene prepared for :func:`.raster.cast_camera` (built on first use)."""
        from .raster import raster_mesh

        with self._lock:
            if self._raster is None:
                V, T = self.static.occluder_vertices, self.static.triangles
                if V is None or T is None:
                    raise IbiscapeError("render: the static scene keeps no triangles to rasterise")
                self._raster = raster_mesh(V, T)
            return self._raster

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

    def _radiance(self, rays: F32, t_ns: int, w: WeatherState, light: Lighting,
                  mover_rays: npt.NDArray[np.bool_] | None = None, *, scale: float = 1.0,
                  board_code: bool = False, lit_code: npt.NDArray[np.uint16] | None = None,
                  rad_buffer: F32 | None = None, hits: tuple[Any, ...] | None = None
                  ) -> tuple[F32, F32, npt.NDArray[np.uint8], npt.NDArray[np.uint8], npt.NDArray[np.uint16]]:
        """Radiance (N, 3) times ``scale`` of rays (N, 6) with shadows, fog and wet road; the
        z-depth (``inf``: sky), material and label of every ray and, when ``board_code``, which
        board side each ray sees and how it is lit (0: no board, else ``1 + 4 board + 2 front +
        lit``; an empty array otherwise).

        ``mover_rays`` (N,) bool limits the movers' cast to the rays that may see one (the renderer
        passes the pixels inside the movers' projected outlines); ``None`` casts all.  A ray that
        sees the board side ``lit_code`` (N,) names (a lit code as above; 0: none) is taken as lit
        without a shadow ray (the supersamples of a pixel whose neighbours all see that side lit).
        The radiance goes into ``rad_buffer`` (N, 3) when given.  ``hits``: the static scene's
        ``(t_hit, primitive_ids, primitive_uvs, normals, by_triangle)`` of the rays when known (the
        rasterised view, :mod:`.raster`, with its normals per triangle); they are cast otherwise.
        """
        from ._kernels import surfaces, zero_at

        if hits is None:
            r = self.static.scene.cast_rays(tensor(rays), nthreads=_CAST_THREADS)
            hits = (r["t_hit"].numpy(), r["primitive_ids"].numpy(), r["primitive_uvs"].numpy(),
                    r["primitive_normals"].numpy(), False)
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
            m = sc.cast_rays(tensor(rays[sel]), nthreads=_CAST_THREADS)
            map2 = np.full(max(n, 2), -1, np.int32)
            map2[sel] = np.arange(len(sel), dtype=np.int32)
            t2 = m["t_hit"].numpy()
            p2 = m["primitive_ids"].numpy()
            b2, n2 = m["primitive_uvs"].numpy(), m["primitive_normals"].numpy()
        sun = np.asarray(light.sun_dir, np.float32)
        shadows = self.options.shadows and light.e_sun > 0.0
        grid = self._sun_grid(t_ns, sun, movers is not None and shadows)
        targets = self.static.targets
        flip = np.array([not t.z_toward_observer for t in targets] or [False], bool)
        depth, mat, var, labels, uv, front, alb, paved, ndl, amb, srays, spix, smov, count = surfaces(
            rays, hits, (map2, t2, p2, b2, n2), (st.material, st.variant, st.label, st.uv_m,
                                                   self.static.n_triangles),
            (mt.material, mt.variant, mt.label, mt.uv_m), flip, kernel_tables(self.static.ground),
            (sun, shadows, np.float32(_SHADOW_EPS_M)), grid, self._workspace(n))
        if targets:
            board_albedo(mat, uv, var, targets, front, alb)
        if count:
            spix, keep = spix[:count], slice(None)
            if lit_code is not None:  # the rays whose board side lit_code says is lit skip their shadow ray
                keep = (mat[spix] != MAT["target"]) | (_board_code(var[spix], front[spix], 1) != lit_code[spix])
            zero_at(ndl, spix[keep], self._occluded(srays[:count][keep], smov[:count][keep], t_ns))
        rad = self._finish(alb, ndl, amb, depth, rays, paved, uv, w, light, scale, rad_buffer)
        code = np.zeros(0, np.uint16)
        if board_code:
            code = np.where(mat == MAT["target"], _board_code(var, front, ndl > 0.0), 0).astype(np.uint16)
        return rad, depth, mat, labels, code

    def _workspace(self, n: int) -> tuple[np.ndarray, ...]:
        """This thread's buffers for ``_kernels.surfaces`` (grown to ``n`` rays when short)."""
        from ._kernels import workspace

        work = getattr(self._local, "work", None)
        if work is None or len(work[0]) < n:
            work = self._local.work = workspace(n)
        return work

    def _buffer(self, name: str, shape: tuple[int, ...]) -> F32:
        """This thread's float32 buffer ``name`` of ``shape`` (reused from view to view: its
        contents live until the thread asks for ``name`` again)."""
        n = int(np.prod(shape))
        buf = getattr(self._local, name, None)
        if buf is None or buf.size < n:
            buf = np.empty(n, np.float32)
            setattr(self._local, name, buf)
        return buf[:n].reshape(shape)

    def _finish(self, alb: F32, ndl: F32, amb: F32, depth: F32, rays: F32, paved: F32, uv: F32,
                w: WeatherState, light: Lighting, scale: float, out: F32 | None = None) -> F32:
        """``_kernels.finish_into`` (``out``, or a new array) with this renderer's weather optics."""
        from ._kernels import finish_into

        tab, sky, wet_fog = self._shading(w, light)
        return finish_into(alb, ndl, amb, depth, rays, paved, uv, tab, sky, wet_fog, np.float32(scale),
                           np.empty((len(depth), 3), np.float32) if out is None else out)

    def _shading(self, w: WeatherState, light: Lighting) -> tuple[Any, tuple[Any, ...], tuple[Any, ...]]:
        """The noise table and the ``sky`` and ``optics`` arguments of ``_kernels.finish_into``
        with this renderer's weather optics."""
        optics = self.options.weather_optics
        wet = w.wetness / 100.0 if optics else 0.0
        puddle_level = 1.6 - 2.2 * w.precipitation_deposits / 100.0  # more deposits: more water
        if not (optics and w.precipitation_deposits > 0):
            puddle_level = np.inf
        beta = fog_beta_per_m(w.fog_density) if optics else 0.0
        sky = (np.float32(light.e_sun), np.float32(light.e_sky), _ZENITH, _HORIZON, _OVERCAST,
               np.float32(w.cloudiness / 100.0), np.float32(1.6 * light.e_sky + 0.25 * light.e_sun))
        wet_fog = (np.float32(wet), np.float32(puddle_level), np.float32(beta), horizon_radiance(w, light),
                   np.float32(_SKY_DISTANCE_M))
        return kernel_tables(self.static.ground)[0], sky, wet_fog

    def _occluded(self, rays: F32, mover_may: npt.NDArray[np.bool_], t_ns: int) -> npt.NDArray[np.bool_]:
        """Shadow rays (N, 6) toward the sun that hit something: the static scene through its grid
        across the sun (:meth:`_shadow_grid`; open3d's any-hit query without one), the movers'
        scene only for the rays flagged in ``mover_may`` that the static scene left free."""
        grid = self._shadow_grid(rays[0, 3:6]) if len(rays) else None
        if grid is None:
            occ = self.static.scene.test_occlusions(tensor(rays), nthreads=_CAST_THREADS).numpy().astype(bool)
        else:
            occ = grid.occluded(rays, rays[0, 3:6])
        movers = self._mover_scene(t_ns)
        if movers is not None:
            sel = np.flatnonzero(mover_may & ~occ)
            if sel.size:
                occ[sel] = movers[0].test_occlusions(tensor(rays[sel]), nthreads=_CAST_THREADS).numpy().astype(bool)
        return occ

    def _shadow_grid(self, sun: F32) -> SunGrid | None:
        """The static scene's grid across the sun (:mod:`.sun_grid`) answering for ``sun``, built
        again when the sun has moved too far since the last one (``None`` for a sun at or below
        the horizon: the grid leaves the ground out)."""
        from .sun_grid import build_sun_grid

        V, T = self.static.occluder_vertices, self.static.occluder_triangles
        if not float(sun[2]) > 1e-3 or V is None or T is None:
            return None
        with self._lock:
            g = self._sun_grid_cache
            if g is None or not g.covers(sun):
                mat = self.static.tables.material  # the ground quad first, the sentinel last
                g = self._sun_grid_cache = build_sun_grid(V, T, sun, terrain=mat[-1 - len(T):-1] == MAT["ground"])
            return g

    def _sun_grid(self, t_ns: int, sun: F32, want: bool) -> tuple[Any, ...]:
        """Where the movers may cast shadows: their bounding boxes (grown by a margin) seen along
        the sun, rasterised on a plane across the sun direction with axes ``e1, e2``.  Returns the
        raster (rows along ``e2``) with its origin ``a0, b0`` and cell size [m] and ``e1, e2``
        (an empty raster when ``want`` is false)."""
        z = np.float32(0.0)
        e = np.zeros(3, np.float32)
        empty = (np.zeros((1, 1), np.bool_), z, z, np.float32(1.0), e, e)
        ag = self.world.agents
        if not want or len(ag) == 0:
            return empty
        s = np.asarray(sun, np.float64)
        e1 = np.cross(s, [0.0, 0.0, 1.0])
        if np.linalg.norm(e1) < 1e-6:  # sun at the zenith
            e1 = np.array([1.0, 0.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(s, e1)
        pts = self._mover_boxes(t_ns, _MOVER_SHADOW_MARGIN_M).reshape(-1, 3)
        a = (pts @ e1).reshape(-1, 8)
        b = (pts @ e2).reshape(-1, 8)
        lo_a, lo_b = float(a.min()), float(b.min())
        cell = max(0.5, (a.max() - lo_a) / 2048.0, (b.max() - lo_b) / 2048.0)
        ia0 = np.floor((a.min(axis=1) - lo_a) / cell).astype(int)
        ia1 = np.floor((a.max(axis=1) - lo_a) / cell).astype(int)
        ib0 = np.floor((b.min(axis=1) - lo_b) / cell).astype(int)
        ib1 = np.floor((b.max(axis=1) - lo_b) / cell).astype(int)
        grid = np.zeros((ib1.max() + 1, ia1.max() + 1), np.bool_)
        for k in range(len(ia0)):  # one rectangle per mover
            grid[ib0[k]:ib1[k] + 1, ia0[k]:ia1[k] + 1] = True
        return (grid, np.float32(lo_a), np.float32(lo_b), np.float32(cell), e1.astype(np.float32),
                e2.astype(np.float32))

    def _mover_boxes(self, t_ns: int, margin_m: float = 0.0) -> npt.NDArray[np.float64]:
        """Corners (A, 8, 3) of boxes around the movers at ``t_ns`` (upright, as wide as their
        diagonal, grown by ``margin_m``); corner ``4 i + 2 j + k`` has signs ``(i, j)`` in x, y
        and the top when ``k``."""
        ag = self.world.agents
        pos, _ = ag.poses_at(np.array([t_ns], dtype=np.int64))
        r = 0.5 * np.hypot(ag.size_m[:, 0], ag.size_m[:, 1]) + margin_m
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (0, 1)], float)
        half = np.stack([r, r, ag.size_m[:, 2] + 2.0 * margin_m], -1)
        base = pos[:, 0, :] - np.array([0.0, 0.0, margin_m])
        return np.asarray(base[:, None, :] + corners[None] * half[:, None, :])

    def _mover_pixels(self, model: CameraModel, T: np.ndarray, t_ns: int) -> npt.NDArray[np.bool_] | None:
        """Pixels (H W,) inside the projected bounding boxes of the movers (with a margin), or
        ``None`` when a projection fails (then every ray is cast).  A mover straddling the
        camera plane is clipped at the near plane and marks the pixels whose ray direction falls
        inside its outline in normalised image coordinates (exact for any distortion)."""
        from ._kernels import rect_mask

        H, W = model.height_px, model.width_px
        mask = np.zeros((H, W), bool)
        if len(self.world.agents) == 0:
            return mask.ravel()
        pts = self._mover_boxes(t_ns)
        Tcw = np.linalg.inv(T)
        pc = pts @ Tcw[:3, :3].T + Tcw[:3, 3]  # (A, 8, 3)
        front = (pc[..., 2] > _NEAR_PLANE_M).all(axis=1)
        behind = (pc[..., 2] <= _NEAR_PLANE_M).all(axis=1)
        margin = 2 + 0.02 * max(H, W)
        ahead = np.flatnonzero(front)
        uv = model.project(pc[ahead].reshape(-1, 3)).reshape(-1, 8, 2)  # every mover ahead at once
        if not np.isfinite(uv).all():
            return None
        lo = np.floor(uv.min(axis=1) - margin).astype(int)
        hi = np.ceil(uv.max(axis=1) + margin).astype(int)
        for (u0, v0), (u1, v1) in zip(lo.tolist(), hi.tolist(), strict=True):
            if u1 < 0 or v1 < 0 or u0 >= W or v0 >= H:
                continue
            mask[max(v0, 0):min(v1 + 1, H), max(u0, 0):min(u1 + 1, W)] = True
        straddle = np.flatnonzero(~front & ~behind)
        if straddle.size:
            rects = np.array([_clipped_outline(pc[k], _NEAR_PLANE_M) for k in straddle])
            m = margin / min(model.fx, model.fy)
            rects = (rects + np.array([-m, m, -m, m])).astype(np.float32)
            dirs = camera_rays(model)
            rect_mask(dirs, rects, mask, _rect_window(dirs, rects))
        return mask.ravel()


def _rect_window(dirs: F32, rects: F32) -> npt.NDArray[np.int64]:
    """``[r0, r1, c0, c1]``: the rows ``r0:r1`` and columns ``c0:c1`` outside of which no direction
    of ``dirs`` (H, W, 3) lies inside a rectangle ``[x0, x1, y0, y1]`` of ``rects`` (K, 4) (by the
    rays' monotone envelopes per column and row, :func:`.raster.ray_bounds`)."""
    from .raster import ray_bounds

    colmin, colmax, rowmin, rowmax = ray_bounds(dirs)[:4]
    r = rects.astype(np.float64)
    return np.array([np.searchsorted(rowmax, r[:, 2].min(), "left"), np.searchsorted(rowmin, r[:, 3].max(), "right"),
                     np.searchsorted(colmax, r[:, 0].min(), "left"), np.searchsorted(colmin, r[:, 1].max(), "right")],
                    np.int64)


def _clipped_outline(corners: np.ndarray, near: float) -> tuple[float, float, float, float]:
    """``(x0, x1, y0, y1)``: bounding rectangle in normalised image coordinates ``(x/z, y/z)`` of
    the part of a box (8 camera-frame corners, :meth:`Renderer._mover_boxes` order) in front of
    the plane ``z = near`` (its corners there and where its edges cross the plane)."""
    z = corners[:, 2]
    pts = [corners[z >= near]]
    for i in range(8):
        for bit in (1, 2, 4):
            j = i | bit
            if j != i and (z[i] - near) * (z[j] - near) < 0:
                f = (near - z[i]) / (z[j] - z[i])
                pts.append((corners[i] + f * (corners[j] - corners[i]))[None])
    p = np.concatenate(pts)
    x, y = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
    return float(x.min()), float(x.max()), float(y.min()), float(y.max())
