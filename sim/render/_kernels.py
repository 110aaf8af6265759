"""numba kernels of the per-ray work around the ray casts (one fused pass instead of ~40 numpy
passes over the image): hit attributes from the triangle tables, surface albedo, final shading
with sky and fog, texture sampling, sensor noise.

They run on one thread: measured on the shared two-core machine, threaded kernels (OpenMP) fight
with Embree's TBB workers that keep spinning after each cast, and cost more wall AND CPU time
(1024 x 1024 view: 1.9 s wall / 0.51 s CPU threaded, 1.4 s / 0.39 s single).  Every iteration
touches one ray only, so switching ``prange`` back on cannot change a result.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def hit_attributes(t, prim, bary, normal, rays, map2, t2, prim2, bary2, normal2,
                   material, variant, label, uv_m, material2, variant2, label2, uv_m2, sentinel):
    """Nearer hit of two scenes -> per-ray material, variant, label, uv [m], unit normal facing
    the viewer, front-face flag of the geometric normal, hit point and ray length |d|.

    The second scene was cast for a subset of the rays: ray ``i`` is its row ``map2[i]`` (-1: not
    cast)."""
    n = t.shape[0]
    mat = np.empty(n, np.uint8)
    var = np.empty(n, np.uint8)
    lab = np.empty(n, np.uint8)
    uv = np.empty((n, 2), np.float32)
    nrm = np.empty((n, 3), np.float32)
    facing = np.empty(n, np.bool_)
    pts = np.empty((n, 3), np.float32)
    dn = np.empty(n, np.float32)
    depth = np.empty(n, np.float32)
    for i in nb.prange(n):
        dx, dy, dz = rays[i, 3], rays[i, 4], rays[i, 5]
        dn[i] = np.sqrt(dx * dx + dy * dy + dz * dz)
        j = map2[i] if map2.shape[0] > 1 else -1
        if j >= 0 and t2[j] < t[i]:
            ti, p, b1, b2 = t2[j], prim2[j], bary2[j, 0], bary2[j, 1]
            nx, ny, nz = normal2[j, 0], normal2[j, 1], normal2[j, 2]
            mat[i], var[i], lab[i] = material2[p], variant2[p], label2[p]
            u0, v0 = uv_m2[p, 0, 0], uv_m2[p, 0, 1]
            u1, v1 = uv_m2[p, 1, 0], uv_m2[p, 1, 1]
            u2, v2 = uv_m2[p, 2, 0], uv_m2[p, 2, 1]
        else:
            ti = t[i]
            p = prim[i] if np.isfinite(ti) else sentinel
            b1, b2 = bary[i, 0], bary[i, 1]
            nx, ny, nz = normal[i, 0], normal[i, 1], normal[i, 2]
            mat[i], var[i], lab[i] = material[p], variant[p], label[p]
            u0, v0 = uv_m[p, 0, 0], uv_m[p, 0, 1]
            u1, v1 = uv_m[p, 1, 0], uv_m[p, 1, 1]
            u2, v2 = uv_m[p, 2, 0], uv_m[p, 2, 1]
        depth[i] = ti
        b0 = 1.0 - b1 - b2
        uv[i, 0] = b0 * u0 + b1 * u1 + b2 * u2
        uv[i, 1] = b0 * v0 + b1 * v1 + b2 * v2
        f = nx * dx + ny * dy + nz * dz < 0.0
        facing[i] = f
        s = 1.0 if f else -1.0
        nrm[i, 0], nrm[i, 1], nrm[i, 2] = s * nx, s * ny, s * nz
        if np.isfinite(ti):
            pts[i, 0] = rays[i, 0] + ti * dx
            pts[i, 1] = rays[i, 1] + ti * dy
            pts[i, 2] = rays[i, 2] + ti * dz
        else:
            pts[i, 0] = pts[i, 1] = pts[i, 2] = 0.0
    return depth, mat, var, lab, uv, nrm, facing, pts, dn


@nb.njit(cache=True, nogil=True)
def shade_all(albedo, nrm, visible, depth, rays, dn, sun, e_sun, e_sky, zenith, horizon, overcast,
              cloud, sky_level, beta, airlight, sky_distance):
    """Radiance (N, 3): lit surfaces ``albedo (e_sun max(0, n.s) V + e_sky (0.6 + 0.4 n_z))``, the
    sky gradient where nothing was hit, then Koschmieder fog ``J t + A (1 - t)``."""
    n = depth.shape[0]
    out = np.empty((n, 3), np.float32)
    for i in nb.prange(n):
        d = depth[i]
        if np.isfinite(d):
            ndl = nrm[i, 0] * sun[0] + nrm[i, 1] * sun[1] + nrm[i, 2] * sun[2]
            if ndl < 0.0 or not visible[i]:
                ndl = 0.0
            e = e_sun * ndl + e_sky * (0.6 + 0.4 * nrm[i, 2])
            for c in range(3):
                out[i, c] = albedo[i, c] * e
            dist = d * dn[i]
        else:
            ez = rays[i, 5] / dn[i]
            ez = min(max(ez, 0.0), 1.0)
            s = np.sqrt(ez)
            for c in range(3):
                clear = horizon[c] + (zenith[c] - horizon[c]) * s
                out[i, c] = ((1.0 - cloud) * clear + cloud * overcast[c]) * sky_level
            dist = sky_distance
        if beta > 0.0:
            tr = np.exp(-beta * min(dist, sky_distance))
            for c in range(3):
                out[i, c] = out[i, c] * tr + airlight[c] * (1.0 - tr)
    return out


@nb.njit(cache=True, nogil=True)
def bilinear(table, x, y, wrap):
    """Bilinear samples (N, C) of ``table`` (H, W, C) float32 at texel coordinates (N,) (texel
    centres at integers); periodic when ``wrap``, else clamped to the border texels."""
    h, w, nc = table.shape
    n = x.shape[0]
    out = np.empty((n, nc), np.float32)
    for i in nb.prange(n):
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
def sensor_noise(image, gain, key):
    """``image + sigma N(0, 1)`` with ``sigma = sqrt((0.6 gain)^2 + 0.04 gain I)`` per value; the
    normal deviates come from a counter-based generator (splitmix64 of ``key`` and the value's
    index, Box-Muller), so they do not depend on the number of threads."""
    flat = image.ravel()
    n = flat.shape[0]
    out = np.empty(n, np.float32)
    read2 = (0.6 * gain) ** 2
    shot = 0.04 * gain
    k = np.uint64(key)
    for j in nb.prange((n + 1) // 2):
        a = _mix64(k + np.uint64(2 * j) * np.uint64(0x9E3779B97F4A7C15))
        b = _mix64(a + np.uint64(0x632BE59BD9B4E019))
        u1 = ((a >> np.uint64(11)) + np.uint64(1)) * (1.0 / 9007199254740993.0)
        u2 = (b >> np.uint64(11)) * (1.0 / 9007199254740992.0)
        r = np.sqrt(-2.0 * np.log(u1))
        z0 = r * np.cos(2.0 * np.pi * u2)
        z1 = r * np.sin(2.0 * np.pi * u2)
        i0 = 2 * j
        v = flat[i0]
        out[i0] = v + np.sqrt(read2 + shot * max(v, 0.0)) * z0
        if i0 + 1 < n:
            v = flat[i0 + 1]
            out[i0 + 1] = v + np.sqrt(read2 + shot * max(v, 0.0)) * z1
    return out.reshape(image.shape)


# material ids (scene.MAT) and CARLA tags used by the albedo kernel (frozen at compile time)
_GROUND, _SIDEWALK, _FACADE, _CROWN, _CAR, _PED, _TARGET, _CAR_ROOF = 1, 3, 4, 7, 9, 10, 11, 13
_TAG_ROADLINE, _TAG_ROAD, _TAG_TERRAIN = 6, 7, 22


@nb.njit(cache=True, inline="always")
def _noise(tab, x, y):
    h, w = tab.shape
    fx = x - w * np.floor(x / w)
    fy = y - h * np.floor(y / h)
    x0 = int(fx)
    y0 = int(fy)
    ax = fx - x0
    ay = fy - y0
    x0 %= w
    y0 %= h
    x1 = (x0 + 1) % w
    y1 = (y0 + 1) % h
    top = tab[y0, x0] * (1.0 - ax) + tab[y0, x1] * ax
    bot = tab[y1, x0] * (1.0 - ax) + tab[y1, x1] * ax
    return top * (1.0 - ay) + bot * ay


@nb.njit(cache=True, inline="always")
def _frac(x):
    return x - np.floor(x)


@nb.njit(cache=True, nogil=True)
def albedo_all(mat, var, uv, tab, fine_per_m, coarse_per_m, gmap, gx0, gy0, gres, plain, amp_f, amp_c,
               facades, cars, clothes, crowns):
    """Albedo (N, 3), label corrections (N,) (0: keep) and paved weight (N,) of every hit (see
    ``textures.albedo``; calibration targets are left black for the caller)."""
    n = mat.shape[0]
    col = np.zeros((n, 3), np.float32)
    lab = np.zeros(n, np.uint8)
    paved = np.zeros(n, np.float32)
    gh, gw = gmap.shape[0], gmap.shape[1]
    for i in nb.prange(n):
        m = mat[i]
        if m == 0 or m == _TARGET:
            continue
        u, v = uv[i, 0], uv[i, 1]
        vi = var[i]
        fine = _noise(tab, u * fine_per_m, v * fine_per_m)
        coarse = _noise(tab, u * coarse_per_m + 97.0, v * coarse_per_m + 31.0)
        mod = min(max(1.0 + amp_f[m] * fine + amp_c[m] * coarse, 0.15), 2.5)
        r, g, b = plain[m, 0], plain[m, 1], plain[m, 2]
        if m == _GROUND:
            fx = min(max((u - gx0) / gres - 0.5, 0.0), gw - 1.0)
            fy = min(max((v - gy0) / gres - 0.5, 0.0), gh - 1.0)
            x0 = int(fx)
            y0 = int(fy)
            x1 = min(x0 + 1, gw - 1)
            y1 = min(y0 + 1, gh - 1)
            ax = fx - x0
            ay = fy - y0
            cov = np.empty(3, np.float32)
            for c in range(3):
                top = gmap[y0, x0, c] * (1.0 - ax) + gmap[y0, x1, c] * ax
                bot = gmap[y1, x0, c] * (1.0 - ax) + gmap[y1, x1, c] * ax
                cov[c] = (top * (1.0 - ay) + bot * ay) / 255.0
            asphalt, pad, mark = cov[0], cov[1], cov[2]
            road = max(asphalt, pad)
            gr = 1.0 + 0.25 * coarse
            r = 0.22 * gr * (1.0 - road) + 0.19 * asphalt + 0.46 * pad
            g = 0.29 * gr * (1.0 - road) + 0.19 * asphalt + 0.45 * pad
            b = 0.13 * gr * (1.0 - road) + 0.20 * asphalt + 0.42 * pad
            r = r * (1.0 - mark) + 0.85 * mark
            g = g * (1.0 - mark) + 0.85 * mark
            b = b * (1.0 - mark) + 0.80 * mark
            paved[i] = road
            lab[i] = _TAG_ROADLINE if mark > 0.5 else (_TAG_ROAD if road > 0.5 else _TAG_TERRAIN)
        elif m == _SIDEWALK:
            if min(_frac(u * 2.0), _frac(v * 2.0)) < 0.04:  # 0.5 m paving slabs, dark joints
                r, g, b = 0.6 * r, 0.6 * g, 0.6 * b
        elif m == _FACADE:
            k = vi % facades.shape[0]
            r, g, b = facades[k, 0], facades[k, 1], facades[k, 2]
            pitch = 2.6 + 0.3 * (vi % 3)
            fu = _frac(u / pitch)
            fv = _frac(v / 3.1)
            if v < 2.2 and abs(_frac(u / 9.0) - 0.5) < 0.07:  # doors
                r, g, b = 0.18, 0.12, 0.08
            elif v > 2.0 and abs(fu - 0.5) < 0.24 and abs(fv - 0.55) < 0.24:  # glass, pane to pane
                pane = (np.floor(u / pitch) * 7 + np.floor(v / 3.1) * 13) % 5
                r, g, b = 0.05 + 0.03 * pane, 0.07 + 0.03 * pane, 0.10 + 0.035 * pane
            elif v > 2.0 and abs(fu - 0.5) < 0.29 and abs(fv - 0.55) < 0.29:  # window frames
                r, g, b = 0.80, 0.80, 0.78
        elif m == _CROWN:
            k = vi % crowns.shape[0]
            r, g, b = crowns[k, 0], crowns[k, 1], crowns[k, 2]
        elif m == _CAR or m == _CAR_ROOF:  # noqa: SIM109 (numba: plain comparisons)
            k = (vi % 100) % cars.shape[0]
            r, g, b = cars[k, 0], cars[k, 1], cars[k, 2]
            if m == _CAR and vi >= 100:  # windows all round the cabin
                r, g, b = 0.06, 0.07, 0.09
            elif m == _CAR and abs(v - 0.18) < 0.08:  # dark bumper band
                r, g, b = 0.25 * r, 0.25 * g, 0.25 * b
        elif m == _PED:
            k = vi % clothes.shape[0]
            r, g, b = clothes[k, 0], clothes[k, 1], clothes[k, 2]
            if v > 1.5:
                r, g, b = 0.55, 0.40, 0.32
            elif v < 0.85:
                r, g, b = 0.12, 0.12, 0.16
        col[i, 0] = r * mod
        col[i, 1] = g * mod
        col[i, 2] = b * mod
    return col, lab, paved
