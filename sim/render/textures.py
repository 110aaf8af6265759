"""Surface albedo: procedural textures sampled at each hit's texture coordinates.

Texture coordinates come from the triangle's vertex coordinates interpolated with the hit's
barycentric coordinates (``renderer.py``).  Every surface gets two octaves of a periodic value
noise (a fixed 256 x 256 table, sampled bilinearly by a numba kernel) on top of its base colour, plus structure where the real thing has it: lane markings and the calibration pad painted
from the :class:`~ibiscape_eval.sim.render.scene.GroundMap`, paving joints on sidewalks, window
grids on facades, windows on cars, and the printed calibration boards (nearest texel of
:meth:`Target.texture` at 200 px/m, whose texel edges coincide with the printed edges, so the
board is exact; the renderer supersamples the pixels that see a board).

Colours are linear reflectances in 0..1 (RGB).
"""

from __future__ import annotations

import functools
import threading
from typing import Any

import numpy as np
import numpy.typing as npt

from .scene import MAT, GroundMap

__all__ = ["TARGET_PX_PER_M", "albedo", "board_albedo", "board_tables", "kernel_tables", "noise_table", "sample_bilinear"]

F32 = npt.NDArray[np.float32]

#: texels per metre of the board textures (every printed edge of both targets falls on a texel edge)
TARGET_PX_PER_M = 200.0
_FINE_PER_M = 24.0  # noise texels per metre, fine octave
_COARSE_PER_M = 1.2  # coarse octave

_FACADES = np.array([(0.55, 0.50, 0.42), (0.62, 0.58, 0.52), (0.45, 0.33, 0.26), (0.70, 0.68, 0.62),
                     (0.40, 0.42, 0.45), (0.58, 0.44, 0.32), (0.50, 0.52, 0.48), (0.66, 0.60, 0.45)],
                    np.float32)
_CARS = np.array([(0.55, 0.06, 0.05), (0.08, 0.16, 0.45), (0.80, 0.80, 0.78), (0.05, 0.05, 0.06),
                  (0.55, 0.56, 0.58), (0.75, 0.60, 0.08)], np.float32)
_CLOTHES = np.array([(0.15, 0.20, 0.45), (0.55, 0.10, 0.12), (0.20, 0.20, 0.20), (0.60, 0.55, 0.40),
                     (0.10, 0.35, 0.20), (0.70, 0.70, 0.70)], np.float32)
_CROWNS = np.array([(0.10, 0.26, 0.07), (0.16, 0.30, 0.08), (0.08, 0.20, 0.10)], np.float32)
_PLAIN = {MAT["roof"]: (0.33, 0.31, 0.30), MAT["pole"]: (0.42, 0.42, 0.44),
          MAT["trunk"]: (0.24, 0.16, 0.10), MAT["stand"]: (0.30, 0.30, 0.32),
          MAT["block"]: (0.24, 0.31, 0.15), MAT["sidewalk"]: (0.52, 0.50, 0.47)}
# (fine, coarse) noise amplitudes per material
_NOISE_AMP = {MAT["ground"]: (0.22, 0.18), MAT["block"]: (0.30, 0.25), MAT["sidewalk"]: (0.12, 0.10),
              MAT["facade"]: (0.10, 0.12), MAT["roof"]: (0.15, 0.15), MAT["pole"]: (0.05, 0.05),
              MAT["crown"]: (0.55, 0.30), MAT["trunk"]: (0.30, 0.10), MAT["car"]: (0.03, 0.03),
              MAT["car_roof"]: (0.03, 0.03), MAT["pedestrian"]: (0.15, 0.05), MAT["stand"]: (0.1, 0.1)}


@functools.lru_cache(maxsize=1)
def noise_table() -> F32:
    """Periodic 256 x 256 value noise, zero mean, unit standard deviation (fixed seed)."""
    rng = np.random.default_rng(20260923)
    white = rng.standard_normal((256, 256))
    k = np.fft.fftfreq(256)
    kk = k[:, None] ** 2 + k[None, :] ** 2
    smooth = np.fft.ifft2(np.fft.fft2(white) * np.exp(-2.0 * (np.pi * 1.2) ** 2 * kk)).real
    smooth = (smooth - smooth.mean()) / smooth.std()
    out = smooth.astype(np.float32)
    out.setflags(write=False)
    return out


def sample_bilinear(table: np.ndarray, x: npt.ArrayLike, y: npt.ArrayLike, *, wrap: bool) -> np.ndarray:
    """Bilinear samples of ``table`` (H, W[, C]) at texel coordinates ``x, y`` (N,) (texel centres
    at integers), periodic (``wrap``) or clamped to the border.  Returns float32 (N,) or (N, C)."""
    from ._kernels import bilinear

    t = np.asarray(table)  # uint8 or float32: numba compiles one kernel per type
    t3 = t[..., None] if t.ndim == 2 else t
    out = bilinear(np.ascontiguousarray(t3), np.asarray(x, np.float32).ravel(),
                   np.asarray(y, np.float32).ravel(), wrap)
    return out[:, 0] if t.ndim == 2 else out


#: One board texture is built at a time: the stereo views render on two threads, and both asked
#: for the textures at their first frame (the AprilGrid's temporaries twice: +50 MB of peak memory)
_TEXTURE_LOCK = threading.Lock()


def _target_texture(target: Any) -> npt.NDArray[np.float32]:
    """The board's printed texture as float32 reflectance (built once per board: cached)."""
    with _TEXTURE_LOCK:
        return _target_texture_cached(target)


@functools.lru_cache(maxsize=8)
def _target_texture_cached(target: Any) -> npt.NDArray[np.float32]:
    tex = target.texture(TARGET_PX_PER_M).astype(np.float32) / 255.0
    # printed paper: black is not perfectly black, white is not perfectly white
    return (0.04 + 0.84 * tex).astype(np.float32)


@functools.lru_cache(maxsize=1)
def _tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    plain = np.zeros((256, 3), np.float32)
    for m, c in _PLAIN.items():
        plain[m] = c
    amp_f = np.zeros(256, np.float32)
    amp_c = np.zeros(256, np.float32)
    for m, (a, b) in _NOISE_AMP.items():
        amp_f[m], amp_c[m] = a, b
    return plain, amp_f, amp_c


def kernel_tables(ground: GroundMap) -> tuple[Any, ...]:
    """The texture arguments of the albedo kernels (``_kernels.albedo_all`` and
    ``_kernels.surfaces``), in their order: noise table, fine and coarse noise texels per metre,
    the ground map with its origin and resolution, per-material base colours and noise amplitudes,
    facade, car, clothes and tree-crown colours."""
    plain, amp_f, amp_c = _tables()
    g = ground
    return (noise_table(), np.float32(_FINE_PER_M), np.float32(_COARSE_PER_M), g.image,
            np.float32(g.origin_m[0]), np.float32(g.origin_m[1]), np.float32(g.res_m), plain, amp_f, amp_c,
            _FACADES, _CARS, _CLOTHES, _CROWNS)


def albedo(mat: np.ndarray, var: np.ndarray, uv: np.ndarray, ground: GroundMap, targets: tuple[Any, ...],
           front: np.ndarray) -> tuple[F32, np.ndarray, np.ndarray]:
    """Albedo ``(N, 3)`` float32, label corrections ``(N,)`` (0 = keep the triangle's label) and a
    'paved road' weight ``(N,)`` 0..1 (wet-road effects) for hits with material ``mat`` (N,),
    variant ``var`` (N,), texture coordinates ``uv`` (N, 2) [m] and a front-face flag (N,).

    Every surface but the boards is one pass of a numba kernel (``_kernels.albedo_all``; the
    renderer's fused ``_kernels.surfaces`` computes the same per hit): base colour per material and
    variant, window grids, paving joints, car windows, clothes, the ground map (asphalt, pad,
    markings, grass) and two noise octaves.  Boards are looked up by :func:`board_albedo`.
    """
    from ._kernels import albedo_all

    col, label, paved = albedo_all(mat, var, np.ascontiguousarray(uv, dtype=np.float32), kernel_tables(ground))
    board_albedo(mat, uv, var, targets, front, col)
    return col, label, paved


def board_albedo(mat: np.ndarray, uv: np.ndarray, var: np.ndarray, targets: tuple[Any, ...],
                 front: np.ndarray, col: np.ndarray) -> None:
    """Fill ``col`` (N, 3) in place where ``mat`` is a calibration board: the nearest texel of the
    board's printed texture on its observed side (``front``), plain grey on its back (one pass of
    ``_kernels.board_texels``)."""
    from ._kernels import board_texels

    if targets:
        board_texels(mat, np.ascontiguousarray(uv, dtype=np.float32), var, front, board_tables(targets),
                     col)


@functools.lru_cache(maxsize=8)
def board_tables(targets: tuple[Any, ...]) -> tuple[tuple[Any, ...], ...]:
    """The ``boards`` argument of ``_kernels.board_texels``: per board its texture, the
    texture's first column / row edge [m], row direction and texels per metre (the arithmetic of
    ``Target.texture_px_from_target``)."""
    out = []
    for t in targets:
        flipped = bool(t.z_toward_observer)  # y up as seen: rows grow with decreasing y
        y0 = float(t.board_max_m[1]) if flipped else float(t.board_min_m[1])
        out.append((np.ascontiguousarray(_target_texture(t)), float(t.board_min_m[0]), y0,
                    -1.0 if flipped else 1.0, float(TARGET_PX_PER_M)))
    return tuple(out)


@functools.lru_cache(maxsize=8)
def board_footprint_tables(targets: tuple[Any, ...]) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """The board arguments of ``_board_kernels.uniform_board_pixels`` besides :func:`board_tables`: the
    poses ``T_world_target`` (B, 4, 4) and per board the summed-area table of its texels that
    differ from a neighbour (``_kernels.texel_diff_table``)."""
    from ._kernels import texel_diff_table

    poses = np.ascontiguousarray([t.T_world_target for t in targets], dtype=np.float64)
    return poses, tuple(texel_diff_table(np.ascontiguousarray(_target_texture(t))) for t in targets)
