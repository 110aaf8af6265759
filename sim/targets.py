"""Calibration targets as Kalibr describes them: a 7x7 checkerboard and a 6x6 tag36h11 AprilGrid.

Target frames (``T_world_target`` maps target coordinates to the world):

- checkerboard: origin at inner corner 0, x along the columns, y along the rows, corners numbered
  row-major (``index = row * targetCols + col``), OpenCV's object-point convention.  Seen from the
  observer the x axis points right, y down, so the board normal z points *away* from the observer.
- AprilGrid: Kalibr's numbering (``../shared/FORMATS.md``): corner (r, c) at
  ``x = floor(c / 2) (1 + tagSpacing) tagSize + (c mod 2) tagSize`` (y likewise with r), numbered
  row-major from the bottom-left corner of tag 0.  Kalibr prints the grid with y pointing *up* on the
  page (tag 0 at the bottom left), so for a readable (non-mirrored) print z = x cross y points
  *toward* the observer.  (A frame with z away from the observer would need a mirrored print, on
  which no AprilTag detector finds a tag.)

``texture(px_per_m)`` draws the printed face as seen by the observer (image row 0 at the top), and
``texture_px_from_target`` maps target coordinates to texture pixels (OpenCV convention: pixel
centres at integer coordinates), so a renderer can map the image onto the board.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.kalibr import CalibrationTarget

__all__ = ["TARGET_KINDS", "Target", "make_target"]

FloatArray = npt.NDArray[np.float64]
TARGET_KINDS = ("checkerboard", "aprilgrid")

# Realistic sizes for a board seen from a car at 3-15 m (a 0.5 m square is 17 px wide at 15 m
# with f = 512 px).  A tag36h11 tag with its 2-cell border is 10 cells wide: a 0.55 m tag is
# 13-41 px in 512 px images (f = 256 px) on the AprilGrid's shuttle drive (3.4-11 m).  Measured on
# a 12 s drive at 512 px: 0.55 m tags gave focal 0.13 px and principal point 0.08 px, 0.4 m tags
# 0.72 px and 0.64 px (fewer tags decoded far away).
CHECKER_SQUARE_M = 0.5
CHECKER_INNER = 7
APRIL_TAG_SIZE_M = 0.55
APRIL_TAG_SPACING = 0.3
APRIL_TAGS = 6
_MARGIN_M = 0.3  # white quiet zone around the pattern


@dataclass(frozen=True, eq=False)
class Target:
    """A planar calibration target placed in the world.

    Attributes
    ----------
    board : CalibrationTarget
        The pattern (Kalibr's parameters and corner geometry).
    T_world_target : ndarray, shape (4, 4)
    board_min_m, board_max_m : ndarray, shape (2,)
        Extent of the printed board (pattern plus white margin) in target x, y, metres.
    z_toward_observer : bool
        Whether the target z axis points toward the side the board is seen from.
    """

    board: CalibrationTarget
    T_world_target: FloatArray
    board_min_m: FloatArray
    board_max_m: FloatArray
    z_toward_observer: bool

    @property
    def target_type(self) -> str:
        """``"checkerboard"`` or ``"aprilgrid"``."""
        return self.board.target_type

    @property
    def kalibr(self) -> dict[str, Any]:
        """Kalibr's target yaml keys (``target_type`` included)."""
        return self.board.to_kalibr()

    @cached_property
    def corners_target_m(self) -> FloatArray:
        """Corner points ``(M, 3)`` in Kalibr's numbering, target frame, metres (z = 0)."""
        return self.board.object_points()

    @property
    def board_size_m(self) -> FloatArray:
        """Width and height of the printed board, metres."""
        return self.board_max_m - self.board_min_m

    @property
    def centre_world_m(self) -> FloatArray:
        """Centre of the corner pattern in the world, shape (3,)."""
        c = self.corners_target_m.mean(axis=0)
        return self.T_world_target[:3, :3] @ c + self.T_world_target[:3, 3]

    @property
    def observer_normal_world(self) -> FloatArray:
        """Unit board normal pointing toward the side the printed face is seen from, shape (3,)."""
        z = self.T_world_target[:3, 2]
        return z if self.z_toward_observer else -z

    def corners_world_m(self) -> FloatArray:
        """Corner points in the world frame, shape (M, 3), metres."""
        R, t = self.T_world_target[:3, :3], self.T_world_target[:3, 3]
        return self.corners_target_m @ R.T + t

    def texture_px_from_target(self, xy_m: npt.ArrayLike, px_per_m: float) -> FloatArray:
        """Texture pixel coordinates ``(N, 2)`` (column, row) of target points ``(N, 2)``."""
        xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
        col = (xy[:, 0] - self.board_min_m[0]) * px_per_m - 0.5
        if self.z_toward_observer:  # y up as seen: rows grow with decreasing y
            row = (self.board_max_m[1] - xy[:, 1]) * px_per_m - 0.5
        else:
            row = (xy[:, 1] - self.board_min_m[1]) * px_per_m - 0.5
        return np.stack((col, row), -1)

    def _target_xy_of_pixels(self, px_per_m: float) -> tuple[FloatArray, FloatArray]:
        w, h = np.round(self.board_size_m * px_per_m).astype(int)
        x = self.board_min_m[0] + (np.arange(w) + 0.5) / px_per_m
        if self.z_toward_observer:
            y = self.board_max_m[1] - (np.arange(h) + 0.5) / px_per_m
        else:
            y = self.board_min_m[1] + (np.arange(h) + 0.5) / px_per_m
        return x, y

    def texture(self, px_per_m: float) -> npt.NDArray[np.uint8]:
        """The printed board as seen from the front, black (0) and white (255).

        Parameters
        ----------
        px_per_m : float
            Resolution; the AprilGrid needs at least 2 px per code cell (``tagSize / 10``).

        Returns
        -------
        ndarray, shape (H, W), uint8
        """
        if not (px_per_m > 0.0 and np.isfinite(px_per_m)):
            raise IbiscapeError(f"px_per_m must be > 0, got {px_per_m}")
        x, y = self._target_xy_of_pixels(px_per_m)
        X, Y = np.meshgrid(x, y)
        if self.target_type == "checkerboard":
            sx = self.kalibr["colSpacingMeters"]
            sy = self.kalibr["rowSpacingMeters"]
            i = np.floor(X / sx).astype(int)  # square index, -1 .. cols
            j = np.floor(Y / sy).astype(int)
            cols, rows = self.kalibr["targetCols"], self.kalibr["targetRows"]
            on = (i >= -1) & (i <= cols - 1) & (j >= -1) & (j <= rows - 1)
            black = on & ((i + j) % 2 == 0)
            return np.where(black, 0, 255).astype(np.uint8)
        return self._april_texture(X, Y, px_per_m)

    def _april_texture(self, X: FloatArray, Y: FloatArray, px_per_m: float) -> npt.NDArray[np.uint8]:
        import cv2

        ts = self.kalibr["tagSize"]
        gap = self.kalibr["tagSpacing"] * ts
        pitch = ts + gap
        n_r, n_c = self.kalibr["tagRows"], self.kalibr["tagCols"]
        img = np.full(X.shape, 255, dtype=np.uint8)
        # position inside the tag lattice
        tc = np.floor((X + gap) / pitch).astype(int)
        tr = np.floor((Y + gap) / pitch).astype(int)
        ux = X - tc * pitch  # in [-gap, ts) : < 0 is the gap before the tag
        uy = Y - tr * pitch
        in_grid_x = (tc >= 0) & (tc <= n_c)
        in_grid_y = (tr >= 0) & (tr <= n_r)
        # black squares at every tag corner: gap x gap squares where both coordinates are in a gap
        corner_sq = in_grid_x & in_grid_y & (ux < 0.0) & (uy < 0.0)
        img[corner_sq] = 0
        in_tag = (tc < n_c) & (tr < n_r) & (tc >= 0) & (tr >= 0) & (ux >= 0.0) & (uy >= 0.0)
        dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
        codes = np.stack(
            [
                # 10 x 10 cells: 2-cell black border around the 6x6 code, drawn rotated by 180 deg
                np.rot90(cv2.aruco.generateImageMarker(dictionary, k, 10, borderBits=2), 2)
                for k in range(n_r * n_c)
            ]
        )
        ids = tr * n_c + tc
        # cell indices in the tag as seen (row 0 at the top = high y)
        cell_c = np.clip(np.floor(ux / ts * 10.0).astype(int), 0, 9)
        cell_r = np.clip(9 - np.floor(uy / ts * 10.0).astype(int), 0, 9)
        if not self.z_toward_observer:  # pragma: no cover - the AprilGrid is always y-up
            cell_r = 9 - cell_r
        img[in_tag] = codes[ids[in_tag], cell_r[in_tag], cell_c[in_tag]]
        return img

    def to_dict(self) -> dict[str, Any]:
        """Kalibr keys plus pose and board size, for ``sequence.yaml``."""
        doc = dict(self.kalibr)
        doc["T_world_target"] = self.T_world_target.tolist()
        doc["board_size_m"] = [float(v) for v in self.board_size_m]
        doc["corner_count"] = len(self.corners_target_m)
        doc["z_toward_observer"] = bool(self.z_toward_observer)
        return doc


def make_target(kind: str, *, T_world_target: npt.ArrayLike, tag_size_m: float = APRIL_TAG_SIZE_M) -> Target:
    """A Kalibr target of the paper's layout (checkerboard 7x7 inner corners, AprilGrid 6x6).

    Parameters
    ----------
    kind : str
        ``"checkerboard"`` or ``"aprilgrid"``.
    T_world_target : array_like, shape (4, 4)
        Pose of the target frame (see the module docstring for the frame of each kind).
    tag_size_m : float
        AprilGrid: the tag size (the simulator's calibration world uses the default).

    Returns
    -------
    Target
    """
    T = np.array(T_world_target, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise IbiscapeError(f"T_world_target must be a finite 4x4 matrix, got shape {T.shape}")
    R = T[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
        raise IbiscapeError("T_world_target's rotation is not a proper rotation matrix")
    if kind == "checkerboard":
        s, n = CHECKER_SQUARE_M, CHECKER_INNER
        lo = np.array([-s - _MARGIN_M, -s - _MARGIN_M])
        hi = np.array([n * s + _MARGIN_M, n * s + _MARGIN_M])
        return Target(CalibrationTarget.checkerboard(n, n, s), T, lo, hi, False)
    if kind == "aprilgrid":
        ts, sp, n = float(tag_size_m), APRIL_TAG_SPACING, APRIL_TAGS
        if not ts > 0.0:
            raise IbiscapeError(f"tag_size_m must be > 0, got {tag_size_m}")
        span = n * ts + (n - 1) * sp * ts
        lo = np.full(2, -sp * ts - _MARGIN_M)
        hi = np.full(2, span + sp * ts + _MARGIN_M)
        return Target(CalibrationTarget.aprilgrid(n, n, ts, sp), T, lo, hi, True)
    raise IbiscapeError(f"target kind {kind!r} is unknown; use one of {TARGET_KINDS}")


def board_pose(kind: str, centre_world_m: npt.ArrayLike, facing_yaw_rad: float,
               lean_rad: float = 0.0) -> FloatArray:
    """``T_world_target`` of a board whose printed face looks along ``facing_yaw_rad``.

    The pattern's centre lands on ``centre_world_m``; ``facing_yaw_rad`` is the horizontal direction
    from the board toward its observers; ``lean_rad`` tips the board's top away from them (0:
    upright; positive: the face looks up).
    """
    h = np.array([np.cos(facing_yaw_rad), np.sin(facing_yaw_rad), 0.0])  # toward the observer
    right = np.array([-np.sin(facing_yaw_rad), np.cos(facing_yaw_rad), 0.0])  # observer's right
    z = np.array([0.0, 0.0, 1.0])
    f = np.cos(lean_rad) * h + np.sin(lean_rad) * z
    up = np.cos(lean_rad) * z - np.sin(lean_rad) * h
    if kind == "checkerboard":
        R = np.stack((right, -up, -f), axis=1)  # x right, y down, z away
        centre_t = np.array([3.0, 3.0, 0.0]) * CHECKER_SQUARE_M
    else:
        R = np.stack((right, up, f), axis=1)  # x right, y up, z toward
        span = APRIL_TAGS * APRIL_TAG_SIZE_M + (APRIL_TAGS - 1) * APRIL_TAG_SPACING * APRIL_TAG_SIZE_M
        centre_t = np.array([0.5 * span, 0.5 * span, 0.0])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(centre_world_m, dtype=np.float64) - R @ centre_t
    return T
