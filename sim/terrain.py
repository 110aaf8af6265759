"""Road surface as a height field: a flat plane (z = 0) with "bubbles" and "waves".

- A *bubble* is a spherical cap of height ``height_m`` whose rim is rounded by a toroidal fillet
  tangent to both the sphere and the ground, so the surface is C1 everywhere; ``radius_m`` is the
  outer radius where the fillet meets the ground.  The IBISCape paper (fig. ``excitationangles``)
  puts such caps on the approach path; placed under one side's wheels they excite roll.
- A *wave* is a ridge across the road: a raised-cosine profile of length ``width_m`` along the
  driving direction ``heading_rad`` and ``length_m`` across it (its ends tapered by a half cosine),
  so both axles cross it one after the other and it excites pitch.

Heights and gradients are exact and vectorised over points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError

__all__ = ["Bump", "Terrain"]

FloatArray = npt.NDArray[np.float64]

_KINDS = ("bubble", "wave")


@dataclass(frozen=True)
class Bump:
    """One bump of the road surface.

    Attributes
    ----------
    kind : str
        ``"bubble"`` (spherical cap) or ``"wave"`` (ridge across the road).
    centre_m : tuple of 2 floats
        Centre on the ground, world x, y in metres.
    height_m : float
        Peak height above the road, metres (> 0).
    radius_m : float
        Bubble only: outer radius where the rounded rim meets the ground, metres.
    width_m : float
        Wave only: length of the raised-cosine profile along ``heading_rad``, metres.
    length_m : float
        Wave only: extent across the driving direction, metres.
    heading_rad : float
        Wave only: driving direction the ridge lies across (radians from world x).
    rim_fraction : float
        Bubble only: fillet radius as a fraction of the un-rounded cap's sphere radius.
    """

    kind: str
    centre_m: tuple[float, float]
    height_m: float
    radius_m: float = 0.0
    width_m: float = 0.0
    length_m: float = 0.0
    heading_rad: float = 0.0
    rim_fraction: float = 0.3
    _geom: tuple[float, ...] = field(default=(), init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.kind not in _KINDS:
            raise IbiscapeError(f"bump kind {self.kind!r} is unknown; use one of {_KINDS}")
        if not (math.isfinite(self.height_m) and self.height_m > 0.0):
            raise IbiscapeError(f"bump height_m must be > 0, got {self.height_m}")
        object.__setattr__(self, "centre_m", (float(self.centre_m[0]), float(self.centre_m[1])))
        if self.kind == "bubble":
            a, h = float(self.radius_m), float(self.height_m)
            if not (a > 2.0 * h):
                raise IbiscapeError(
                    f"bubble radius_m ({a}) must exceed twice its height_m ({h}) for a cap"
                )
            if not (0.0 < self.rim_fraction < 1.0):
                raise IbiscapeError(f"bubble rim_fraction must be in (0, 1), got {self.rim_fraction}")
            # Sphere (radius R, centre at depth c below ground) plus a fillet circle (radius rho,
            # centre (a, rho)) tangent to it: (R + rho)^2 = a^2 + (R + rho - h)^2.
            big = (a * a + h * h) / (2.0 * h)
            rho = self.rim_fraction * big
            R = big - rho
            c = R - h
            r_t = R * a / (R + rho)  # where sphere and fillet touch
            object.__setattr__(self, "_geom", (R, c, rho, r_t, a))
        else:
            if not (self.width_m > 0.0 and self.length_m > 0.0):
                raise IbiscapeError(
                    f"wave width_m and length_m must be > 0, got {self.width_m}, {self.length_m}"
                )

    @property
    def extent_m(self) -> float:
        """Radius of a disc around ``centre_m`` outside which the bump is exactly 0."""
        if self.kind == "bubble":
            return float(self.radius_m)
        return 0.5 * math.hypot(self.width_m, self.length_m)

    def height_and_gradient(self, xy: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Height ``(N,)`` and gradient ``(N, 2)`` of this bump alone at points ``xy (N, 2)``."""
        d = xy - np.asarray(self.centre_m)
        z = np.zeros(len(xy))
        g = np.zeros((len(xy), 2))
        if self.kind == "bubble":
            R, c, rho, r_t, a = self._geom
            r = np.hypot(d[:, 0], d[:, 1])
            cap = r <= r_t
            rim = (r > r_t) & (r < a)
            dz_dr = np.zeros(len(xy))
            rc = r[cap]
            root = np.sqrt(R * R - rc * rc)
            z[cap] = root - c
            dz_dr[cap] = -rc / root
            u = r[rim] - a
            root = np.sqrt(np.maximum(rho * rho - u * u, 0.0))
            z[rim] = rho - root
            dz_dr[rim] = u / np.maximum(root, 1e-300)
            inside = r > 0.0
            g[inside] = (dz_dr[inside] / r[inside])[:, None] * d[inside]
            return z, g
        ch, sh = math.cos(self.heading_rad), math.sin(self.heading_rad)
        u = d[:, 0] * ch + d[:, 1] * sh
        v = -d[:, 0] * sh + d[:, 1] * ch
        w, half_l = self.width_m, 0.5 * self.length_m
        taper = min(0.5, 0.25 * self.length_m)
        on_u = np.abs(u) < 0.5 * w
        p = np.where(on_u, 0.5 * self.height_m * (1.0 + np.cos(2.0 * np.pi * u / w)), 0.0)
        dp = np.where(on_u, -self.height_m * np.pi / w * np.sin(2.0 * np.pi * u / w), 0.0)
        av = np.abs(v)
        e = (av - (half_l - taper)) / taper
        in_taper = (e > 0.0) & (e < 1.0)
        q = np.where(av <= half_l - taper, 1.0, np.where(in_taper, 0.5 * (1.0 + np.cos(np.pi * e)), 0.0))
        dq = np.where(in_taper, -0.5 * np.pi / taper * np.sin(np.pi * e) * np.sign(v), 0.0)
        z = p * q
        dz_du = dp * q
        dz_dv = p * dq
        g[:, 0] = dz_du * ch - dz_dv * sh
        g[:, 1] = dz_du * sh + dz_dv * ch
        return z, g

    def to_dict(self) -> dict[str, Any]:
        """Plain-type description for ``sequence.yaml``."""
        doc: dict[str, Any] = {
            "kind": self.kind,
            "centre_m": [self.centre_m[0], self.centre_m[1]],
            "height_m": float(self.height_m),
        }
        if self.kind == "bubble":
            doc["radius_m"] = float(self.radius_m)
            doc["rim_fraction"] = float(self.rim_fraction)
        else:
            doc.update(
                width_m=float(self.width_m),
                length_m=float(self.length_m),
                heading_rad=float(self.heading_rad),
            )
        return doc


@dataclass(frozen=True)
class Terrain:
    """Flat road (z = 0) plus bumps; overlapping bumps add up.

    Attributes
    ----------
    bumps : tuple of Bump
    """

    bumps: tuple[Bump, ...] = ()

    def _eval(self, xy: npt.ArrayLike, grad: bool) -> tuple[FloatArray, FloatArray | None]:
        pts = np.asarray(xy, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise IbiscapeError(f"terrain points must have shape (N, 2), got {pts.shape}")
        z = np.zeros(len(pts))
        g = np.zeros((len(pts), 2)) if grad else None
        for bump in self.bumps:
            # Only the points near this bump are evaluated (cheap box test first).
            ext = bump.extent_m
            cx, cy = bump.centre_m
            near = np.flatnonzero(
                (np.abs(pts[:, 0] - cx) < ext) & (np.abs(pts[:, 1] - cy) < ext)
            )
            if near.size == 0:
                continue
            zb, gb = bump.height_and_gradient(pts[near])
            z[near] += zb
            if g is not None:
                g[near] += gb
        return z, g

    def height_m(self, xy: npt.ArrayLike) -> FloatArray:
        """Surface height at world points.

        Parameters
        ----------
        xy : array_like, shape (N, 2)
            World x, y in metres.

        Returns
        -------
        ndarray, shape (N,)
            Height in metres (0 on the flat road).
        """
        return self._eval(xy, False)[0]

    def gradient(self, xy: npt.ArrayLike) -> FloatArray:
        """Exact surface gradient ``(dz/dx, dz/dy)``, shape ``(N, 2)``, at world points ``(N, 2)``."""
        g = self._eval(xy, True)[1]
        assert g is not None
        return g

    def to_dict(self) -> dict[str, Any]:
        """Bump list for ``sequence.yaml``."""
        return {
            "n_bubbles": sum(b.kind == "bubble" for b in self.bumps),
            "n_waves": sum(b.kind == "wave" for b in self.bumps),
            "bumps": [b.to_dict() for b in self.bumps],
        }
