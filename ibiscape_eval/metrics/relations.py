"""evo's pose relations and projection to a plane.

Every relation of evo's APE/RPE is a function of the error pose ``E``'s translation norm
``||t||`` and rotation angle ``theta`` (``||R - I||_F = 2 sqrt(2) |sin(theta / 2)|`` and
``||E - I||_F = sqrt(||R - I||_F^2 + ||t||^2``), except RPE's ``point-distance``, which compares
the lengths of the two displacements ``| ||Q_j - Q_i|| - ||P_j - P_i|| |``.  So the metrics keep
the two vectors they always compute and derive the chosen relation from them.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import IbiscapeError, Trajectory

from ._fast import trusted

__all__ = [
    "PLANES",
    "POSE_RELATIONS",
    "RELATION_UNITS",
    "check_plane",
    "check_relation",
    "project_to_plane",
    "relation_errors",
]

POSE_RELATIONS = ("trans", "rot-angle", "rot-part", "full", "point-distance")
"""``trans``: ``||t(E)||`` [m]; ``rot-angle``: angle of ``R(E)`` [deg]; ``rot-part``:
``||R(E) - I||_F``; ``full``: ``||E - I||_F`` (metres and radians mixed, as evo);
``point-distance``: difference of the distances (ATE: equals ``trans``)."""

RELATION_UNITS = {"trans": "m", "rot-angle": "deg", "rot-part": "", "full": "",
                  "point-distance": "m"}
PLANES = ("xy", "xz", "yz")
_NULL_AXIS = {"xy": 2, "xz": 1, "yz": 0}


def check_relation(relation: str) -> str:
    """``relation`` if it is one of :data:`POSE_RELATIONS`, else a one-line error."""
    if relation not in POSE_RELATIONS:
        raise IbiscapeError(
            f"unknown pose relation {relation!r}; choose one of {', '.join(POSE_RELATIONS)}"
        )
    return relation


def check_plane(plane: str | None) -> str | None:
    """``plane`` (lower case) if it is one of :data:`PLANES` or None, else a one-line error."""
    if plane is None:
        return None
    p = plane.lower()
    if p not in PLANES:
        raise IbiscapeError(f"unknown plane {plane!r}; choose one of {', '.join(PLANES)}")
    return p


def project_to_plane(traj: Trajectory, plane: str) -> Trajectory:
    """``traj`` flattened onto ``plane`` like evo's ``--project_to_plane``.

    The coordinate normal to the plane is set to 0 and each orientation is replaced by the
    rotation about the plane's normal by the matching angle of the static x-y-z Euler angles
    (roll for ``yz``, pitch for ``xz``, yaw for ``xy``).
    """
    from scipy.spatial.transform import Rotation

    p = check_plane(plane)
    assert p is not None
    k = _NULL_AXIS[p]
    pos = np.array(traj.pos_m, dtype=np.float64)
    pos[:, k] = 0.0
    if len(traj) == 0:
        return trusted(traj.stamps_ns, pos, traj.quat_xyzw, traj.name)
    angle = Rotation.from_quat(traj.quat_xyzw).as_euler("xyz")[:, k]
    rotvec = np.zeros((len(traj), 3))
    rotvec[:, k] = angle
    quat = Rotation.from_rotvec(rotvec).as_quat()
    return trusted(traj.stamps_ns, pos, quat, traj.name)


def relation_errors(
    relation: str,
    trans_m: npt.ArrayLike,
    angle_deg: npt.ArrayLike,
    *,
    point_distance_m: npt.ArrayLike | None = None,
) -> npt.NDArray[np.float64]:
    """Per-pose (or per-pair) errors of ``relation`` from the error poses' translation norms
    [m] and rotation angles [deg]; ``point_distance_m`` is RPE's displacement-length difference
    (ATE's point distance is the translation norm)."""
    check_relation(relation)
    t = np.asarray(trans_m, dtype=np.float64)
    if relation == "trans":
        return t
    a = np.asarray(angle_deg, dtype=np.float64)
    if relation == "rot-angle":
        return a
    if relation == "point-distance":
        return t if point_distance_m is None else np.asarray(point_distance_m, dtype=np.float64)
    rot_part = 2.0 * np.sqrt(2.0) * np.abs(np.sin(np.radians(a) / 2.0))
    if relation == "rot-part":
        return rot_part
    return np.sqrt(rot_part * rot_part + t * t)
