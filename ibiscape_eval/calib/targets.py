"""Planar calibration targets as Kalibr describes them: checkerboards and AprilGrids.

Target frame and corner numbering (``../shared/FORMATS.md``):

- checkerboard: ``targetRows`` x ``targetCols`` *inner* corners, ``rowSpacingMeters`` /
  ``colSpacingMeters``; corner ``index = row * targetCols + col`` at ``(col * sx, row * sy, 0)``
  (OpenCV's object-point order, origin at the first inner corner).
- AprilGrid (tag36h11): ``tagRows`` x ``tagCols`` tags of ``tagSize`` metres (edge to edge of the
  black border) separated by ``tagSpacing * tagSize``.  ``2 tagRows x 2 tagCols`` corners, corner
  ``(r, c)`` at ``x = floor(c / 2) (1 + tagSpacing) tagSize + (c mod 2) tagSize`` (y likewise with r),
  numbered row-major from the bottom left; tag ``id`` owns the corners
  ``[base, base + 1, base + C + 1, base + C]`` with ``C = 2 tagCols`` and
  ``base = 2 C floor(id / tagCols) + 2 (id mod tagCols)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError

__all__ = ["TARGET_TYPES", "CalibrationTarget", "target_from_kalibr"]

TARGET_TYPES = ("checkerboard", "aprilgrid")
FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class CalibrationTarget:
    """A planar target: its type, its Kalibr parameters and its corner points.

    Attributes
    ----------
    target_type : str
        ``"checkerboard"`` or ``"aprilgrid"``.
    rows, cols : int
        Checkerboard: inner corners; AprilGrid: tags.
    spacing_x_m, spacing_y_m : float
        Checkerboard square size along columns / rows [m].
    tag_size_m, tag_spacing : float
        AprilGrid tag edge [m] and gap as a fraction of the tag edge.
    """

    target_type: str
    rows: int
    cols: int
    spacing_x_m: float = 0.0
    spacing_y_m: float = 0.0
    tag_size_m: float = 0.0
    tag_spacing: float = 0.0

    def __post_init__(self) -> None:
        if self.target_type not in TARGET_TYPES:
            raise IbiscapeError(f"target_type {self.target_type!r}: use checkerboard or aprilgrid")
        if self.rows < 1 or self.cols < 1:
            raise IbiscapeError(f"target size {self.rows}x{self.cols}: give positive counts")
        if self.target_type == "checkerboard":
            if self.rows < 2 or self.cols < 2:
                raise IbiscapeError(f"checkerboard with {self.rows}x{self.cols} inner corners: "
                                    "give at least 2x2 (inner corners, not squares)")
            if not (self.spacing_x_m > 0 and self.spacing_y_m > 0):
                raise IbiscapeError(f"checkerboard spacing {self.spacing_x_m} x {self.spacing_y_m} m: "
                                    "give positive rowSpacingMeters and colSpacingMeters")
        elif not (self.tag_size_m > 0 and self.tag_spacing > 0):
            raise IbiscapeError(f"aprilgrid tagSize {self.tag_size_m} m, tagSpacing {self.tag_spacing}: "
                                "give positive values (tagSpacing is the gap / tag size, e.g. 0.3)")

    # ------------------------------------------------------------------------------------ corners
    @property
    def corner_rows(self) -> int:
        """Rows of the corner grid."""
        return self.rows if self.target_type == "checkerboard" else 2 * self.rows

    @property
    def corner_cols(self) -> int:
        """Columns of the corner grid."""
        return self.cols if self.target_type == "checkerboard" else 2 * self.cols

    @property
    def n_corners(self) -> int:
        return self.corner_rows * self.corner_cols

    def object_points(self) -> FloatArray:
        """Corner points in the target frame, shape (M, 3) [m], in Kalibr's numbering."""
        r, c = np.divmod(np.arange(self.n_corners), self.corner_cols)
        if self.target_type == "checkerboard":
            x, y = c * self.spacing_x_m, r * self.spacing_y_m
        else:
            step = (1.0 + self.tag_spacing) * self.tag_size_m
            x = (c // 2) * step + (c % 2) * self.tag_size_m
            y = (r // 2) * step + (r % 2) * self.tag_size_m
        return np.stack([x, y, np.zeros(self.n_corners)], axis=-1).astype(np.float64)

    def tag_corner_ids(self, tag_ids: npt.ArrayLike) -> npt.NDArray[np.int64]:
        """Kalibr corner ids ``(T, 4)`` of AprilGrid tags (bottom-left, bottom-right, top-right,
        top-left on the board)."""
        ids = np.asarray(tag_ids, dtype=np.int64)
        C = 2 * self.cols
        base = (ids // self.cols) * 2 * C + (ids % self.cols) * 2
        return np.stack([base, base + 1, base + C + 1, base + C], axis=-1)

    def symmetries(self) -> list[npt.NDArray[np.int64]]:
        """Corner-index permutations under which the corner set maps onto itself by a rigid motion.

        A checkerboard detector may number the corners from any of these starting points; the
        AprilGrid has unique tag ids and only the identity.  ``perm[i]`` is the corner that
        index ``i`` becomes.
        """
        n_r, n_c = self.corner_rows, self.corner_cols
        idx = np.arange(n_r * n_c).reshape(n_r, n_c)
        if self.target_type == "aprilgrid":
            return [idx.ravel()]
        # a mirrored numbering is a proper rotation too: the planar board turned over (z flips)
        perms = [idx, idx[::-1, ::-1], idx[::-1, :], idx[:, ::-1]]
        if n_r == n_c and self.spacing_x_m == self.spacing_y_m:
            perms += [np.rot90(idx, 1), np.rot90(idx, 3), idx.T, idx.T[::-1, ::-1]]
        return [p.ravel().copy() for p in perms]

    def to_kalibr(self) -> dict[str, Any]:
        """Kalibr's target yaml keys."""
        if self.target_type == "checkerboard":
            return {"target_type": "checkerboard", "targetRows": self.rows, "targetCols": self.cols,
                    "rowSpacingMeters": self.spacing_y_m, "colSpacingMeters": self.spacing_x_m}
        return {"target_type": "aprilgrid", "tagRows": self.rows, "tagCols": self.cols,
                "tagSize": self.tag_size_m, "tagSpacing": self.tag_spacing}

    def __repr__(self) -> str:
        if self.target_type == "checkerboard":
            return (f"CalibrationTarget(checkerboard {self.rows}x{self.cols} inner corners, "
                    f"{self.spacing_x_m:g} x {self.spacing_y_m:g} m)")
        return (f"CalibrationTarget(aprilgrid {self.rows}x{self.cols} tags, {self.tag_size_m:g} m, "
                f"spacing {self.tag_spacing:g})")


_KEYS = {
    "checkerboard": ("targetRows", "targetCols", "rowSpacingMeters", "colSpacingMeters"),
    "aprilgrid": ("tagRows", "tagCols", "tagSize", "tagSpacing"),
}


def target_from_kalibr(doc: Any, *, source: str = "target") -> CalibrationTarget:
    """Build a target from Kalibr's target yaml mapping.

    Raises :class:`IbiscapeError` naming ``source`` and the missing or wrong key.
    """
    if not isinstance(doc, dict):
        raise IbiscapeError(f"{source}: expected a mapping with target_type and its keys, "
                            f"got {type(doc).__name__}")
    kind = doc.get("target_type")
    if kind not in _KEYS:
        raise IbiscapeError(f"{source}: target_type is {kind!r}; use checkerboard or aprilgrid "
                            "(Kalibr's target yaml)")
    missing = [k for k in _KEYS[kind] if k not in doc]
    if missing:
        raise IbiscapeError(f"{source}: a {kind} target needs the keys {', '.join(_KEYS[kind])}; "
                            f"missing {', '.join(missing)}")
    a, b, c, d = (doc[k] for k in _KEYS[kind])
    try:
        if isinstance(a, bool) or isinstance(b, bool) or int(a) != a or int(b) != b:
            raise ValueError
        rows, cols, p, q = int(a), int(b), float(c), float(d)
    except (TypeError, ValueError):
        raise IbiscapeError(f"{source}: {_KEYS[kind][0]}, {_KEYS[kind][1]} must be integers and "
                            f"{_KEYS[kind][2]}, {_KEYS[kind][3]} numbers, got {a!r}, {b!r}, {c!r}, "
                            f"{d!r}") from None
    if not (np.isfinite(p) and np.isfinite(q)):
        raise IbiscapeError(f"{source}: sizes must be finite, got {c!r}, {d!r}")
    try:
        if kind == "checkerboard":
            return CalibrationTarget(kind, rows, cols, spacing_x_m=q, spacing_y_m=p)
        return CalibrationTarget(kind, rows, cols, tag_size_m=p, tag_spacing=q)
    except IbiscapeError as e:
        raise IbiscapeError(f"{source}: {e}") from None
