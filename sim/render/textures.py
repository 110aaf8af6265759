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
from typing import Any

import numpy as np
import numpy.typing as npt

from .labels import TAG
from .scene import MAT, GroundMap

__all__ = ["TARGET_PX_PER_M", "albedo", "noise_table", "sample_bilinear"]

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


@functools.lru_cache(maxsize=8)
def _target_texture(target: Any) -> npt.NDArray[np.float32]:
    tex = target.texture(TARGET_PX_PER_M).astype(np.float32) / 255.0
    # printed paper: black is not perfectly black, white is not perfectly white
    return (0.04 + 0.84 * tex).astype(np.float32)


def _frac(x: np.ndarray) -> np.ndarray:
    return x - np.floor(x)


def albedo(mat: np.ndarray, var: np.ndarray, uv: np.ndarray, ground: GroundMap, targets: tuple[Any, ...],
           front: np.ndarray) -> tuple[F32, np.ndarray, np.ndarray]:
    """Albedo ``(N, 3)`` float32, label corrections ``(N,)`` (0 = keep the triangle's label) and a
    'paved road' weight ``(N,)`` 0..1 (wet-road effects) for hits with material ``mat`` (N,),
    variant ``var`` (N,), texture coordinates ``uv`` (N, 2) [m] and a front-face flag (N,)."""
    n = len(mat)
    col = np.zeros((n, 3), np.float32)
    label = np.zeros(n, np.uint8)
    paved = np.zeros(n, np.float32)
    tab = noise_table()
    u, v = uv[:, 0], uv[:, 1]
    fine = sample_bilinear(tab, u * _FINE_PER_M, v * _FINE_PER_M, wrap=True)
    coarse = sample_bilinear(tab, u * _COARSE_PER_M + 97.0, v * _COARSE_PER_M + 31.0, wrap=True)
    amp_f = np.zeros(256, np.float32)
    amp_c = np.zeros(256, np.float32)
    for m, (a, b) in _NOISE_AMP.items():
        amp_f[m], amp_c[m] = a, b
    mod = np.clip(1.0 + amp_f[mat] * fine + amp_c[mat] * coarse, 0.15, 2.5).astype(np.float32)

    present = set(np.unique(mat).tolist())
    for m in present:
        idx = np.flatnonzero(mat == m)
        if m in _PLAIN:
            col[idx] = _PLAIN[m]
        if m == MAT["sidewalk"]:  # 0.5 m paving slabs with dark joints
            j = (np.minimum(_frac(u[idx] * 2.0), _frac(v[idx] * 2.0)) < 0.04)
            col[idx[j]] *= 0.6
        elif m == MAT["ground"]:
            _ground(idx, u, v, ground, col, label, paved, coarse)
        elif m == MAT["facade"]:
            _facade(idx, u, v, var, col)
        elif m == MAT["crown"]:
            col[idx] = _CROWNS[var[idx] % len(_CROWNS)]
        elif m in (MAT["car"], MAT["car_roof"]):
            vi = var[idx]
            col[idx] = _CARS[vi % 100 % len(_CARS)]
            cabin = (vi >= 100) & (m == MAT["car"])
            col[idx[cabin]] = (0.06, 0.07, 0.09)  # windows all round the cabin
            body = (vi < 100) & (m == MAT["car"])
            stripe = body & (np.abs(v[idx] - 0.18) < 0.08)  # dark bumper / rocker band
            col[idx[stripe]] *= 0.25
        elif m == MAT["pedestrian"]:
            vi = var[idx]
            col[idx] = _CLOTHES[vi % len(_CLOTHES)]
            head = v[idx] > 1.5
            col[idx[head]] = (0.55, 0.40, 0.32)
            legs = v[idx] < 0.85
            col[idx[legs]] = (0.12, 0.12, 0.16)
        elif m == MAT["target"]:
            _target(idx, uv, var, targets, front, col)
            mod[idx] = 1.0
    col *= mod[:, None]
    return col, label, paved


def _ground(idx: np.ndarray, u: np.ndarray, v: np.ndarray, ground: GroundMap, col: np.ndarray,
            label: np.ndarray, paved: np.ndarray, coarse: np.ndarray) -> None:
    g = ground
    cov = sample_bilinear(g.image, (u[idx] - g.origin_m[0]) / g.res_m - 0.5,
                          (v[idx] - g.origin_m[1]) / g.res_m - 0.5, wrap=False).astype(np.float32) / 255.0
    asphalt, pad, mark = cov[:, 0], cov[:, 1], cov[:, 2]
    grass = np.array([0.22, 0.29, 0.13], np.float32) * (1.0 + 0.25 * coarse[idx, None])
    c = grass * (1.0 - np.maximum(asphalt, pad))[:, None]
    c += asphalt[:, None] * np.array([0.19, 0.19, 0.20], np.float32)
    c += pad[:, None] * np.array([0.46, 0.45, 0.42], np.float32)
    road = np.maximum(asphalt, pad)
    c = c * (1.0 - mark[:, None]) + mark[:, None] * np.array([0.85, 0.85, 0.80], np.float32)
    col[idx] = c
    paved[idx] = road
    label[idx] = np.where(mark > 0.5, TAG["RoadLine"], np.where(road > 0.5, TAG["Road"], TAG["Terrain"]))


def _facade(idx: np.ndarray, u: np.ndarray, v: np.ndarray, var: np.ndarray, col: np.ndarray) -> None:
    vi = var[idx]
    col[idx] = _FACADES[vi % len(_FACADES)]
    pitch_u = 2.6 + 0.3 * (vi % 3)
    fu = _frac(u[idx] / pitch_u)
    fv = _frac(v[idx] / 3.1)
    win = (np.abs(fu - 0.5) < 0.24) & (np.abs(fv - 0.55) < 0.24) & (v[idx] > 2.0)
    frame = (np.abs(fu - 0.5) < 0.29) & (np.abs(fv - 0.55) < 0.29) & (v[idx] > 2.0) & ~win
    door = (v[idx] < 2.2) & (np.abs(_frac(u[idx] / 9.0) - 0.5) < 0.07)
    col[idx[frame]] = (0.80, 0.80, 0.78)
    # glass: dark, slightly blue, varying pane to pane
    pane = (np.floor(u[idx] / pitch_u) * 7 + np.floor(v[idx] / 3.1) * 13) % 5
    glass = np.stack([0.05 + 0.03 * pane, 0.07 + 0.03 * pane, 0.10 + 0.035 * pane], -1).astype(np.float32)
    col[idx[win]] = glass[win]
    col[idx[door]] = (0.18, 0.12, 0.08)


def _target(idx: np.ndarray, uv: np.ndarray, var: np.ndarray, targets: tuple[Any, ...],
            front: np.ndarray, col: np.ndarray) -> None:
    for k in np.unique(var[idx]).tolist():
        sel = idx[var[idx] == k]
        t = targets[k]
        tex = _target_texture(t)
        px = t.texture_px_from_target(uv[sel].astype(np.float64), TARGET_PX_PER_M)
        # nearest texel: texel centres are at integers and every printed edge is a texel edge
        c = np.clip(np.floor(px[:, 0] + 0.5).astype(np.intp), 0, tex.shape[1] - 1)
        r = np.clip(np.floor(px[:, 1] + 0.5).astype(np.intp), 0, tex.shape[0] - 1)
        val = tex[r, c]
        val = np.where(front[sel], val, 0.35)  # the back of the board is grey
        col[sel] = val[:, None]
