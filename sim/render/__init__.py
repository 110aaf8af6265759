"""CPU rendering of the simulated world with open3d's ``RaycastingScene`` (Embree).

API (for the generator, the DVS model, calibration and VIO users)::

    from ibiscape_eval.sim.render import Renderer, RenderOptions
    r = Renderer.from_config(cfg, world, motion, weather_log)   # once per sequence
    view = r.render("rgbL", t_ns)            # RenderedView: rgb uint8 (H, W, 3), depth_m float32
                                             # (H, W) z-depth, inf = sky), labels uint8 (H, W) CARLA tags
    g = r.gray("davisL", t_ns)               # float32 (H, W), linear 0..255 intensity of the noise-free
                                             # RGB render: 0.2989 R + 0.587 G + 0.114 B, weather optics
                                             # (fog, rain streaks, wet road, dim light) included, no
                                             # sensor noise, no depth/segmentation work (cheap path)
    r.camera("rgbL")                         # RenderCamera: name, kind, model (core CameraModel),
                                             # T_body_cam (4x4)
    r.T_world_cam("rgbL", t_ns)              # 4x4 pose of the OpenCV camera frame at t_ns
    r.render_pose(model, T_world_cam, t_ns)  # any camera anywhere (tests, calibration views)

``t_ns`` may be any int64 time inside the sequence (the DVS model asks for times between frames):
the vehicle pose comes from the motion, movers from their closed-form paths, the weather state is
interpolated linearly between the logged camera frames.  Same inputs -> identical arrays.

Modules (one concern each): ``rays`` (camera rays from :class:`~ibiscape_eval.core.camera.CameraModel`,
pixel-centre convention), ``scene`` (static meshes from the world, per-triangle material, label and
texture coordinates; movers in a second small scene), ``textures`` (procedural surfaces, targets),
``shading`` (sun, sky, ambient, shadows), ``optics`` (fog, rain streaks, wet road, exposure, sensor
noise), ``labels`` (CARLA's semantic tags and the CityScapes palette), ``renderer`` (orchestration),
``_kernels`` (numba loops of the per-ray work), ``sequence`` (every camera of a sequence into the
IBISCape layout, called by ``sim.generate(..., render=True)``), ``preview`` (contact sheets).

Rain streaks are part of :meth:`Renderer.render` but not of :meth:`Renderer.gray`: the DVS model
adds rain as its own noise events (streaks crossing the image in a millisecond would force it to
render at its maximum rate).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ibiscape_eval.core.lazy import lazy_exports

_EXPORTS: dict[str, str] = {
    "Renderer": "renderer",
    "RenderOptions": "renderer",
    "RenderedView": "renderer",
    "RenderCamera": "renderer",
    "CARLA_TAGS": "labels",
    "CITYSCAPES_PALETTE": "labels",
    "camera_rays": "rays",
    "camera_model": "rays",
    "contact_sheet": "preview",
    "render_cameras": "sequence",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)


if TYPE_CHECKING:  # pragma: no cover
    from .labels import CARLA_TAGS, CITYSCAPES_PALETTE  # noqa: F401
    from .preview import contact_sheet  # noqa: F401
    from .rays import camera_model, camera_rays  # noqa: F401
    from .renderer import RenderCamera, RenderedView, Renderer, RenderOptions  # noqa: F401
    from .sequence import render_cameras  # noqa: F401
