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

Chunks of consecutive triangles outside the view are skipped by their bounding boxes, and a
ray whose nearest hit so far lies nearer than all of a triangle's vertices is not tested against
it (the hits are those of testing every ray: ``tests/sim/test_render_raster.py``).  Rays
within :data:`NEAR_M` of the camera centre do not see surfaces there (open3d's cast would).  The
kernels run on one thread (the stereo views render on two threads; see ``_kernels``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
import numpy.typing as npt

__all__ = ["NEAR_M", "RasterMesh", "cast_camera", "raster_mesh", "ray_bounds", "workspace"]

F32 = npt.NDArray[np.float32]
NEAR_M = 1e-3  #: surfaces closer than this to the camera centre are not seen
_CHUNK = 64  # consecutive triangles culled together by their bounding box
_EPS = 1e-9  # relative margin on the outline in normalised coordinates (far below a pixel)
_TIE = 1.0 - 1e-9  # a later triangle must be nearer by this factor: coplanar ties go to the lower id
_ZCUT = 1e-3  # relative margin below a triangle's nearest vertex of the z-buffer values it skips


@dataclass(frozen=True, eq=False)
class RasterMesh:
    """A triangle mesh prepared for :func:`cast_camera`: vertices (V, 3) float64, triangles (T, 3)
    int32, unit normals (T + 1, 3) float32 (as open3d's ``primitive_normals``; the last row zero, for
    rays that hit nothing), chunk bounds
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
    n = np.concatenate([n, np.zeros((1, 3), np.float32)])
    nc = -(-len(T) // _CHUNK)
    pts = np.full((nc * _CHUNK, 3, 3), np.nan)
    pts[:len(T)] = np.stack([a, b, c], 1)
    pts = pts.reshape(nc, _CHUNK * 3, 3)
    lo, hi = np.nanmin(pts, axis=1), np.nanmax(pts, axis=1)
    return RasterMesh(V32.astype(np.float64), T, n, lo, hi)


_BOUNDS: dict[int, tuple[np.ndarray, tuple[np.ndarray, ...]]] = {}


def ray_bounds(dirs: F32) -> tuple[np.ndarray, ...]:
    """``colmin, colmax, rowmin, rowmax``: per column (row) the monotone envelope of the rays'
    normalised ``x`` (``y``) over the image, ``rowlo, rowhi``: the range of ``y`` in each row, and
    ``unit_z`` (1,): whether every ray has ``z = 1`` (its hits' ``t`` are their z-depths) (cached
    per ray table: the renderer's are cached)."""
    hit = _BOUNDS.get(id(dirs))
    if hit is not None and hit[0] is dirs:
        return hit[1]
    x, y = dirs[..., 0].astype(np.float64), dirs[..., 1].astype(np.float64)
    # monotone ranges: the columns from c on reach down to colmin[c], those up to c reach colmax[c]
    colmin = np.minimum.accumulate(x.min(axis=0)[::-1])[::-1].copy()
    colmax = np.maximum.accumulate(x.max(axis=0))
    rowmin = np.minimum.accumulate(y.min(axis=1)[::-1])[::-1].copy()
    rowmax = np.maximum.accumulate(y.max(axis=1))
    unit_z = np.array([bool((dirs[..., 2] == 1.0).all())])
    out = (colmin, colmax, rowmin, rowmax, y.min(axis=1), y.max(axis=1), unit_z)
    if len(_BOUNDS) >= 32:
        _BOUNDS.clear()
    _BOUNDS[id(dirs)] = (dirs, out)
    return out


def cast_camera(mesh: RasterMesh, dirs: F32, T_world_cam: npt.ArrayLike,
                work: tuple[np.ndarray, ...] | None = None, *, pixel_normals: bool = True
                ) -> tuple[F32, npt.NDArray[np.uint32], F32, F32]:
    """What ``cast_rays`` of the world rays ``[c, R d]`` (``T_world_cam = [R | c]``) returns for the
    camera-frame directions ``dirs`` (H, W, 3) ``(x, y, 1)``: ``t_hit`` (H W,) float32 (``inf``:
    none), ``primitive_ids`` (H W,) uint32 (``0xFFFFFFFF``: none), ``primitive_uvs`` (H W, 2) and
    ``primitive_normals`` (H W, 3) float32 (world frame; zeros where nothing is hit).

    ``work``: :func:`workspace` buffers to fill (the result's arrays are views of them; fresh
    arrays of a large image cost about a third of the pass in page faults).  Without
    ``pixel_normals`` the last result is ``mesh.normals`` (T + 1, 3), the normal of each triangle
    and a zero row for no hit (the renderer looks them up by triangle: 12 bytes a pixel less)."""
    T = np.asarray(T_world_cam, dtype=np.float64)
    h, w, _ = dirs.shape
    d = np.ascontiguousarray(dirs, dtype=np.float32).reshape(-1, 3)
    R, c = T[:3, :3], T[:3, 3]
    Vc = (mesh.vertices - c) @ R  # camera frame, float64
    bounds = ray_bounds(dirs)
    visible = _visible_chunks(mesh.lo, mesh.hi, R, c, *bounds[:4])
    n = h * w
    zbuf, ids, uv, nrm = _workspace(n, work, pixel_normals)
    _zbuffer(Vc, mesh.triangles, visible, _CHUNK, d, w, bounds, NEAR_M, zbuf, ids, uv)
    t = zbuf.view(np.float32)[:n]  # the float32 depths overwrite the float64 ones already read
    _resolve(mesh.normals, zbuf, ids, t, uv, nrm)
    # -1 (no hit) reads as open3d's 0xFFFFFFFF
    return t, ids.view(np.uint32), uv, nrm if pixel_normals else mesh.normals


def workspace(n: int, pixel_normals: bool = True) -> tuple[np.ndarray, ...]:
    """Buffers for :func:`cast_camera`'s ``work``, ``n`` rays long (32 bytes a ray; 20 without
    ``pixel_normals``)."""
    return _workspace(n, None, pixel_normals)


def _workspace(n: int, work: tuple[np.ndarray, ...] | None, pixel_normals: bool) -> tuple[np.ndarray, ...]:
    """Buffers for ``n`` rays: ``work``'s views when it is long enough, else new arrays."""
    if work is None or len(work[0]) < n or (pixel_normals and len(work[3]) < n):
        work = (np.empty(n, np.float64), np.empty(n, np.int32), np.empty((n, 2), np.float32),
                np.empty((n if pixel_normals else 0, 3), np.float32))
    zbuf, ids, uv, nrm = work
    return zbuf[:n], ids[:n], uv[:n], nrm[:n]


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
def _outline(Vc, ia, ib, ic, near, px, py):
    # the triangle's part in front of z = near seen in normalised coordinates: a convex polygon
    # (its vertices there and its edges' crossings, in order) into px, py; returns its vertex
    # count and bounding box (x0, x1, y0, y1)
    m = 0
    idx = (ia, ib, ic)
    for e in range(3):
        p, q = idx[e], idx[(e + 1) % 3]
        zp, zq = Vc[p, 2], Vc[q, 2]
        if zp > near:
            px[m], py[m] = Vc[p, 0] / zp, Vc[p, 1] / zp
            m += 1
        if (zp > near) != (zq > near):
            f = (near - zp) / (zq - zp)
            px[m] = (Vc[p, 0] + f * (Vc[q, 0] - Vc[p, 0])) / near
            py[m] = (Vc[p, 1] + f * (Vc[q, 1] - Vc[p, 1])) / near
            m += 1
    x0, x1, y0, y1 = np.inf, -np.inf, np.inf, -np.inf
    for i in range(m):
        x0, x1, y0, y1 = min(x0, px[i]), max(x1, px[i]), min(y0, py[i]), max(y1, py[i])
    return m, x0, x1, y0, y1


@nb.njit(cache=True, inline="always")
def _first(a, x, right):
    # np.searchsorted(a, x, side): the first index whose a[i] >= x (> x when ``right``) of a
    # non-decreasing array, from a linear guess (the rays' x or y grow about evenly with the
    # pixel index) and a short walk
    n = a.shape[0]
    if x < a[0] or (not right and x == a[0]):
        return 0
    if x > a[n - 1] or (right and x == a[n - 1]):
        return n
    # here a[0] <= x <= a[n - 1] and a[0] < a[n - 1]
    g = min(max(int((x - a[0]) / (a[n - 1] - a[0]) * (n - 1)), 0), n - 1)
    if right:
        while g > 0 and a[g - 1] > x:
            g -= 1
        while g < n and a[g] <= x:
            g += 1
    else:
        while g > 0 and a[g - 1] >= x:
            g -= 1
        while g < n and a[g] < x:
            g += 1
    return g


@nb.njit(cache=True, inline="always")
def _band(px, py, m, ylo, yhi):
    # x-range of the convex polygon (px, py)[:m] inside the band ylo <= y <= yhi (x0 > x1: none)
    x0, x1 = np.inf, -np.inf
    for i in range(m):
        j = (i + 1) % m
        if ylo <= py[i] <= yhi:
            x0, x1 = min(x0, px[i]), max(x1, px[i])
        for yb in (ylo, yhi):
            if (py[i] - yb) * (py[j] - yb) < 0.0:
                x = px[i] + (yb - py[i]) / (py[j] - py[i]) * (px[j] - px[i])
                x0, x1 = min(x0, x), max(x1, x)
    return x0, x1


@nb.njit(cache=True, nogil=True)
def _zbuffer(Vc, tris, visible, chunk, d, w, bounds, near, zbuf, ids, uv):
    """The nearest hit ``zbuf`` (t), its triangle ``ids`` (-1: none) and barycentric coordinates
    ``uv`` (float32) of vertices 1 and 2 of every ray ``d`` (N, 3) (``bounds``: :func:`ray_bounds`)."""
    zbuf[:] = np.inf
    ids[:] = -1
    colmin, colmax, rowmin, rowmax, rowlo, rowhi, unit_z = bounds
    px, py = np.empty(4), np.empty(4)
    nt = tris.shape[0]
    for ch in range(visible.shape[0]):
        if not visible[ch]:
            continue
        for k in range(ch * chunk, min((ch + 1) * chunk, nt)):
            ia, ib, ic = tris[k, 0], tris[k, 1], tris[k, 2]
            m, x0, x1, y0, y1 = _outline(Vc, ia, ib, ic, near, px, py)
            if m == 0:
                continue
            x0, x1 = x0 - _EPS * (1.0 + abs(x0)), x1 + _EPS * (1.0 + abs(x1))
            y0, y1 = y0 - _EPS * (1.0 + abs(y0)), y1 + _EPS * (1.0 + abs(y1))
            if x1 < colmin[0] or x0 > colmax[-1] or y1 < rowmin[0] or y0 > rowmax[-1]:
                continue  # beside the image
            c0, c1 = _first(colmax, x0, False), _first(colmin, x1, True) - 1
            r0, r1 = _first(rowmax, y0, False), _first(rowmin, y1, True) - 1
            if c0 > c1 or r0 > r1:
                continue
            # a ray whose nearest hit so far is nearer than every vertex cannot take this triangle
            # (with a margin far above the rounding of t; off unless t is the z-depth)
            zcut = min(Vc[ia, 2], Vc[ib, 2], Vc[ic, 2]) * (1.0 - _ZCUT) if unit_z[0] else -np.inf
            _scan(Vc, ia, ib, ic, k, d, w, px, py, m, c0, c1, r0, r1, colmin, colmax, rowlo, rowhi, zcut, zbuf,
                  ids, uv)
    return zbuf


@nb.njit(cache=True, inline="always")
def _scan(Vc, ia, ib, ic, k, d, w, px, py, m, c0, c1, r0, r1, colmin, colmax, rowlo, rowhi, zcut, zbuf, ids,
          uv):
    # test the rays of rows r0..r1, columns c0..c1 (per row only those the outline's band may
    # cover, when the box is wide) against triangle k, but those whose z-buffer is at or below
    # zcut; keep the nearest hit
    ax, ay, az = Vc[ia, 0], Vc[ia, 1], Vc[ia, 2]
    bx, by, bz = Vc[ib, 0], Vc[ib, 1], Vc[ib, 2]
    cx, cy, cz = Vc[ic, 0], Vc[ic, 1], Vc[ic, 2]
    e0x, e0y, e0z = by * cz - bz * cy, bz * cx - bx * cz, bx * cy - by * cx
    e1x, e1y, e1z = cy * az - cz * ay, cz * ax - cx * az, cx * ay - cy * ax
    e2x, e2y, e2z = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    det = ax * e0x + ay * e0y + az * e0z
    if det == 0.0:
        return
    wide = c1 - c0 > 3
    for r in range(r0, r1 + 1):
        cs, ce = c0, c1
        if wide:
            xl, xh = _band(px, py, m, rowlo[r] - _EPS * (1.0 + abs(rowlo[r])), rowhi[r] + _EPS * (1.0 + abs(rowhi[r])))
            if not xl <= xh:
                continue
            cs = max(c0, _first(colmax, xl - _EPS * (1.0 + abs(xl)), False))
            ce = min(c1, _first(colmin, xh + _EPS * (1.0 + abs(xh)), True) - 1)
        for col in range(cs, ce + 1):
            p = r * w + col
            if zbuf[p] <= zcut:
                continue
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
                        uv[p, 0] = w1 / s
                        uv[p, 1] = w2 / s


@nb.njit(cache=True, nogil=True)
def _resolve(normals, zbuf, ids, t, uv, nrm):
    """open3d's outputs of the z-buffer: t (float32; ``t`` may be ``zbuf``'s memory, written behind
    the reads), the triangle's unit normal (when ``nrm`` is not empty); no hit: ``inf`` and zero
    coordinates and normal."""
    with_normals = nrm.shape[0] > 0
    for p in range(ids.shape[0]):
        k = ids[p]
        if k < 0:
            t[p] = np.inf
            uv[p, 0] = uv[p, 1] = 0.0
            if with_normals:
                nrm[p, 0] = nrm[p, 1] = nrm[p, 2] = 0.0
            continue
        t[p] = zbuf[p]
        if with_normals:
            nrm[p, 0], nrm[p, 1], nrm[p, 2] = normals[k, 0], normals[k, 1], normals[k, 2]
    return t
