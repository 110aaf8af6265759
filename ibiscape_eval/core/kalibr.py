"""Kalibr's calibration files as typed values: the target, the IMU noise and the camera chain.

One type per file, with one reader and one writer each in :mod:`ibiscape_eval.io.kalibr`:

- target yaml -> :class:`CalibrationTarget` (checkerboard or AprilGrid, with its 3-D corner
  points in Kalibr's numbering);
- ``imu.yaml`` -> :class:`ImuNoise` (continuous-time densities and random walks, rate, topic);
  also the ``imus.<name>`` entry of our ``sequence.yaml`` and an EuRoC IMU ``sensor.yaml``;
- ``camchain.yaml`` and ``camchain-imucam.yaml`` -> :class:`CameraChain` of :class:`ChainCamera`
  (intrinsics, distortion, resolution, ``T_cn_cnm1``, ``T_cam_imu``, ``timeshift_cam_imu``,
  ``rostopic``).

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

IMU noise is Kalibr's continuous-time convention: per-sample sigma = density * sqrt(rate), bias
step sigma = random walk * sqrt(dt).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from .camera import CameraModel
from .errors import FormatError, IbiscapeError

__all__ = [
    "IMU_NOISE_FLOOR",
    "MAX_LEVER_ARM_M",
    "TARGET_TYPES",
    "CalibrationTarget",
    "CameraChain",
    "ChainCamera",
    "ImuNoise",
    "check_camchain_matches",
    "rigid_transform_problem",
    "target_from_kalibr",
]

FloatArray = npt.NDArray[np.float64]
TARGET_TYPES = ("checkerboard", "aprilgrid")
#: the largest board a target description may give: squares / tags up to 10 m, up to 1000 rows or
#: columns, a checkerboard cell at most 10 times longer than wide, tag gaps up to 10 tag sizes
MAX_TARGET_CELL_M = 10.0
MAX_TARGET_COUNT = 1000
MAX_CELL_ASPECT = 10.0
MAX_TAG_SPACING = 10.0


# ============================================================================================ target
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
        if not (1 <= self.rows <= MAX_TARGET_COUNT and 1 <= self.cols <= MAX_TARGET_COUNT):
            raise IbiscapeError(f"target size {self.rows}x{self.cols}: give counts in 1..{MAX_TARGET_COUNT}")
        if self.target_type == "checkerboard":
            if self.rows < 2 or self.cols < 2:
                raise IbiscapeError(f"checkerboard with {self.rows}x{self.cols} inner corners: "
                                    "give at least 2x2 (inner corners, not squares)")
            sx, sy = self.spacing_x_m, self.spacing_y_m
            if not (0 < sx <= MAX_TARGET_CELL_M and 0 < sy <= MAX_TARGET_CELL_M):
                raise IbiscapeError(f"checkerboard spacing {sx} x {sy} m: give rowSpacingMeters and "
                                    f"colSpacingMeters in (0, {MAX_TARGET_CELL_M:g}] m (the square size)")
            if max(sx / sy, sy / sx) > MAX_CELL_ASPECT:
                raise IbiscapeError(f"checkerboard spacing {sx} x {sy} m: a square more than "
                                    f"{MAX_CELL_ASPECT:g} times longer than wide; check the units of "
                                    "rowSpacingMeters and colSpacingMeters")
        elif not (0 < self.tag_size_m <= MAX_TARGET_CELL_M and 0 < self.tag_spacing <= MAX_TAG_SPACING):
            raise IbiscapeError(f"aprilgrid tagSize {self.tag_size_m} m, tagSpacing {self.tag_spacing}: "
                                f"give tagSize in (0, {MAX_TARGET_CELL_M:g}] m and tagSpacing in (0, "
                                f"{MAX_TAG_SPACING:g}] (the gap / tag size, e.g. 0.3)")

    @classmethod
    def checkerboard(cls, rows: int, cols: int, square_m: float) -> CalibrationTarget:
        """A checkerboard of ``rows`` x ``cols`` inner corners and square squares."""
        return cls("checkerboard", rows, cols, spacing_x_m=square_m, spacing_y_m=square_m)

    @classmethod
    def aprilgrid(cls, rows: int, cols: int, tag_size_m: float, tag_spacing: float) -> CalibrationTarget:
        """An AprilGrid of ``rows`` x ``cols`` tags."""
        return cls("aprilgrid", rows, cols, tag_size_m=tag_size_m, tag_spacing=tag_spacing)

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

    @classmethod
    def from_kalibr(cls, doc: Any, *, source: str = "target") -> CalibrationTarget:
        """From Kalibr's target yaml mapping (or ``sequence.yaml``'s ``target``); see
        :func:`target_from_kalibr`."""
        return target_from_kalibr(doc, source=source)

    def __repr__(self) -> str:
        if self.target_type == "checkerboard":
            return (f"CalibrationTarget(checkerboard {self.rows}x{self.cols} inner corners, "
                    f"{self.spacing_x_m:g} x {self.spacing_y_m:g} m)")
        return (f"CalibrationTarget(aprilgrid {self.rows}x{self.cols} tags, {self.tag_size_m:g} m, "
                f"spacing {self.tag_spacing:g})")


_TARGET_KEYS = {
    "checkerboard": ("targetRows", "targetCols", "rowSpacingMeters", "colSpacingMeters"),
    "aprilgrid": ("tagRows", "tagCols", "tagSize", "tagSpacing"),
}


def target_from_kalibr(doc: Any, *, source: str = "target") -> CalibrationTarget:
    """Build a target from Kalibr's target yaml mapping.

    Raises :class:`IbiscapeError` naming ``source`` and the missing or wrong key.
    """
    if not isinstance(doc, Mapping):
        raise IbiscapeError(f"{source}: expected a mapping with target_type and its keys, "
                            f"got {type(doc).__name__}")
    kind = doc.get("target_type")
    if kind not in _TARGET_KEYS:
        raise IbiscapeError(f"{source}: target_type is {kind!r}; use checkerboard or aprilgrid "
                            "(Kalibr's target yaml)")
    keys = _TARGET_KEYS[kind]
    missing = [k for k in keys if k not in doc]
    if missing:
        raise IbiscapeError(f"{source}: a {kind} target needs the keys {', '.join(keys)}; "
                            f"missing {', '.join(missing)}")
    a, b, c, d = (doc[k] for k in keys)
    try:
        if isinstance(a, bool) or isinstance(b, bool) or int(a) != a or int(b) != b:
            raise ValueError
        rows, cols, p, q = int(a), int(b), float(c), float(d)
    except (TypeError, ValueError, OverflowError):
        raise IbiscapeError(f"{source}: {keys[0]}, {keys[1]} must be integers and "
                            f"{keys[2]}, {keys[3]} numbers, got {a!r}, {b!r}, {c!r}, "
                            f"{d!r}") from None
    if not (np.isfinite(p) and np.isfinite(q)):
        raise IbiscapeError(f"{source}: sizes must be finite, got {c!r}, {d!r}")
    try:
        if kind == "checkerboard":
            return CalibrationTarget(kind, rows, cols, spacing_x_m=q, spacing_y_m=p)
        return CalibrationTarget(kind, rows, cols, tag_size_m=p, tag_spacing=q)
    except IbiscapeError as e:
        raise IbiscapeError(f"{source}: {e}") from None


# ========================================================================================= IMU noise
#: Kalibr key, our field, accepted range (far beyond any real IMU, tight enough to keep an
#: estimator's information matrices well conditioned), unit
_IMU_KEYS: tuple[tuple[str, str, float, str], ...] = (
    ("accelerometer_noise_density", "accel_noise_density_m_s2_sqrt_hz", 10.0, "m/s^2/sqrt(Hz)"),
    ("accelerometer_random_walk", "accel_random_walk_m_s3_sqrt_hz", 10.0, "m/s^3/sqrt(Hz)"),
    ("gyroscope_noise_density", "gyro_noise_density_rad_s_sqrt_hz", 1.0, "rad/s/sqrt(Hz)"),
    ("gyroscope_random_walk", "gyro_random_walk_rad_s2_sqrt_hz", 1.0, "rad/s^2/sqrt(Hz)"),
)
MAX_IMU_RATE_HZ = 1e5
#: the least density an estimator puts under an ideal (zero-noise) sensor, so that its information
#: stays finite: gyro, gyro walk, accel, accel walk
IMU_NOISE_FLOOR = {"gyro_noise_density_rad_s_sqrt_hz": 1e-5, "gyro_random_walk_rad_s2_sqrt_hz": 1e-6,
                   "accel_noise_density_m_s2_sqrt_hz": 1e-4, "accel_random_walk_m_s3_sqrt_hz": 1e-5}


@dataclass(frozen=True, kw_only=True)
class ImuNoise:
    """Continuous-time IMU noise (Kalibr's ``imu.yaml``); keyword-only, so no field order to get
    wrong.

    Attributes
    ----------
    gyro_noise_density_rad_s_sqrt_hz : float
        Gyroscope white noise [rad/s/sqrt(Hz)] (``gyroscope_noise_density``).
    gyro_random_walk_rad_s2_sqrt_hz : float
        Gyroscope bias random walk [rad/s^2/sqrt(Hz)] (``gyroscope_random_walk``).
    accel_noise_density_m_s2_sqrt_hz : float
        Accelerometer white noise [m/s^2/sqrt(Hz)] (``accelerometer_noise_density``).
    accel_random_walk_m_s3_sqrt_hz : float
        Accelerometer bias random walk [m/s^3/sqrt(Hz)] (``accelerometer_random_walk``).
    update_rate_hz : float
        The sample rate the file states (``update_rate``).
    rostopic : str or None
        The IMU topic, when the file names one.

    Zero densities are allowed (a noise-free, simulated sensor says so); :meth:`floored` gives the
    values an estimator can weigh with.
    """

    gyro_noise_density_rad_s_sqrt_hz: float
    gyro_random_walk_rad_s2_sqrt_hz: float
    accel_noise_density_m_s2_sqrt_hz: float
    accel_random_walk_m_s3_sqrt_hz: float
    update_rate_hz: float
    rostopic: str | None = None

    def __post_init__(self) -> None:
        for key, name, hi, unit in _IMU_KEYS:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not (0.0 <= v <= hi):
                raise IbiscapeError(f"{key} = {v!r} is out of range; give a number in [0, {hi:g}] {unit} "
                                    "(e.g. from `ibiscape-eval allan IMU --yaml imu.yaml`)")
            object.__setattr__(self, name, float(v))
        r = self.update_rate_hz
        if isinstance(r, bool) or not isinstance(r, int | float) or not (0.0 < r <= MAX_IMU_RATE_HZ):
            raise IbiscapeError(f"update_rate = {r!r} is out of range; give the IMU sample rate in Hz, in "
                                f"(0, {MAX_IMU_RATE_HZ:g}]")
        object.__setattr__(self, "update_rate_hz", float(r))
        if self.rostopic is not None and not isinstance(self.rostopic, str):
            raise IbiscapeError(f"rostopic = {self.rostopic!r}: give a topic name or nothing")

    @property
    def is_ideal(self) -> bool:
        """Whether any density is zero (a noise-free sensor)."""
        return any(getattr(self, name) == 0.0 for _, name, _, _ in _IMU_KEYS)

    def floored(self) -> ImuNoise:
        """The densities raised to at least :data:`IMU_NOISE_FLOOR` (what an estimator weighs
        with when the file describes an ideal sensor)."""
        return replace(self, **{k: max(getattr(self, k), v) for k, v in IMU_NOISE_FLOOR.items()})

    @classmethod
    def from_kalibr(cls, doc: Any, *, source: str = "imu.yaml") -> ImuNoise:
        """From a Kalibr ``imu.yaml`` mapping, a ``sequence.yaml`` ``imus.<name>`` entry or an
        EuRoC IMU ``sensor.yaml`` (its rate is ``rate_hz``).

        Raises :class:`FormatError` naming ``source`` and the missing or bad key.
        """
        if not isinstance(doc, Mapping):
            raise FormatError(source, "expected a mapping with the Kalibr IMU keys "
                              f"{', '.join(k for k, *_ in _IMU_KEYS)}, update_rate")
        rate_key = "update_rate" if "update_rate" in doc or "rate_hz" not in doc else "rate_hz"
        missing = [k for k, *_ in _IMU_KEYS if k not in doc] + ([] if rate_key in doc else ["update_rate"])
        if missing:
            raise FormatError(source, f"missing key(s) {', '.join(missing)}; give Kalibr's imu.yaml "
                              "(e.g. `ibiscape-eval allan IMU --yaml imu.yaml`)")
        vals: dict[str, Any] = {}
        for key, name, *_ in (*_IMU_KEYS, (rate_key, "update_rate_hz", 0.0, "Hz")):
            raw = doc[key]
            try:
                if isinstance(raw, bool):
                    raise ValueError
                vals[name] = float(raw)
            except (TypeError, ValueError, OverflowError):
                raise FormatError(source, f"{key} = {raw!r} is not a number") from None
        topic = doc.get("rostopic")
        try:
            return cls(**vals, rostopic=None if topic is None else str(topic))
        except IbiscapeError as e:
            raise FormatError(source, str(e)) from None

    def to_kalibr(self) -> dict[str, Any]:
        """Kalibr's ``imu.yaml`` keys, in Kalibr's order (``rostopic`` when known)."""
        doc: dict[str, Any] = {key: getattr(self, name) for key, name, *_ in _IMU_KEYS}
        if self.rostopic is not None:
            doc["rostopic"] = self.rostopic
        doc["update_rate"] = self.update_rate_hz
        return doc

    def __repr__(self) -> str:
        return (f"ImuNoise(gyro {self.gyro_noise_density_rad_s_sqrt_hz:.3g} rad/s/rtHz "
                f"walk {self.gyro_random_walk_rad_s2_sqrt_hz:.3g}, accel "
                f"{self.accel_noise_density_m_s2_sqrt_hz:.3g} m/s^2/rtHz walk "
                f"{self.accel_random_walk_m_s3_sqrt_hz:.3g}, {self.update_rate_hz:g} Hz)")


# ====================================================================================== camera chain
#: the largest lever arm [m] accepted between two sensors of one rig
MAX_LEVER_ARM_M = 1000.0


def rigid_transform_problem(T: npt.ArrayLike) -> str | None:
    """What is wrong with a 4x4 rigid transform (None if it is one): finite, last row
    ``0 0 0 1``, an orthonormal rotation with determinant +1 (to 1e-5) and a translation shorter
    than :data:`MAX_LEVER_ARM_M`."""
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4) or not np.isfinite(T).all() or not np.allclose(T[3], [0, 0, 0, 1]):
        return "must be a finite homogeneous 4x4 matrix (last row 0 0 0 1)"
    R, t = T[:3, :3], T[:3, 3]
    if np.abs(R).max() > 1.0 + 1e-5:  # also keeps R @ R.T below from overflowing
        return "the rotation part is not a rotation matrix (orthonormal, determinant +1)"
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-5) or np.linalg.det(R) < 0:
        return "the rotation part is not a rotation matrix (orthonormal, determinant +1)"
    if np.abs(t).max() > MAX_LEVER_ARM_M:  # the max norm: no overflow on huge entries
        return (f"translation ({', '.join(f'{v:.3g}' for v in t)}) m reaches beyond "
                f"{MAX_LEVER_ARM_M:g} m")
    return None


def _checked_T(T: Any, what: str) -> FloatArray | None:
    if T is None:
        return None
    try:
        M = np.array(T, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise IbiscapeError(f"{what}: must be a 4x4 matrix of numbers") from None
    problem = "must be a 4x4 matrix" if M.shape != (4, 4) else rigid_transform_problem(M)
    if problem:
        raise IbiscapeError(f"{what}: {problem}")
    M.setflags(write=False)
    return M


@dataclass(frozen=True, eq=False)
class ChainCamera:
    """One camera of a Kalibr chain (a ``camN`` entry).

    Attributes
    ----------
    name : str
        ``cam0``, ``cam1``, ... or a sequence's camera name.
    camera : CameraModel
        Intrinsics, distortion and resolution.
    T_cn_cnm1 : ndarray (4, 4) or None
        Camera n-1 to camera n; None for the first camera.
    T_cam_imu : ndarray (4, 4) or None
        IMU to camera (``camchain-imucam.yaml``).
    timeshift_cam_imu_s : float or None
        ``t_imu = t_cam + shift`` [s].
    rostopic : str or None
    """

    name: str
    camera: CameraModel
    T_cn_cnm1: FloatArray | None = None
    T_cam_imu: FloatArray | None = None
    timeshift_cam_imu_s: float | None = None
    rostopic: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.camera, CameraModel):
            raise IbiscapeError(f"{self.name}: camera must be a CameraModel")
        object.__setattr__(self, "T_cn_cnm1", _checked_T(self.T_cn_cnm1, f"{self.name}.T_cn_cnm1"))
        object.__setattr__(self, "T_cam_imu", _checked_T(self.T_cam_imu, f"{self.name}.T_cam_imu"))
        if self.timeshift_cam_imu_s is not None:
            s = self.timeshift_cam_imu_s
            if isinstance(s, bool) or not isinstance(s, int | float) or not math.isfinite(s):
                raise IbiscapeError(f"{self.name}.timeshift_cam_imu = {s!r}: give seconds")
            object.__setattr__(self, "timeshift_cam_imu_s", float(s))

    @property
    def resolution(self) -> tuple[int, int]:
        """``(width, height)`` [px]."""
        return int(self.camera.width_px), int(self.camera.height_px)

    def __repr__(self) -> str:
        w, h = self.resolution
        return f"ChainCamera({self.name}, {w}x{h}{', T_cam_imu' if self.T_cam_imu is not None else ''})"


@dataclass(frozen=True, eq=False)
class CameraChain:
    """Cameras of a rig in chain order (Kalibr's ``camchain.yaml`` / ``camchain-imucam.yaml``).

    Every camera after the first has ``T_cn_cnm1``; a camchain-imucam also has ``T_cam_imu`` on
    every camera (then ``T_cn_cnm1`` is ``T_cn_imu inv(T_cnm1_imu)`` when the file omits it).
    """

    cameras: tuple[ChainCamera, ...]

    def __post_init__(self) -> None:
        cams = tuple(self.cameras)
        if not cams:
            raise IbiscapeError("camera chain: no cameras")
        names = [c.name for c in cams]
        if len(set(names)) != len(names):
            raise IbiscapeError(f"camera chain: names must be unique, got {names}")
        if cams[0].T_cn_cnm1 is not None:
            cams = (replace(cams[0], T_cn_cnm1=None), *cams[1:])
        for i in range(1, len(cams)):
            if cams[i].T_cn_cnm1 is None:
                a, b = cams[i - 1].T_cam_imu, cams[i].T_cam_imu
                if a is None or b is None:
                    raise IbiscapeError(f"{cams[i].name}: lacks T_cn_cnm1 (transform from "
                                        f"{cams[i - 1].name}) and T_cam_imu to derive it")
                cams = (*cams[:i], replace(cams[i], T_cn_cnm1=b @ np.linalg.inv(a)), *cams[i + 1:])
        object.__setattr__(self, "cameras", cams)

    def __len__(self) -> int:
        return len(self.cameras)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.cameras)

    @property
    def models(self) -> tuple[CameraModel, ...]:
        return tuple(c.camera for c in self.cameras)

    @property
    def rostopics(self) -> tuple[str | None, ...]:
        return tuple(c.rostopic for c in self.cameras)

    @property
    def relative_transforms(self) -> tuple[FloatArray, ...]:
        """``T_cn_cnm1`` of every camera after the first (n-1 of them)."""
        return tuple(c.T_cn_cnm1 for c in self.cameras[1:] if c.T_cn_cnm1 is not None)

    @property
    def has_imu(self) -> bool:
        """Whether every camera has ``T_cam_imu`` (a camchain-imucam)."""
        return all(c.T_cam_imu is not None for c in self.cameras)

    def T_cn_c0(self, n: int) -> FloatArray:
        """Transform from camera 0 to camera n (product of the chain)."""
        T = np.eye(4)
        for k in range(1, n + 1):
            Tk = self.cameras[k].T_cn_cnm1
            assert Tk is not None
            T = Tk @ T
        return T

    @classmethod
    def from_relative(cls, names: Sequence[str], cameras: Sequence[CameraModel],
                      T_cn_cnm1: Sequence[npt.ArrayLike], rostopics: Sequence[str | None] | None = None
                      ) -> CameraChain:
        """A camchain from the n-1 relative transforms (one per camera after the first)."""
        if len(T_cn_cnm1) != max(len(cameras) - 1, 0) or len(names) != len(cameras):
            raise IbiscapeError("camera chain: names, cameras and n-1 transforms needed")
        topics = list(rostopics) if rostopics is not None else [None] * len(names)
        Ts = [None, *(np.asarray(T, dtype=np.float64) for T in T_cn_cnm1)]
        return cls(tuple(ChainCamera(n, c, T, None, None, t)
                         for n, c, T, t in zip(names, cameras, Ts, topics, strict=True)))

    @classmethod
    def from_imu_extrinsics(cls, names: Sequence[str], cameras: Sequence[CameraModel],
                            T_cam_imu: Sequence[npt.ArrayLike],
                            timeshift_cam_imu_s: Sequence[float], *,
                            rostopics: Sequence[str | None] | None = None) -> CameraChain:
        """A camchain-imucam: ``T_cn_cnm1`` follows from consecutive ``T_cam_imu``."""
        topics = list(rostopics) if rostopics is not None else [None] * len(names)
        return cls(tuple(ChainCamera(n, c, None, np.asarray(T, dtype=np.float64), float(s), t)
                         for n, c, T, s, t in zip(names, cameras, T_cam_imu, timeshift_cam_imu_s,
                                                  topics, strict=True)))

    def match(self, names: Sequence[str]) -> dict[str, int]:
        """Which chain camera each of a sequence's cameras ``names`` is: by the rostopic
        ``/<name>/...``, else by the entry name, else (a chain of other names, e.g. ``cam0,
        cam1``) by chain order.  Cameras without a match are left out."""
        topics = [f"{t}/" if t else "" for t in self.rostopics]
        any_topic = any(f"/{n}/" in t for t in topics for n in names)
        out: dict[str, int] = {}
        for i, name in enumerate(names):
            hit = [k for k, t in enumerate(topics) if f"/{name}/" in t]
            hit = hit or [k for k, n in enumerate(self.names) if n == name]
            if hit:
                out[name] = hit[0]
            elif not any_topic and not set(names) & set(self.names) and i < len(self.cameras):
                out[name] = i
        return out

    def __repr__(self) -> str:
        return f"CameraChain({', '.join(self.names)})"


def check_camchain_matches(chain: CameraChain, cameras: Mapping[str, tuple[int, int] | None], *,
                           source: str, require_all: bool = True) -> dict[str, int]:
    """Check a camchain against a sequence's cameras and say which entry each camera is.

    Parameters
    ----------
    chain : CameraChain
    cameras : mapping
        The sequence's camera names (in order) -> ``(width, height)`` [px] of its frames, or None
        when the sequence does not state it.
    source : str
        The camchain file, for the message.
    require_all : bool
        Refuse a sequence camera without an entry (default); False: leave it out of the result
        (the caller says what is missing), still checking the resolutions of the others.

    Returns
    -------
    dict
        Camera name -> index in ``chain.cameras`` (see :meth:`CameraChain.match`).

    Raises
    ------
    FormatError
        A sequence camera the camchain has no entry for (naming both sides' cameras), or a
        resolution that differs between the two.
    """
    names = list(cameras)
    found = chain.match(names)
    missing = [n for n in names if n not in found]
    if missing and require_all:
        have = ", ".join(f"{c.name}{f' ({c.rostopic})' if c.rostopic else ''}" for c in chain.cameras)
        raise FormatError(source, f"has no entry for the sequence's camera(s) {', '.join(missing)} "
                          f"(it has {have}; the sequence has {', '.join(names)}); give the "
                          "camchain of this rig or name its rostopics /<camera>/image_raw")
    for n in found:
        size = cameras[n]
        cam = chain.cameras[found[n]]
        if size is not None and tuple(int(v) for v in size) != cam.resolution:
            w, h = cam.resolution
            raise FormatError(source, f"{cam.name} is {w}x{h} px but the sequence's camera {n} "
                              f"is {int(size[0])}x{int(size[1])} px; give the camchain of this "
                              "rig (or of this image resolution)")
    return found
