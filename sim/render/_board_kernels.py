"""numba kernel of the target supersampling's common case (``Renderer._supersample_targets``).

:func:`uniform_board_pixels` takes the candidate pixels whose 3 x 3 neighbourhood sees one board
side, lit alike, and decides each in one pass over its ``s x s`` rays: the footprint test (its
corner rays bound the others; all of them inside one uniform patch of the print, a texel of margin
all round, by :func:`._kernels.texel_diff_table`: the pixel keeps its centre sample), else, when the four corner rays meet the board's plane inside its print
(a texel of margin; the board is a convex quad, so every other ray does too), the mean of all its
rays on that plane, shaded as :func:`._kernels.board_plane_means` does.  Only the rest (a corner
ray off the print, or a side facing the sun in shadow) is left to the casts.  Before this kernel
those pixels cast a coarse 3 x 3 subset of their rays against the whole scene to confirm what their
neighbours already showed (about a tenth of the 384 px calibration drive's CPU).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ._kernels import _plane_hit

FLAT, PLANE, CAST = 0, 1, 2


@nb.njit(cache=True, inline="always")
def _corner_texels(rays, k, per_pixel, P, x0, y0, sign, ppm):
    # texel rows r0..r1 and columns c0..c1 (a texel of margin) holding where the corner rays of
    # pixel k's s x s grid meet the plane of the board at pose P; ok False when one misses it
    rmin, cmin, rmax, cmax = 1 << 30, 1 << 30, -(1 << 30), -(1 << 30)
    s = int(np.sqrt(per_pixel) + 0.5)
    for q in (0, s - 1, per_pixel - s, per_pixel - 1):
        i = k * per_pixel + q
        ox, oy, oz = rays[i, 0] - P[0, 3], rays[i, 1] - P[1, 3], rays[i, 2] - P[2, 3]
        dx, dy, dz = np.float64(rays[i, 3]), np.float64(rays[i, 4]), np.float64(rays[i, 5])
        dn = P[0, 2] * dx + P[1, 2] * dy + P[2, 2] * dz
        t = -(P[0, 2] * ox + P[1, 2] * oy + P[2, 2] * oz) / dn if dn != 0.0 else -1.0
        if not t > 0.0:
            return False, 0, 0, 0, 0
        px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
        x = P[0, 0] * px + P[1, 0] * py + P[2, 0] * pz
        y = P[0, 1] * px + P[1, 1] * py + P[2, 1] * pz
        c = int(np.floor((x - x0) * ppm))
        r = int(np.floor((y - y0) * ppm)) if sign > 0 else int(np.floor((y0 - y) * ppm))
        rmin, rmax, cmin, cmax = min(rmin, r), max(rmax, r), min(cmin, c), max(cmax, c)
    return True, rmin - 1, rmax + 1, cmin - 1, cmax + 1


@nb.njit(cache=True, inline="always")
def _plane_mean(rays, k, per_pixel, P, board, front, lit, sun, e_sun, e_sky, beta, air, sky_distance, scale, work):
    # board_plane_means' mean radiance of pixel k's rays (one origin) on the plane of the board at
    # pose P: a branch-free pass finding each ray's texel (_texel's arithmetic) into ``work``, then
    # the sum (one channel without fog: a board's albedo is grey)
    tex, x0, y0, sign, ppm = board
    rr, cc, tt = work
    h, w = tex.shape
    i0 = k * per_pixel
    ox, oy, oz = rays[i0, 0] - P[0, 3], rays[i0, 1] - P[1, 3], rays[i0, 2] - P[2, 3]
    _, _, _, ndl, amb = _plane_hit(rays, i0, P, sun, lit)  # the same for every ray meeting the plane
    e = e_sun * np.float32(ndl) + e_sky * np.float32(amb)
    num = -(P[0, 2] * ox + P[1, 2] * oy + P[2, 2] * oz)
    for q in range(per_pixel):
        i = i0 + q
        dx, dy, dz = np.float64(rays[i, 3]), np.float64(rays[i, 4]), np.float64(rays[i, 5])
        t = num / (P[0, 2] * dx + P[1, 2] * dy + P[2, 2] * dz)
        px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
        u = np.float64(np.float32(P[0, 0] * px + P[1, 0] * py + P[2, 0] * pz))
        v = np.float64(np.float32(P[0, 1] * px + P[1, 1] * py + P[2, 1] * pz))
        cf = (u - x0) * ppm - 0.5
        rf = (v - y0) * ppm - 0.5 if sign > 0 else (y0 - v) * ppm - 0.5
        cc[q] = min(max(np.int64(np.floor(cf + 0.5)), 0), w - 1)
        rr[q] = min(max(np.int64(np.floor(rf + 0.5)), 0), h - 1)
        tt[q] = t
    a0 = a1 = a2 = 0.0
    for q in range(per_pixel):
        alb = tex[rr[q], cc[q]] if front else np.float32(0.35)
        r = g = bl = alb * e
        if beta > 0.0:
            i = i0 + q
            dnorm = np.sqrt(rays[i, 3] * rays[i, 3] + rays[i, 4] * rays[i, 4] + rays[i, 5] * rays[i, 5])
            tr = np.exp(-beta * min(np.float32(tt[q]) * dnorm, sky_distance))
            r = r * tr + air[0] * (1.0 - tr)
            g = g * tr + air[1] * (1.0 - tr)
            bl = bl * tr + air[2] * (1.0 - tr)
            a1 += float(np.float32(g * scale))
            a2 += float(np.float32(bl * scale))
        a0 += float(np.float32(r * scale))
    if not beta > 0.0:
        a1 = a2 = a0
    return a0 / per_pixel, a1 / per_pixel, a2 / per_pixel


@nb.njit(cache=True, inline="always")
def _classify(rays, k, per_pixel, code, poses, boards, diffs, sun):
    # FLAT, CAST or PLANE for pixel k (board code ``code``) from its corner rays alone
    c = code - 1
    b, lit = c >> 2, c % 2 == 1
    P = poses[b]
    tex, x0, y0, sign, ppm = boards[b]
    sat = diffs[b]
    h, w = tex.shape
    ok, r0, r1, c0, c1 = _corner_texels(rays, k, per_pixel, P, x0, y0, sign, ppm)
    if not ok or r0 < 0 or c0 < 0 or r1 >= h or c1 >= w:
        return CAST
    if sat[r1 + 1, c1 + 1] - sat[r0 + 1, c1 + 1] - sat[r1 + 1, c0 + 1] + sat[r0 + 1, c0 + 1] == 0:
        return FLAT
    # the side faces the sun when max(0, n.s) of its normal facing the ray is > 0
    if not lit and _plane_hit(rays, k * per_pixel, P, sun, True)[3] > 0.0:
        return CAST
    return PLANE


@nb.njit(cache=True, inline="always")
def _mean_into(rays, k, per_pixel, code, poses, boards, sun, sky, optics, scale, out, j, work):
    # out[j]: the PLANE mean of pixel k (board code ``code``)
    c = code - 1
    b, front, lit = c >> 2, (c >> 1) % 2 == 1, c % 2 == 1
    out[j, 0], out[j, 1], out[j, 2] = _plane_mean(rays, k, per_pixel, poses[b], boards[b], front, lit, sun, sky[0],
                                                  sky[1], optics[2], optics[3], optics[4], scale, work)


@nb.njit(cache=True, nogil=True)
def uniform_board_pixels(rays, per_pixel, code, poses, boards, diffs, sun, sky, optics, scale, rows_flat, out,
                         state):
    """Decide the pixels k whose 3 x 3 neighbourhood sees the board side ``code[k]``
    (``Renderer._radiance``'s board code, lit as it says), their ``per_pixel = s * s`` rays at
    rows ``k per_pixel ...`` of ``rays`` (an s x s grid).  ``state[k]``:

    - ``FLAT``: every ray meets the board's plane inside one uniform patch of its print, a texel of
      margin all round (the summed-area table ``diffs`` of :func:`._kernels.texel_diff_table`): the
      pixel keeps its centre sample;
    - ``PLANE``: the corner rays meet the plane inside the print (a texel of margin), so all rays
      do; ``out[rows_flat[k]]`` gets their mean radiance (times ``scale``) there, textured and
      shaded as :func:`._kernels.board_plane_means` (``sky``, ``optics`` as there);
    - ``CAST``: the rest, for the caller's casts: a corner ray off the print, or a side that faces
      the sun but is unlit (its neighbours in a shadow that may end inside the pixel).

    Like the centre-sample test, this assumes no occluder, shadow edge or board corner inside the
    pixel that none of its 3 x 3 neighbours' centre rays sees."""
    work = (np.empty(per_pixel, np.int64), np.empty(per_pixel, np.int64), np.empty(per_pixel, np.float64))
    for k in range(code.shape[0]):
        state[k] = _classify(rays, k, per_pixel, code[k], poses, boards, diffs, sun)
        if state[k] == PLANE:
            _mean_into(rays, k, per_pixel, code[k], poses, boards, sun, sky, optics, scale, out, rows_flat[k], work)
    return state


@nb.njit(cache=True, inline="always")
def _pinhole_ray(row, col, off, fxy, R, origin, i, j, rays):
    # ray i s + j of the s x s grid in pixel (row, col): pinhole_subpixel_dirs then transform_rays
    fx, fy, cx, cy = fxy
    x = np.float32((col + off[j] - cx) / fx)
    y = np.float32((row + off[i] - cy) / fy)
    z = np.float32(1.0)
    q = i * off.shape[0] + j
    rays[q, 0], rays[q, 1], rays[q, 2] = origin[0], origin[1], origin[2]
    rays[q, 3] = R[0, 0] * x + R[0, 1] * y + R[0, 2] * z
    rays[q, 4] = R[1, 0] * x + R[1, 1] * y + R[1, 2] * z
    rays[q, 5] = R[2, 0] * x + R[2, 1] * y + R[2, 2] * z


@nb.njit(cache=True, nogil=True)
def uniform_board_pixels_pinhole(rows, cols, off, fxy, R, origin, code, poses, boards, diffs, sun, sky, optics,
                                 scale, rows_flat, out, state):
    """:func:`uniform_board_pixels` of a camera without distortion, its rays made per pixel
    instead of read: the s x s grid ``off`` (s,) inside pixel ``(rows[k], cols[k])`` as
    ``_kernels.pinhole_subpixel_dirs`` (``fxy = (fx, fy, cx, cy)``) turned into the world as
    ``_kernels.transform_rays`` (float32 ``R`` (3, 3) and ``origin`` (3,)): the same float32 rays."""
    s = off.shape[0]
    rays = np.empty((s * s, 6), np.float32)
    work = (np.empty(s * s, np.int64), np.empty(s * s, np.int64), np.empty(s * s, np.float64))
    n = s * s
    corners = np.array([0, s - 1, n - s, n - 1])
    xs, ys = np.empty(s, np.float32), np.empty(s, np.float32)
    for k in range(code.shape[0]):
        for q in corners:  # the corner rays decide FLAT and CAST; PLANE needs them all
            _pinhole_ray(rows[k], cols[k], off, fxy, R, origin, q // s, q % s, rays)
        state[k] = _classify(rays, 0, n, code[k], poses, boards, diffs, sun)
        if state[k] != PLANE:
            continue
        for i in range(s):
            xs[i] = np.float32((cols[k] + off[i] - fxy[2]) / fxy[0])  # _pinhole_ray's x of column i, y of row i
            ys[i] = np.float32((rows[k] + off[i] - fxy[3]) / fxy[1])
        for i in range(s):
            for j in range(s):
                x, y, z = xs[j], ys[i], np.float32(1.0)
                q = i * s + j
                rays[q, 0], rays[q, 1], rays[q, 2] = origin[0], origin[1], origin[2]
                rays[q, 3] = R[0, 0] * x + R[0, 1] * y + R[0, 2] * z
                rays[q, 4] = R[1, 0] * x + R[1, 1] * y + R[1, 2] * z
                rays[q, 5] = R[2, 0] * x + R[2, 1] * y + R[2, 2] * z
        _mean_into(rays, 0, n, code[k], poses, boards, sun, sky, optics, scale, out, rows_flat[k], work)
    return state
