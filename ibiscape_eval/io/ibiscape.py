r"""IBISCape ground truth, ``vehicle_gt/groundtruth_sync.csv``, and CARLA's left-handed frame.

File layout (as the public acquisition scripts write it)
---------------------------------------------------------
A header written by Python's ``csv.writer`` (``#timestamp [ns],p_RS_R_x_m_,...``, ending in
``\r\n``), then rows ``"%f,%21.21f,...,%21.21f \n"``: comma separated, a space before the newline,
the stamp a float of nanoseconds (``123456789000.000000``; some files have integers).  Columns::

    t_ns, p_x, p_y, p_z [m], v_x, v_y, v_z [m/s], a_x, a_y, a_z [m/s^2],
    q_w, q_x, q_y, q_z, w_x, w_y, w_z [rad/s]

(position, velocity, acceleration, quaternion w first, angular rate: not EuRoC's order).  All
vectors are CARLA world-frame quantities (``get_location``, ``get_velocity``,
``get_acceleration``, ``get_angular_velocity`` converted from deg/s to rad/s).

Frames: what the numbers in the file mean
-----------------------------------------
CARLA (Unreal) uses a left-handed frame: x forward, y right, z up.  Our world is right-handed:
x forward, y LEFT, z up.  With the mirror ``S = diag(1, -1, 1)``::

    p = S p_c,   v = S v_c,   a = S a_c,   R = S R_c S.

*Angular rate.*  CARLA's angular velocity obeys ``dR_c/dt = [w_c]x R_c`` with the ordinary
(coordinate) cross product.  Differentiating ``R = S R_c S`` gives
``dR/dt = S [w_c]x S R`` and for any 3x3 ``M``, ``M [w]x M^T = det(M) [M w]x``; with
``det S = -1``: ``dR/dt = [-S w_c]x R``, so ``w = -S w_c = (-w_x, w_y, -w_z)``.  A reflection
flips the sense of rotation: a car turning right (clockwise seen from above) has ``w_z > 0`` in
CARLA and ``w_z < 0`` in our frame, as it must.

*Orientation.*  CARLA's true rotation of a ``Rotation(pitch, yaw, roll)`` (degrees) is, from its
``Transform.get_matrix()``::

    R_c = Rz(yaw) Ry(-pitch) Rx(-roll)

(in CARLA, a positive pitch raises the nose: forward vector
``(cos p cos y, cos p sin y, sin p)``; ``Rz, Ry, Rx`` are the textbook matrices).  The IBISCape
scripts do NOT store ``R_c``: they build the quaternion with the textbook aerospace formula
``euler_to_quaternion(yaw, pitch, roll)`` (angles converted to radians), i.e. the file holds::

    R_f = Rz(yaw) Ry(pitch) Rx(roll).

Mirroring the true rotation (``S Rz(a) S = Rz(-a)``, ``S Ry(a) S = Ry(a)``, ``S Rx(a) S = Rx(-a)``)::

    R = S R_c S = Rz(-yaw) Ry(-pitch) Rx(roll) = X R_f X,   X = diag(-1, 1, 1)

because conjugating by ``X`` flips rotations about y and z and keeps those about x.  For a
quaternion, conjugation by a reflection ``M`` maps the axis ``u`` to ``det(M) M u``; with ``X``
that is ``(u_x, -u_y, -u_z)``, so the file's ``(w, x, y, z)`` becomes ``(x, -y, -z, w)`` in our
x, y, z, w order.  (Applying ``S . S`` to the file's quaternion instead would invert pitch and roll.)
Checks: a car with ``yaw_c = +90 deg`` drives along ``+y_c = -y`` and its body x axis
``R[:, 0] = (0, -1, 0)``; ``pitch_c > 0`` (nose up) gives ``R[2, 0] > 0``, nose up.  Both are
tested with files built by the scripts' formula.

The writer applies the inverse maps (all are involutions) and writes CARLA's frame exactly like
the scripts do (header, separators, trailing space; values with 15 significant digits).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.rotations import quat_conjugate, quat_multiply, rotvec_from_quat
from ibiscape_eval.core.trajectory import Trajectory

from ._poses import check_positions, check_quaternions, check_rows
from ._text import decimal_to_ns, parse_table, read_bytes, write_table
from .atomic import atomic_write

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "IBISCAPE_HEADER",
    "IbiscapeGroundTruth",
    "read_ibiscape",
    "read_ibiscape_groundtruth",
    "write_ibiscape",
    "write_ibiscape_groundtruth",
]

#: Header line exactly as ``csv.writer`` writes it in the acquisition scripts (without \r\n).
IBISCAPE_HEADER = (
    "#timestamp [ns],p_RS_R_x_m_,p_RS_R_y_m_,p_RS_R_z_m_,v_RS_R_x_mS__1_,v_RS_R_y_mS__1_,"
    "v_RS_R_z_mS__1_,a_RS_S_x_mS__2_,a_RS_S_y_mS__2_,a_RS_S_z_mS__2_,q_RS_w__,q_RS_x__,"
    "q_RS_y__,q_RS_z__,w_RS_S_x_radS__1_,w_RS_S_y_radS__1_,w_RS_S_z_radS__1_"
)
_EXPECTED = ("17 columns (timestamp [ns], p_x, p_y, p_z, v_x, v_y, v_z, a_x, a_y, a_z, "
             "q_w, q_x, q_y, q_z, w_x, w_y, w_z)")
_S = np.array([1.0, -1.0, 1.0])  # the mirror y -> -y between CARLA's frame and ours


@dataclass(frozen=True, eq=False)
class IbiscapeGroundTruth:
    """IBISCape vehicle ground truth in OUR right-handed world frame (x forward, y left, z up).

    Attributes
    ----------
    trajectory : Trajectory
        Poses ``T_world_body``, stamps in int64 ns.
    vel_m_s : ndarray, shape (N, 3)
        Velocity of the body origin in the world frame, m/s.
    acc_m_s2 : ndarray, shape (N, 3)
        Acceleration in the world frame (no gravity), m/s^2.
    angvel_rad_s : ndarray, shape (N, 3)
        Angular velocity in the world frame, rad/s.
    """

    trajectory: Trajectory
    vel_m_s: npt.NDArray[np.float64]
    acc_m_s2: npt.NDArray[np.float64]
    angvel_rad_s: npt.NDArray[np.float64]

    def __post_init__(self) -> None:
        n = len(self.trajectory)
        for field in ("vel_m_s", "acc_m_s2", "angvel_rad_s"):
            a = np.array(getattr(self, field), dtype=np.float64)
            if a.shape != (n, 3):
                raise IbiscapeError(f"IbiscapeGroundTruth.{field}: expected shape ({n}, 3), "
                                    f"got {a.shape}")
            a.flags.writeable = False
            object.__setattr__(self, field, a)

    def __len__(self) -> int:
        return len(self.trajectory)

    def to_frame(self) -> pd.DataFrame:
        """Trajectory columns plus ``vx_m_s.. ax_m_s2.. wx_rad_s..``."""
        df = self.trajectory.to_frame()
        for prefix, unit, arr in (("v", "m_s", self.vel_m_s), ("a", "m_s2", self.acc_m_s2),
                                  ("w", "rad_s", self.angvel_rad_s)):
            for k, ax in enumerate("xyz"):
                df[f"{prefix}{ax}_{unit}"] = arr[:, k]
        return df


def _quat_ours_from_file(q_wxyz: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """File quaternion ``(w, x, y, z)`` of ``Rz(yaw) Ry(pitch) Rx(roll)`` -> ours, x y z w."""
    return np.stack((q_wxyz[:, 1], -q_wxyz[:, 2], -q_wxyz[:, 3], q_wxyz[:, 0]), axis=1)


def _quat_file_from_ours(q_xyzw: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Inverse of :func:`_quat_ours_from_file`: ours x y z w -> file ``(w, x, y, z)``."""
    return np.stack((q_xyzw[:, 3], q_xyzw[:, 0], -q_xyzw[:, 1], -q_xyzw[:, 2]), axis=1)


def read_ibiscape_groundtruth(
    path: str | os.PathLike[str], *, name: str | None = None
) -> IbiscapeGroundTruth:
    """Read ``groundtruth_sync.csv`` and convert it to our right-handed frame.

    Parameters
    ----------
    path
        The IBISCape ground-truth file (17 columns, see the module docstring).
    name
        Label of the trajectory; the file name by default.

    Returns
    -------
    IbiscapeGroundTruth
        ``p, v, a`` mirrored (``S = diag(1, -1, 1)``), orientation ``R = S R_c S`` recovered from
        the scripts' quaternion as ``(x, -y, -z, w)``, angular rate ``w = -S w_c``.

    Raises
    ------
    FormatError
        Wrong column count, non-numeric field, non-unit quaternion, decreasing stamps, empty
        or binary file; the message names the file and line.
    """
    data = read_bytes(path)
    tb = parse_table(path, data, nkeep=17, ncols_min=17, ncols_max=17, expected=_EXPECTED)
    del data  # the raw bytes are no longer needed: lower peak memory
    stamps = decimal_to_ns(path, tb, unit_exp=0)
    keep = check_rows(path, stamps, tb.finite, tb.lines, stacklevel=4)
    v = tb.values[keep]
    check_positions(path, v[:, 1:4], tb.lines[keep])
    quat = _quat_ours_from_file(check_quaternions(path, v[:, 10:14], tb.lines[keep]))
    traj = Trajectory(stamps[keep], v[:, 1:4] * _S, quat,
                      Path(path).name if name is None else name)
    return IbiscapeGroundTruth(traj, v[:, 4:7] * _S, v[:, 7:10] * _S, -_S * v[:, 14:17])


def write_ibiscape_groundtruth(path: str | os.PathLike[str], gt: IbiscapeGroundTruth) -> None:
    """Write ground truth given in OUR frame as an IBISCape ``groundtruth_sync.csv`` in CARLA's
    left-handed frame, laid out like the acquisition scripts (header from ``csv.writer`` ending in
    ``\\r\\n``, comma separated rows ending in `` \\n``, stamps as ``%d.000000`` ns).  Atomic."""
    tr = gt.trajectory
    values = np.concatenate(
        (tr.pos_m * _S, gt.vel_m_s * _S, gt.acc_m_s2 * _S, _quat_file_from_ours(tr.quat_xyzw),
         -_S * gt.angvel_rad_s), axis=1)
    with atomic_write(path, "wb") as f:
        f.write((IBISCAPE_HEADER + "\r\n").encode())
        write_table(f, tr.stamps_ns, values, stamp="ns_f", sep=",", row_end=" \n")


def read_ibiscape(path: str | os.PathLike[str], *, name: str | None = None) -> Trajectory:
    """The poses of :func:`read_ibiscape_groundtruth` (our right-handed frame)."""
    return read_ibiscape_groundtruth(path, name=name).trajectory


def _finite_difference_groundtruth(traj: Trajectory) -> IbiscapeGroundTruth:
    """Velocity, acceleration (``np.gradient``, second order inside) and angular rate
    (``rotvec(q_{i+1} q_i^-1) / dt``, forward, last row repeated) estimated from the poses."""
    n = len(traj)
    if n < 2:
        z = np.zeros((n, 3))
        return IbiscapeGroundTruth(traj, z, z, z)
    t_s = (traj.stamps_ns - traj.stamps_ns[0]) / 1e9
    vel = np.gradient(traj.pos_m, t_s, axis=0)
    acc = np.gradient(vel, t_s, axis=0)
    q = traj.quat_xyzw
    dq = quat_multiply(q[1:], quat_conjugate(q[:-1]))
    w = rotvec_from_quat(dq) / np.diff(t_s)[:, None]
    return IbiscapeGroundTruth(traj, vel, acc, np.concatenate((w, w[-1:]), axis=0))


def write_ibiscape(path: str | os.PathLike[str], traj: Trajectory) -> None:
    """Write poses as an IBISCape ground-truth file (CARLA frame).

    A :class:`Trajectory` has no velocities: the velocity, acceleration and angular-rate columns
    are estimated by finite differences of the poses (use :func:`write_ibiscape_groundtruth` to
    write known values).
    """
    write_ibiscape_groundtruth(path, _finite_difference_groundtruth(traj))
