"""numba kernels of the per-ray work around the ray casts: two fused passes per image instead of
~40 numpy passes over a million pixels.

- :func:`surfaces` (after the casts): nearer hit of the static scene and the movers, the hit
  triangle's material, label and texture coordinates, the procedural albedo, the sun and sky terms
  of the shading and, for every lit pixel facing the sun, its shadow ray (written compactly, with a
  flag saying whether a mover may cast that shadow).
- :func:`finish` (after the shadow rays): sun + sky shading, the wet road, puddles mirroring the
  sky, Koschmieder fog, exposure.
- :func:`quantize`: sensor noise and rounding to 8 bits in one pass.

They run on one thread: measured on the shared two-core machine, threaded kernels (OpenMP) fight
with Embree's TBB workers that keep spinning after each cast, and cost more wall AND CPU time
(1024 x 1024 view: 1.9 s wall / 0.51 s CPU threaded, 1.4 s / 0.39 s single).  The stereo views of
one instant render on two threads instead (the kernels release the GIL).  Every iteration touches
one ray only, so a result never depends on the threads.
"""

from __future__ import annotations

import numba as nb
import numpy as np

# material ids (scene.MAT) and CARLA tags used by the albedo (frozen at compile time)
_GROUND, _SIDEWALK, _FACADE, _CROWN, _CAR, _PED, _TARGET, _CAR_ROOF = 1, 3, 4, 7, 9, 10, 11, 13
_TAG_ROADLINE, _TAG_ROAD, _TAG_TERRAIN = 6, 7, 22


@nb.njit(cache=True, nogil=True)
def transform_rays(dirs, R, origin, out):
    """``out[i] = [origin, R dirs[i]]`` for camera-frame directions (N, 3) -> world rays (N, 6)."""
    for i in range(dirs.shape[0]):
        x, y, z = dirs[i, 0], dirs[i, 1], dirs[i, 2]
        out[i, 0], out[i, 1], out[i, 2] = origin[0], origin[1], origin[2]
        out[i, 3] = R[0, 0] * x + R[0, 1] * y + R[0, 2] * z
        out[i, 4] = R[1, 0] * x + R[1, 1] * y + R[1, 2] * z
        out[i, 5] = R[2, 0] * x + R[2, 1] * y + R[2, 2] * z
    return out


@nb.njit(cache=True, nogil=True)
def pinhole_subpixel_dirs(rows, cols, off, fx, fy, cx, cy, out):
    """``out[k, i s + j] = ((cols[k] + off[j] - cx) / fx, (rows[k] + off[i] - cy) / fy, 1)`` (float64
    arithmetic, stored as float32): the undistorted directions through an s x s grid in each pixel
    (``CameraModel.unproject`` of a model without distortion)."""
    s = off.shape[0]
    for k in range(rows.shape[0]):
        for i in range(s):
            y = (rows[k] + off[i] - cy) / fy
            for j in range(s):
                q = i * s + j
                out[k, q, 0] = (cols[k] + off[j] - cx) / fx
                out[k, q, 1] = y
                out[k, q, 2] = 1.0
    return out


@nb.njit(cache=True, nogil=True)
def rect_mask(dirs, rects, mask, window):
    """``mask[r, c] |= (x, y)`` inside any rectangle ``[x0, x1, y0, y1]`` of ``rects`` (K, 4),
    for camera-frame directions ``(x, y, 1)`` (H, W, 3) (normalised image coordinates), in the
    rows ``window[0]:window[1]`` and columns ``window[2]:window[3]`` only (the caller's bound on
    where such directions lie)."""
    k = rects.shape[0]
    for r in range(window[0], window[1]):
        for c in range(window[2], window[3]):
            if mask[r, c]:
                continue
            x, y = dirs[r, c, 0], dirs[r, c, 1]
            for j in range(k):
                if rects[j, 0] <= x <= rects[j, 1] and rects[j, 2] <= y <= rects[j, 3]:
                    mask[r, c] = True
                    break
    return mask


@nb.njit(cache=True, nogil=True)
def bilinear(table, x, y, wrap):
    """Bilinear samples (N, C) of ``table`` (H, W, C) float32 at texel coordinates (N,) (texel
    centres at integers); periodic when ``wrap``, else clamped to the border texels."""
    h, w, nc = table.shape
    n = x.shape[0]
    out = np.empty((n, nc), np.float32)
    for i in range(n):
        fx, fy = x[i], y[i]
        if wrap:
            fx = fx - w * np.floor(fx / w)
            fy = fy - h * np.floor(fy / h)
        else:
            fx = min(max(fx, 0.0), w - 1.0)
            fy = min(max(fy, 0.0), h - 1.0)
        x0 = int(np.floor(fx))
        y0 = int(np.floor(fy))
        ax = fx - x0
        ay = fy - y0
        if wrap:
            x0 %= w
            y0 %= h
            x1 = (x0 + 1) % w
            y1 = (y0 + 1) % h
        else:
            x1 = min(x0 + 1, w - 1)
            y1 = min(y0 + 1, h - 1)
        for c in range(nc):
            top = table[y0, x0, c] * (1.0 - ax) + table[y0, x1, c] * ax
            bot = table[y1, x0, c] * (1.0 - ax) + table[y1, x1, c] * ax
            out[i, c] = top * (1.0 - ay) + bot * ay
    return out


@nb.njit(cache=True, inline="always")
def _mix64(z):
    # splitmix64 finaliser (Steele, Lea, Flood 2014)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@nb.njit(cache=True, nogil=True)
def quantize(image, gain, key, normal, noise, out):
    """8-bit sensor output of a 0..255 float image (any shape, C order) into ``out`` (uint8, same
    size): ``rint(clip(I + sigma z, 0, 255))`` with ``sigma = sqrt((0.6 gain)^2 + 0.04 gain I)``
    when ``noise``, else ``rint(clip(I, 0, 255))``.

    The standard normal deviates ``z`` come from a counter-based generator: value ``i`` takes the
    16-bit field ``i mod 4`` of ``splitmix64(key + (i div 4) phi)`` as an index into ``normal``, a
    table of the normal quantiles at ``(k + 0.5) / 65536`` (:func:`normal_table`), so the noise
    depends on ``key`` and the pixel only (not on threads, tiles or the image size) and costs
    one hash per four values.
    """
    flat = image.ravel()
    dst = out.ravel()
    n = flat.shape[0]
    read2 = np.float32((0.6 * gain) ** 2)
    shot = np.float32(0.04 * gain)
    k = np.uint64(key)
    full = n >> 2
    for g in range(full):  # four values per hash, without a branch per value
        h = _mix64(k + np.uint64(g) * np.uint64(0x9E3779B97F4A7C15)) if noise else np.uint64(0)
        for q in range(4):
            dst[4 * g + q] = _quantized(flat[4 * g + q], noise, h, q, normal, read2, shot)
    h = _mix64(k + np.uint64(full) * np.uint64(0x9E3779B97F4A7C15)) if noise else np.uint64(0)
    for i in range(4 * full, n):
        dst[i] = _quantized(flat[i], noise, h, i & 3, normal, read2, shot)
    return out


@nb.njit(cache=True, inline="always")
def _quantized(v, noise, h, q, normal, read2, shot):
    # value v with the deviate of field q of hash h when ``noise``, clipped and rounded to 8 bits
    if noise:
        z = normal[(h >> np.uint64(16 * q)) & np.uint64(0xFFFF)]
        v = v + np.sqrt(read2 + shot * max(v, np.float32(0.0))) * z
    v = min(max(v, np.float32(0.0)), np.float32(255.0))
    return np.uint8(np.rint(v))


@nb.njit(cache=True, nogil=True)
def sensor_noise(image, gain, key, normal):
    """``image + sigma z`` (float32, same shape) with the deviates of :func:`quantize`."""
    flat = image.ravel()
    n = flat.shape[0]
    out = np.empty(n, np.float32)
    read2 = np.float32((0.6 * gain) ** 2)
    shot = np.float32(0.04 * gain)
    k = np.uint64(key)
    h = np.uint64(0)
    for i in range(n):
        q = i & 3
        if q == 0:
            h = _mix64(k + np.uint64(i >> 2) * np.uint64(0x9E3779B97F4A7C15))
        z = normal[(h >> np.uint64(16 * q)) & np.uint64(0xFFFF)]
        v = flat[i]
        out[i] = v + np.sqrt(read2 + shot * max(v, np.float32(0.0))) * z
    return out.reshape(image.shape)


@nb.njit(cache=True, inline="always")
def _noise(tab, x, y):
    # periodic bilinear sample of a table whose sides are powers of two (texel centres at integers)
    h, w = tab.shape
    fx = np.floor(x)
    fy = np.floor(y)
    ax = x - fx
    ay = y - fy
    x0 = int(fx) & (w - 1)
    y0 = int(fy) & (h - 1)
    x1 = (x0 + 1) & (w - 1)
    y1 = (y0 + 1) & (h - 1)
    top = tab[y0, x0] * (1.0 - ax) + tab[y0, x1] * ax
    bot = tab[y1, x0] * (1.0 - ax) + tab[y1, x1] * ax
    return top * (1.0 - ay) + bot * ay


@nb.njit(cache=True, inline="always")
def _frac(x):
    return x - np.floor(x)


@nb.njit(cache=True, inline="always")
def _ground_colour(u, v, coarse, gmap, gx0, gy0, gres):
    # asphalt, calibration pad and markings of the ground map (bilinear), grass elsewhere:
    # (r, g, b, paved weight, label)
    gh, gw = gmap.shape[0], gmap.shape[1]
    fx = min(max((u - gx0) / gres - 0.5, 0.0), gw - 1.0)
    fy = min(max((v - gy0) / gres - 0.5, 0.0), gh - 1.0)
    x0 = int(fx)
    y0 = int(fy)
    x1 = min(x0 + 1, gw - 1)
    y1 = min(y0 + 1, gh - 1)
    ax = fx - x0
    ay = fy - y0
    w00 = (1.0 - ax) * (1.0 - ay)
    w01 = ax * (1.0 - ay)
    w10 = (1.0 - ax) * ay
    w11 = ax * ay
    asphalt = (gmap[y0, x0, 0] * w00 + gmap[y0, x1, 0] * w01 + gmap[y1, x0, 0] * w10
               + gmap[y1, x1, 0] * w11) / 255.0
    pad = (gmap[y0, x0, 1] * w00 + gmap[y0, x1, 1] * w01 + gmap[y1, x0, 1] * w10
           + gmap[y1, x1, 1] * w11) / 255.0
    mark = (gmap[y0, x0, 2] * w00 + gmap[y0, x1, 2] * w01 + gmap[y1, x0, 2] * w10
            + gmap[y1, x1, 2] * w11) / 255.0
    road = max(asphalt, pad)
    gr = 1.0 + 0.25 * coarse
    r = 0.22 * gr * (1.0 - road) + 0.19 * asphalt + 0.46 * pad
    g = 0.29 * gr * (1.0 - road) + 0.19 * asphalt + 0.45 * pad
    b = 0.13 * gr * (1.0 - road) + 0.20 * asphalt + 0.42 * pad
    r = r * (1.0 - mark) + 0.85 * mark
    g = g * (1.0 - mark) + 0.85 * mark
    b = b * (1.0 - mark) + 0.80 * mark
    lab = _TAG_ROADLINE if mark > 0.5 else (_TAG_ROAD if road > 0.5 else _TAG_TERRAIN)
    return r, g, b, road, lab


@nb.njit(cache=True, inline="always")
def _facade_colour(u, v, vi, facades):
    # a facade colour per variant with doors, glass panes and window frames on a grid
    k = vi % facades.shape[0]
    r, g, b = facades[k, 0], facades[k, 1], facades[k, 2]
    pitch = 2.6 + 0.3 * (vi % 3)
    fu = _frac(u / pitch)
    fv = _frac(v / 3.1)
    if v < 2.2 and abs(_frac(u / 9.0) - 0.5) < 0.07:  # doors
        return 0.18, 0.12, 0.08
    if v > 2.0 and abs(fu - 0.5) < 0.24 and abs(fv - 0.55) < 0.24:  # glass, pane to pane
        pane = (np.floor(u / pitch) * 7 + np.floor(v / 3.1) * 13) % 5
        return 0.05 + 0.03 * pane, 0.07 + 0.03 * pane, 0.10 + 0.035 * pane
    if v > 2.0 and abs(fu - 0.5) < 0.29 and abs(fv - 0.55) < 0.29:  # window frames
        return 0.80, 0.80, 0.78
    return r, g, b


@nb.njit(cache=True, inline="always")
def _mover_colour(m, v, vi, cars, clothes):
    # cars: body colour, windows all round the cabin (variant >= 100), a dark bumper band;
    # pedestrians: clothes, skin above 1.5 m, dark trousers below 0.85 m
    if m == _PED:
        k = vi % clothes.shape[0]
        if v > 1.5:
            return 0.55, 0.40, 0.32
        if v < 0.85:
            return 0.12, 0.12, 0.16
        return clothes[k, 0], clothes[k, 1], clothes[k, 2]
    k = (vi % 100) % cars.shape[0]
    r, g, b = cars[k, 0], cars[k, 1], cars[k, 2]
    if m == _CAR and vi >= 100:
        return 0.06, 0.07, 0.09
    if m == _CAR and abs(v - 0.18) < 0.08:
        return 0.25 * r, 0.25 * g, 0.25 * b
    return r, g, b


@nb.njit(cache=True, nogil=True)
def albedo_into(mat, var, uv, tex, col, labels, paved):
    """Albedo into ``col`` (N, 3), the ground map's label corrections into ``labels`` (N,) (left
    alone elsewhere) and the paved weight into ``paved`` (N,) of every hit (see
    ``textures.albedo``; the sky and calibration boards get black: the caller looks boards up).
    ``tex`` is the tuple of :func:`~ibiscape_eval.sim.render.textures.kernel_tables` (the noise
    table's sides must be powers of two)."""
    tab, fine_per_m, coarse_per_m, gmap, gx0, gy0, gres, plain, amp_f, amp_c = tex[:10]
    facades, cars, clothes, crowns = tex[10:]
    for i in range(mat.shape[0]):
        m = mat[i]
        if m == 0 or m == _TARGET:  # sky; boards are looked up by the caller
            col[i, 0] = col[i, 1] = col[i, 2] = 0.0
            paved[i] = 0.0
            continue
        u, v, vi = uv[i, 0], uv[i, 1], var[i]
        lab = 0
        pv = 0.0
        fine = _noise(tab, u * fine_per_m, v * fine_per_m)
        coarse = _noise(tab, u * coarse_per_m + 97.0, v * coarse_per_m + 31.0)
        mod = min(max(1.0 + amp_f[m] * fine + amp_c[m] * coarse, 0.15), 2.5)
        r, g, b = plain[m, 0], plain[m, 1], plain[m, 2]
        if m == _GROUND:
            r, g, b, pv, lab = _ground_colour(u, v, coarse, gmap, gx0, gy0, gres)
        elif m == _SIDEWALK:
            if min(_frac(u * 2.0), _frac(v * 2.0)) < 0.04:  # 0.5 m paving slabs, dark joints
                r, g, b = 0.6 * r, 0.6 * g, 0.6 * b
        elif m == _FACADE:
            r, g, b = _facade_colour(u, v, vi, facades)
        elif m == _CROWN:
            k = vi % crowns.shape[0]
            r, g, b = crowns[k, 0], crowns[k, 1], crowns[k, 2]
        elif m == _CAR or m == _CAR_ROOF or m == _PED:  # noqa: SIM109 (numba: plain comparisons)
            r, g, b = _mover_colour(m, v, vi, cars, clothes)
        col[i, 0], col[i, 1], col[i, 2] = r * mod, g * mod, b * mod
        if lab > 0:
            labels[i] = lab
        paved[i] = pv


@nb.njit(cache=True, nogil=True)
def albedo_all(mat, var, uv, tex):
    """Albedo (N, 3), label corrections (N,) (0: keep) and paved weight (N,) of every hit
    (:func:`albedo_into` into new arrays)."""
    n = mat.shape[0]
    col = np.empty((n, 3), np.float32)
    lab = np.zeros(n, np.uint8)
    paved = np.empty(n, np.float32)
    albedo_into(mat, var, uv, tex, col, lab, paved)
    return col, lab, paved


@nb.njit(cache=True, nogil=True)
def board_texels(mat, uv, var, front, boards, col):
    """Fill ``col`` (N, 3) where ``mat`` is a calibration board: the nearest texel of board
    ``var``'s printed texture on its observed side (``front``), grey 0.35 on its back.

    ``boards`` is a tuple per board of ``(texture (H, W) float32, x0, y0 [m] of the texture's
    first column / row edge, row sign (+1: rows grow with y, -1: with decreasing y), texels per
    metre)``, the float64 arithmetic of ``Target.texture_px_from_target`` (texel centres at
    integers, every printed edge on a texel edge)."""
    for i in range(mat.shape[0]):
        if mat[i] != _TARGET:
            continue
        if not front[i]:
            col[i, 0] = col[i, 1] = col[i, 2] = np.float32(0.35)
            continue
        tex, x0, y0, sign, ppm = boards[var[i]]
        col[i, 0] = col[i, 1] = col[i, 2] = _texel(tex, x0, y0, sign, ppm, uv[i, 0], uv[i, 1])
    return col


@nb.njit(cache=True, inline="always")
def _texel(tex, x0, y0, sign, ppm, u, v):
    # the nearest texel of a board's print at target coordinates u, v (float32) [m]
    cf = (np.float64(u) - x0) * ppm - 0.5
    rf = (np.float64(v) - y0) * ppm - 0.5 if sign > 0 else (y0 - np.float64(v)) * ppm - 0.5
    c = min(max(int(np.floor(cf + 0.5)), 0), tex.shape[1] - 1)
    r = min(max(int(np.floor(rf + 0.5)), 0), tex.shape[0] - 1)
    return tex[r, c]


@nb.njit(cache=True, inline="always")
def _shadow_ray(i, count, ox, oy, oz, sun, grid, srays, spix, smov):
    # shadow ray ``count`` from the (lifted) surface point toward the sun, its pixel and whether
    # the point's cell in the movers' sun raster says a mover may shade it
    sgrid, sa0, sb0, scell, e1, e2 = grid
    srays[count, 0], srays[count, 1], srays[count, 2] = ox, oy, oz
    srays[count, 3], srays[count, 4], srays[count, 5] = sun[0], sun[1], sun[2]
    spix[count] = i
    ga = int(np.floor((ox * e1[0] + oy * e1[1] + oz * e1[2] - sa0) / scell))
    gb = int(np.floor((ox * e2[0] + oy * e2[1] + oz * e2[2] - sb0) / scell))
    h, w = sgrid.shape
    inside = (ga >= 0) & (ga < w) & (gb >= 0) & (gb < h)  # without branches: mostly inside, mostly 0
    smov[count] = inside & sgrid[gb if inside else 0, ga if inside else 0]


@nb.njit(cache=True, nogil=True)
def surfaces(rays, hits, hits2, tables, tables2, board_flip, tex, light, grid, work):
    """Everything of the hits the shading needs, in one pass over the rays (N, 6).

    ``hits`` are the static scene's ``(t_hit, primitive_ids, primitive_uvs, primitive_normals,
    by_triangle)`` (``by_triangle``: the normals are a table per triangle, the sentinel row zero,
    not per ray),
    ``tables`` its triangle tables ``(material, variant, label, uv_m, sentinel row)``.  The
    second scene (movers) was cast for a subset of the rays: ``hits2 = (map2, t, ids, uvs,
    normals)`` with ray ``i`` its row ``map2[i]`` (-1: not cast), ``tables2`` its tables.
    ``board_flip[var]`` says for each calibration board whether its triangle normal points away
    from the observed side; ``tex`` are the albedo tables (``textures.kernel_tables``), ``light``
    is ``(sun direction, shadows, lift eps [m])`` and ``grid`` the movers' outlines seen along
    the sun ``(raster, a0, b0, cell, e1, e2)`` (``a = p.e1``, ``b = p.e2``).  ``work`` holds the
    buffers of the results that do not leave the renderer, each at least N long (:func:`workspace`;
    reused from view to view: fresh arrays this size cost as much kernel time in page faults as
    the pass itself).

    Returns
    -------
    depth (N,) (``inf``: sky), mat (N,), var (N,), labels (N,) (with the ground map's
    corrections), uv (N, 2) [m], front (N,) (the observed side of a board), albedo (N, 3) (boards
    black: the caller looks them up), paved (N,), ndl (N,) ``max(0, n.s)`` of the unit normal
    facing the viewer, amb (N,) ``0.6 + 0.4 n_z``, shadow rays (N, 6) of which the first
    ``count`` are used (the lit pixels facing the sun, when ``shadows``), their pixels (N,),
    whether a mover may shade them (N,), and ``count``.
    """
    t, prim, bary, normal, by_triangle = hits
    map2, t2, prim2, bary2, normal2 = hits2
    material, variant, label, uv_m, sentinel = tables
    material2, variant2, label2, uv_m2 = tables2
    sun, shadows, eps = light
    n = t.shape[0]
    depth, mat, lab = np.empty(n, np.float32), np.empty(n, np.uint8), np.empty(n, np.uint8)
    var, uv, front, alb, paved, ndl_out, amb, srays, spix, smov = work
    var, uv, front, alb, paved, ndl_out, amb = var[:n], uv[:n], front[:n], alb[:n], paved[:n], ndl_out[:n], amb[:n]
    has2 = map2.shape[0] > 1
    count = 0
    for i in range(n):
        dx, dy, dz = rays[i, 3], rays[i, 4], rays[i, 5]
        j = map2[i] if has2 else -1
        if j >= 0 and t2[j] < t[i]:
            ti, p, b1, b2 = t2[j], prim2[j], bary2[j, 0], bary2[j, 1]
            nx, ny, nz = normal2[j, 0], normal2[j, 1], normal2[j, 2]
            m, vi, lb = material2[p], variant2[p], label2[p]
            u0, v0, u1, v1 = uv_m2[p, 0, 0], uv_m2[p, 0, 1], uv_m2[p, 1, 0], uv_m2[p, 1, 1]
            u2, v2 = uv_m2[p, 2, 0], uv_m2[p, 2, 1]
        else:
            ti = t[i]
            p = prim[i] if np.isfinite(ti) else sentinel
            b1, b2 = bary[i, 0], bary[i, 1]
            q = p if by_triangle else i
            nx, ny, nz = normal[q, 0], normal[q, 1], normal[q, 2]
            m, vi, lb = material[p], variant[p], label[p]
            u0, v0, u1, v1 = uv_m[p, 0, 0], uv_m[p, 0, 1], uv_m[p, 1, 0], uv_m[p, 1, 1]
            u2, v2 = uv_m[p, 2, 0], uv_m[p, 2, 1]
        depth[i], mat[i], var[i], lab[i] = ti, m, vi, lb
        b0 = 1.0 - b1 - b2
        u = b0 * u0 + b1 * u1 + b2 * u2
        v = b0 * v0 + b1 * v1 + b2 * v2
        uv[i, 0], uv[i, 1] = u, v
        f = nx * dx + ny * dy + nz * dz < 0.0
        s = 1.0 if f else -1.0
        nx, ny, nz = s * nx, s * ny, s * nz
        front[i] = f != board_flip[vi] if m == _TARGET else f
        amb[i] = 0.6 + 0.4 * nz
        ndl = nx * sun[0] + ny * sun[1] + nz * sun[2]
        if ndl < 0.0 or not np.isfinite(ti):
            ndl = 0.0
        ndl_out[i] = ndl
        if shadows and ndl > 0.0:
            _shadow_ray(i, count, rays[i, 0] + ti * dx + eps * nx, rays[i, 1] + ti * dy + eps * ny,
                        rays[i, 2] + ti * dz + eps * nz, sun, grid, srays, spix, smov)
            count += 1
    albedo_into(mat, var, uv, tex, alb, lab, paved)
    return depth, mat, var, lab, uv, front, alb, paved, ndl_out, amb, srays, spix, smov, count


def workspace(n):
    """Buffers for :func:`surfaces`' ``work`` argument, ``n`` rays long."""
    return (np.empty(n, np.uint8), np.empty((n, 2), np.float32), np.empty(n, np.bool_),
            np.empty((n, 3), np.float32), np.empty(n, np.float32), np.empty(n, np.float32),
            np.empty(n, np.float32), np.empty((n, 6), np.float32), np.empty(n, np.int32),
            np.empty(n, np.bool_))


@nb.njit(cache=True, nogil=True)
def finish(alb, ndl, amb, depth, rays, paved, uv, tab, sky, optics, scale):
    """:func:`finish_into` a new (N, 3) array."""
    return finish_into(alb, ndl, amb, depth, rays, paved, uv, tab, sky, optics, scale,
                       np.empty((depth.shape[0], 3), np.float32))


@nb.njit(cache=True, nogil=True)
def finish_into(alb, ndl, amb, depth, rays, paved, uv, tab, sky, optics, scale, out):
    """Radiance into ``out`` (N, 3) times ``scale``: lit surfaces ``albedo (1 - 0.45 wet paved) (e_sun n.s V +
    e_sky (0.6 + 0.4 n_z))`` (``ndl`` already 0 in shadow), the sky gradient where nothing was hit,
    puddles on paved ground mirroring the sky (where a coarse noise exceeds ``puddle_level``; none
    when it is ``inf``), then Koschmieder fog ``J t + A (1 - t)`` (no fog when ``beta`` is 0).

    ``sky`` is ``(e_sun, e_sky, zenith (3,), horizon (3,), overcast (3,), cloud, sky_level)``,
    ``optics`` is ``(wet, puddle_level, beta [1/m], airlight (3,), sky_distance [m])``; ``tab`` is
    the noise table."""
    e_sun, e_sky, zenith, horizon, overcast, cloud, sky_level = sky
    wet, puddle_level, beta, airlight, sky_distance = optics
    n = depth.shape[0]
    puddling = np.isfinite(puddle_level)
    for i in range(n):
        d = depth[i]
        dn = np.sqrt(rays[i, 3] * rays[i, 3] + rays[i, 4] * rays[i, 4] + rays[i, 5] * rays[i, 5])
        if np.isfinite(d):
            pv = paved[i]
            e = (e_sun * ndl[i] + e_sky * amb[i]) * (1.0 - 0.45 * wet * pv)
            r, g, b = alb[i, 0] * e, alb[i, 1] * e, alb[i, 2] * e
            if puddling and pv > 0.0:
                pn = _noise(tab, uv[i, 0] * 0.45 + 11.0, uv[i, 1] * 0.45 + 5.0)
                k = 0.65 * min(max((pn - puddle_level) * 3.0, 0.0), 1.0) * pv
                ez = min(max(-rays[i, 5] / dn, 0.0), 1.0)  # the mirrored ray's elevation
                sq = np.sqrt(ez)
                sr = ((1.0 - cloud) * (horizon[0] + (zenith[0] - horizon[0]) * sq) + cloud * overcast[0]) * sky_level
                sg = ((1.0 - cloud) * (horizon[1] + (zenith[1] - horizon[1]) * sq) + cloud * overcast[1]) * sky_level
                sb = ((1.0 - cloud) * (horizon[2] + (zenith[2] - horizon[2]) * sq) + cloud * overcast[2]) * sky_level
                r = r * (1.0 - k) + sr * k
                g = g * (1.0 - k) + sg * k
                b = b * (1.0 - k) + sb * k
            dist = min(d * dn, sky_distance)
        else:
            ez = min(max(rays[i, 5] / dn, 0.0), 1.0)
            sq = np.sqrt(ez)
            r = ((1.0 - cloud) * (horizon[0] + (zenith[0] - horizon[0]) * sq) + cloud * overcast[0]) * sky_level
            g = ((1.0 - cloud) * (horizon[1] + (zenith[1] - horizon[1]) * sq) + cloud * overcast[1]) * sky_level
            b = ((1.0 - cloud) * (horizon[2] + (zenith[2] - horizon[2]) * sq) + cloud * overcast[2]) * sky_level
            dist = sky_distance
        if beta > 0.0:
            tr = np.exp(-beta * dist)
            r = r * tr + airlight[0] * (1.0 - tr)
            g = g * tr + airlight[1] * (1.0 - tr)
            b = b * tr + airlight[2] * (1.0 - tr)
        out[i, 0] = r * scale
        out[i, 1] = g * scale
        out[i, 2] = b * scale
    return out


@nb.njit(cache=True, nogil=True)
def zero_at(values, index, mask):
    """``values[index[mask]] = 0`` without the index array in between."""
    for i in range(index.shape[0]):
        if mask[i]:
            values[index[i]] = 0.0
    return values


@nb.njit(cache=True, nogil=True)
def streaks_into(img, cov, glow):
    """Rain streaks over the radiance ``img`` (N, 3) in place: ``I (1 - a) + a glow`` with
    ``a = 0.45 cov`` (``cov`` (N,) the streak coverage), in float32 as numpy computes it, only
    where ``cov`` is not 0 (elsewhere the blend returns ``I``; streaks cover a few % of an image)."""
    g = np.float32(glow)
    one = np.float32(1.0)
    for i in range(cov.shape[0]):
        c = cov[i]
        if c != 0.0:
            a = np.float32(0.45) * c
            for k in range(3):
                img[i, k] = img[i, k] * (one - a) + a * g
    return img


@nb.njit(cache=True, nogil=True)
def texel_diff_table(tex):
    """Summed-area table ``S`` (H + 1, W + 1) int32 of the texels of ``tex`` (H, W) that differ from
    their left or upper neighbour: ``S[i, j]`` counts them in rows ``< i``, columns ``< j``."""
    h, w = tex.shape
    S = np.zeros((h + 1, w + 1), np.int32)
    for r in range(h):
        run = 0
        for c in range(w):
            d = (c > 0 and tex[r, c] != tex[r, c - 1]) or (r > 0 and tex[r, c] != tex[r - 1, c])
            run += 1 if d else 0
            S[r + 1, c + 1] = S[r, c + 1] + run
    return S


@nb.njit(cache=True, nogil=True)
def pixel_means(samples, per_pixel, rows_flat, out):
    """``out[rows_flat[k]] = mean of samples[k per_pixel .. (k + 1) per_pixel]`` (samples (K per_pixel,
    3), ``out`` (N, 3)): the supersampled pixels' box filter, summed in float64."""
    inv = 1.0 / per_pixel
    for k in range(rows_flat.shape[0]):
        a0 = a1 = a2 = 0.0
        for q in range(k * per_pixel, (k + 1) * per_pixel):
            a0 += samples[q, 0]
            a1 += samples[q, 1]
            a2 += samples[q, 2]
        j = rows_flat[k]
        out[j, 0], out[j, 1], out[j, 2] = a0 * inv, a1 * inv, a2 * inv
    return out


@nb.njit(cache=True, nogil=True)
def board_plane_samples(rays, var, code, poses, sun, depth, uv, ndl, amb):
    """Where rays (N, 6) meet the plane of board ``var[i]`` (pose ``poses[var[i]]``
    ``T_world_target``): the ray parameter into ``depth`` (the z-depth of a camera ray), target
    coordinates into ``uv`` and the shading terms of :func:`surfaces` for that plane into ``ndl``
    (``max(0, n.s)`` of the normal facing the ray; 0 when ``code[i]`` says unlit: ``code`` as
    ``Renderer._radiance``'s board code) and ``amb`` (``0.6 + 0.4 n_z``).  A ray parallel to the
    plane gets ``inf`` (the caller casts only rays whose neighbours saw the plane)."""
    for i in range(rays.shape[0]):
        depth[i], uv[i, 0], uv[i, 1], ndl[i], amb[i] = _plane_hit(rays, i, poses[var[i]], sun,
                                                                  (code[i] - 1) % 2 == 1)
    return depth


@nb.njit(cache=True, inline="always")
def _plane_hit(rays, i, P, sun, lit):
    # ray i meets the plane of the board at pose P: t, target x, y and the shading terms
    ox, oy, oz = rays[i, 0] - P[0, 3], rays[i, 1] - P[1, 3], rays[i, 2] - P[2, 3]
    dx, dy, dz = np.float64(rays[i, 3]), np.float64(rays[i, 4]), np.float64(rays[i, 5])
    nx, ny, nz = P[0, 2], P[1, 2], P[2, 2]
    dn = nx * dx + ny * dy + nz * dz
    t = -(nx * ox + ny * oy + nz * oz) / dn if dn != 0.0 else np.inf
    px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
    if dn > 0.0:  # the normal facing the viewer
        nx, ny, nz = -nx, -ny, -nz
    ndl = max(nx * sun[0] + ny * sun[1] + nz * sun[2], 0.0) if lit else 0.0
    return (t, P[0, 0] * px + P[1, 0] * py + P[2, 0] * pz, P[0, 1] * px + P[1, 1] * py + P[2, 1] * pz, ndl,
            0.6 + 0.4 * nz)


@nb.njit(cache=True, nogil=True)
def board_plane_means(rays, per_pixel, code, poses, boards, sun, sky, optics, scale, rows_flat, out):
    """``out[rows_flat[k]]``: the mean radiance (times ``scale``) of the ``per_pixel`` rays of
    pixel k (rows ``k per_pixel ...`` of ``rays``) where they meet the plane of the board side
    that ``code[k]`` names (``Renderer._radiance``'s board code; lit as it says), textured and
    shaded as :func:`board_plane_samples`, :func:`board_texels` and :func:`finish_into` do for a
    board (no wet road; float32 depth, target coordinates and shading terms, as those arrays
    hold them), summed in float64.  Every ray must meet the plane in front (``t > 0``: the
    caller's coarse rays saw the board around them)."""
    e_sun, e_sky = sky[0], sky[1]
    beta, airlight, sky_distance = optics[2], optics[3], optics[4]
    f0, f1, f2 = airlight[0], airlight[1], airlight[2]
    for k in range(rows_flat.shape[0]):
        c = code[k] - 1
        b, front, lit = c >> 2, (c >> 1) % 2 == 1, c % 2 == 1
        P = poses[b]
        tex, x0, y0, sign, ppm = boards[b]
        a0 = a1 = a2 = 0.0
        for i in range(k * per_pixel, (k + 1) * per_pixel):
            t, u, v, ndl, amb = _plane_hit(rays, i, P, sun, lit)
            alb = _texel(tex, x0, y0, sign, ppm, np.float32(u), np.float32(v)) if front else np.float32(0.35)
            e = e_sun * np.float32(ndl) + e_sky * np.float32(amb)
            r = g = bl = alb * e
            if beta > 0.0:
                dn = np.sqrt(rays[i, 3] * rays[i, 3] + rays[i, 4] * rays[i, 4] + rays[i, 5] * rays[i, 5])
                tr = np.exp(-beta * min(np.float32(t) * dn, sky_distance))
                r = r * tr + f0 * (1.0 - tr)
                g = g * tr + f1 * (1.0 - tr)
                bl = bl * tr + f2 * (1.0 - tr)
            a0 += float(np.float32(r * scale))
            a1 += float(np.float32(g * scale))
            a2 += float(np.float32(bl * scale))
        j = rows_flat[k]
        out[j, 0], out[j, 1], out[j, 2] = a0 / per_pixel, a1 / per_pixel, a2 / per_pixel
    return out


@nb.njit(cache=True, nogil=True)
def hit_board_codes(rays, t, prim, normal, material, variant, board_flip, sun, out):
    """``out[i]``: ``Renderer._radiance``'s board code of ray i's hit in the static scene
    (``t``, ``prim``, ``normal`` as open3d returns them; 0 where it sees no board), lit where the
    board side faces the sun, without a shadow ray: :func:`surfaces`' arithmetic, for rays whose
    neighbours saw that side lit."""
    for i in range(t.shape[0]):
        out[i] = 0
        if not np.isfinite(t[i]) or material[prim[i]] != _TARGET:
            continue
        vi = variant[prim[i]]
        nx, ny, nz = normal[i, 0], normal[i, 1], normal[i, 2]
        f = nx * rays[i, 3] + ny * rays[i, 4] + nz * rays[i, 5] < 0.0
        s = 1.0 if f else -1.0
        ndl = s * nx * sun[0] + s * ny * sun[1] + s * nz * sun[2]
        out[i] = 1 + 4 * vi + (2 if f != board_flip[vi] else 0) + (1 if ndl > 0.0 else 0)
    return out
