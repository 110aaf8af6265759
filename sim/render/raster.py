"""Primary visibility without a ray tracer: a z-buffer over each pixel's own ray.

:func:`cast_camera` returns for the rays of one camera image what open3d's
``RaycastingScene.cast_rays`` returns for them (``t_hit``, ``primitive_ids``, ``primitive_uvs``,
``primitive_normals``), computed by walking the triangles instead of the pixels:

- the scene's vertices go into the camera frame (float64, relative to the camera centre);
- per triangle, the outline in normalised image coordinates ``(x/z, y/z)`` (clipped at
  :data:`NEAR_M` in front of the camera) bounds the pixels it can cover: a pixel column (row) is
  visited when the range of its rays' ``x`` (``y``) over the image meets the outline's range
  (ranges made monotone over the columns (rows), so any invertible distortion is covered);
- each visited pixel's ray ``d`` (the renderer's precomputed undistorted direction ``(x, y, 1)``)
  is tested exactly: ``w_i = d . (V_j x V_k)`` all of one sign puts the ray inside the triangle,
  ``t = V_0 . (V_1 x V_2) / sum(w)`` is the hit's z-depth (the ray parameter of ``d``), the
  barycentric coordinates are ``w_i / sum(w)``.  Shared edges use the same cross product (one
  negated), so a ray on an edge is claimed by both triangles: no cracks.  The nearest ``t`` wins;
  between coplanar triangles (``t`` equal within 1e-9, float64 arithmetic) the lower triangle id,
  where Embree's float32 arithmetic picks one by rounding (the town's overlapping facades).

Chunks of consecutive triangles outside the view are skipped by their bounding boxes.  Rays
within :data:`NEAR_M` of the camera centre do not see surfaces there (open3d's cast would).  The
kernels run on one thread (the stereo views render on two threads; see ``_kernels``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
import numpy.typing as npt

__all__ = ["NEAR_M", "RasterMesh", "cast_camera", "raster_mesh"]

F32 = npt.NDArray[np.float32]
NEAR_M = 1e-3  #: surfaces closer than this to the camera centre are not seen
_CHUNK = 64  # consecutive triangles culled together by their bounding box
_TIE = 1.0 - 1e-9  # a later triangle must be nearer by this factor: coplanar ties go to the lower id


@dataclass(frozen=True, eq=False)
class RasterMesh:
    """A triangle mesh prepared for :func:`cast_camera`: vertices (V, 3) float64, triangles (T, 3)
    int32, unit normals (T, 3) float32 (as open3d's ``primitive_normals``), chunk bounds
    ``lo``, ``hi`` (C, 3) float64 of the triangles ``[64 c, 64 c + 64)``."""

    vertices: npt.NDArray[np.float64]
    triangles: npt.NDArray[np.int32]
    normals: F32
    lo: npt.NDArray[np.float64]
    hi: npt.NDArray[np.float64]


def raster_mesh(vertices: npt.ArrayLike, triangles: npt.ArrayLike) -> RasterMesh:
    """The :class:`RasterMesh` of a mesh (float32 vertices as open3d holds them)."""
    V32 = np.ascontiguousarray(vertices, dtype=np.float32)
    T = np.ascontiguousarray(triangles, dtype=np.int32).reshape(-1, 3)
    a, b, c = V32[T[:, 0]], V32[T[:, 1]], V32[T[:, 2]]
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0).astype(np.float32)
    nc = -(-len(T) // _CHUNK)
    pts = np.full((nc * _CHUNK, 3, 3), np.nan)
    pts[:len(T)] = np.stack([a, b, c], 1)
    pts = pts.reshape(nc, _CHUNK * 3, 3)
    lo, hi = np.nanmin(pts, axis=1), np.nanmax(pts, axis=1)
    return RasterMesh(V32.astype(np.float64), T, n, lo, hi)


_BOUNDS: dict[int, tuple[np.ndarray, tuple[np.ndarray, ...]]] = {}


def ray_bounds(dirs: F32) -> tuple[np.ndarray, ...]:
    """``colmin, colmax, rowmin, rowmax``: per column (row) the monotone envelope of the rays'
    normalised ``x`` (``y``) over the image (cached per ray table: the renderer's are cached)."""
    hit = _BOUNDS.get(id(dirs))
    if hit is not None and hit[0] is dirs:
        return hit[1]
    x, y = dirs[..., 0].astype(np.float64), dirs[..., 1].astype(np.float64)
    # monotone ranges: the columns from c on reach down to colmin[c], those up to c reach colmax[c]
    colmin = np.minimum.accumulate(x.min(axis=0)[::-1])[::-1].copy()
    colmax = np.maximum.accumulate(x.max(axis=0))
    rowmin = np.minimum.accumulate(y.min(axis=1)[::-1])[::-1].copy()
    rowmax = np.maximum.accumulate(y.max(axis=1))
    if len(_BOUNDS) >= 32:
        _BOUNDS.clear()
    _BOUNDS[id(dirs)] = (dirs, (colmin, colmax, rowmin, rowmax))
    return colmin, colmax, rowmin, rowmax


def cast_camera(mesh: RasterMesh, dirs: F32, T_world_cam: npt.ArrayLike
                ) -> tuple[F32, npt.NDArray[np.uint32], F32, F32]:
    """What ``cast_rays`` of the world rays ``[c, R d]`` (``T_world_cam = [R | c]``) returns for the
    camera-frame directions ``dirs`` (H, W, 3) ``(x, y, 1)``: ``t_hit`` (H W,) float32 (``inf``:
    none), ``primitive_ids`` (H W,) uint32 (``0xFFFFFFFF``: none), ``primitive_uvs`` (H W, 2) and
    ``primitive_normals`` (H W, 3) float32 (world frame; zeros where nothing is hit)."""
    T = np.asarray(T_world_cam, dtype=np.float64)
    h, w, _ = dirs.shape
    d = np.ascontiguousarray(dirs, dtype=np.float32).reshape(-1, 3)
    R, c = T[:3, :3], T[:3, 3]
    Vc = (mesh.vertices - c) @ R  # camera frame, float64
    visible = _visible_chunks(mesh.lo, mesh.hi, R, c, *ray_bounds(dirs))
    n = h * w
    zbuf = np.empty(n, np.float64)
    ids = np.empty(n, np.int32)
    _zbuffer(Vc, mesh.triangles, visible, _CHUNK, d, w, *ray_bounds(dirs), NEAR_M, zbuf, ids)
    t = np.empty(n, np.float32)
    prim = np.empty(n, np.uint32)
    uv = np.empty((n, 2), np.float32)
    nrm = np.empty((n, 3), np.float32)
    _resolve(Vc, mesh.triangles, mesh.normals, d, zbuf, ids, t, prim, uv, nrm)
    return t, prim, uv, nrm


def _visible_chunks(lo: np.ndarray, hi: np.ndarray, R: np.ndarray, c: np.ndarray, colmin: np.ndarray,
                    colmax: np.ndarray, rowmin: np.ndarray, rowmax: np.ndarray) -> npt.NDArray[np.bool_]:
    """Which chunks' bounding boxes may be seen: not wholly behind the near plane nor wholly
    beyond one side of the image (boxes straddling the near plane are kept)."""
    corners = np.stack([np.where(np.array([i, j, k], bool), hi, lo) for i in (0, 1) for j in (0, 1)
                        for k in (0, 1)], 1)  # (C, 8, 3)
    pc = (corners - c) @ R
    z = pc[..., 2]
    front = (z > NEAR_M).all(axis=1)
    keep = (z > NEAR_M).any(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        x, y = pc[..., 0] / z, pc[..., 1] / z
    out = (x.max(axis=1) < colmin[0]) | (x.min(axis=1) > colmax[-1]) | \
          (y.max(axis=1) < rowmin[0]) | (y.min(axis=1) > rowmax[-1])
    return np.asarray(keep & ~(front & out))


@nb.njit(cache=True, inline="always")
def _outline(Vc, ia, ib, ic, near):
    # bounding box (x0, x1, y0, y1) in normalised coordinates of the triangle's part in front of
    # z = near (its vertices there and its edges' crossings); x0 > x1 when nothing is in front
    x0, x1, y0, y1 = np.inf, -np.inf, np.inf, -np.inf
    idx = (ia, ib, ic)
    for e in range(3):
        p, q = idx[e], idx[(e + 1) % 3]
        zp, zq = Vc[p, 2], Vc[q, 2]
        if zp > near:
            x, y = Vc[p, 0] / zp, Vc[p, 1] / zp
            x0, x1, y0, y1 = min(x0, x), max(x1, x), min(y0, y), max(y1, y)
        if (zp > near) != (zq > near):
            f = (near - zp) / (zq - zp)
            x = (Vc[p, 0] + f * (Vc[q, 0] - Vc[p, 0])) / near
            y = (Vc[p, 1] + f * (Vc[q, 1] - Vc[p, 1])) / near
            x0, x1, y0, y1 = min(x0, x), max(x1, x), min(y0, y), max(y1, y)
    return x0, x1, y0, y1


@nb.njit(cache=True, nogil=True)
def _zbuffer(Vc, tris, visible, chunk, d, w, colmin, colmax, rowmin, rowmax, near, zbuf, ids):
    """The nearest hit ``zbuf`` (t) and its triangle ``ids`` (-1: none) of every ray ``d`` (N, 3)."""
    zbuf[:] = np.inf
    ids[:] = -1
    nt = tris.shape[0]
    for ch in range(visible.shape[0]):
        if not visible[ch]:
            continue
        for k in range(ch * chunk, min((ch + 1) * chunk, nt)):
            ia, ib, ic = tris[k, 0], tris[k, 1], tris[k, 2]
            x0, x1, y0, y1 = _outline(Vc, ia, ib, ic, near)
            if not x0 <= x1:
                continue
            c0 = np.searchsorted(colmax, x0)
            c1 = np.searchsorted(colmin, x1, side="right") - 1
            r0 = np.searchsorted(rowmax, y0)
            r1 = np.searchsorted(rowmin, y1, side="right") - 1
            if c0 > c1 or r0 > r1:
                continue
            ax, ay, az = Vc[ia, 0], Vc[ia, 1], Vc[ia, 2]
            bx, by, bz = Vc[ib, 0], Vc[ib, 1], Vc[ib, 2]
            cx, cy, cz = Vc[ic, 0], Vc[ic, 1], Vc[ic, 2]
            e0x, e0y, e0z = by * cz - bz * cy, bz * cx - bx * cz, bx * cy - by * cx
            e1x, e1y, e1z = cy * az - cz * ay, cz * ax - cx * az, cx * ay - cy * ax
            e2x, e2y, e2z = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
            det = ax * e0x + ay * e0y + az * e0z
            if det == 0.0:
                continue
            for r in range(r0, r1 + 1):
                for col in range(c0, c1 + 1):
                    p = r * w + col
                    dx, dy, dz = np.float64(d[p, 0]), np.float64(d[p, 1]), np.float64(d[p, 2])
                    w0 = dx * e0x + dy * e0y + dz * e0z
                    w1 = dx * e1x + dy * e1y + dz * e1z
                    w2 = dx * e2x + dy * e2y + dz * e2z
                    if (w0 >= 0.0 and w1 >= 0.0 and w2 >= 0.0) or (w0 <= 0.0 and w1 <= 0.0 and w2 <= 0.0):
                        s = w0 + w1 + w2
                        if s != 0.0:
                            t = det / s
                            if t > 0.0 and t < zbuf[p] * _TIE:
                                zbuf[p] = t
                                ids[p] = k
    return zbuf


@nb.njit(cache=True, nogil=True)
def _resolve(Vc, tris, normals, d, zbuf, ids, t, prim, uv, nrm):
    """open3d's outputs of the z-buffer: t (float32), ids (uint32), barycentric (u, v) of vertices
    1 and 2, the triangle's unit normal."""
    for p in range(ids.shape[0]):
        k = ids[p]
        if k < 0:
            t[p] = np.inf
            prim[p] = 0xFFFFFFFF
            uv[p, 0] = uv[p, 1] = 0.0
            nrm[p, 0] = nrm[p, 1] = nrm[p, 2] = 0.0
            continue
        ia, ib, ic = tris[k, 0], tris[k, 1], tris[k, 2]
        ax, ay, az = Vc[ia, 0], Vc[ia, 1], Vc[ia, 2]
        bx, by, bz = Vc[ib, 0], Vc[ib, 1], Vc[ib, 2]
        cx, cy, cz = Vc[ic, 0], Vc[ic, 1], Vc[ic, 2]
        dx, dy, dz = np.float64(d[p, 0]), np.float64(d[p, 1]), np.float64(d[p, 2])
        w0 = dx * (by * cz - bz * cy) + dy * (bz * cx - bx * cz) + dz * (bx * cy - by * cx)
        w1 = dx * (cy * az - cz * ay) + dy * (cz * ax - cx * az) + dz * (cx * ay - cy * ax)
        w2 = dx * (ay * bz - az * by) + dy * (az * bx - ax * bz) + dz * (ax * by - ay * bx)
        s = w0 + w1 + w2
        t[p] = zbuf[p]
        prim[p] = k
        uv[p, 0] = w1 / s
        uv[p, 1] = w2 / s
        nrm[p, 0], nrm[p, 1], nrm[p, 2] = normals[k, 0], normals[k, 1], normals[k, 2]
    return t
