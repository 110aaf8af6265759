"""Calibration report: estimates with standard deviations, and errors against ground truth.

The ground-truth tables follow the IBISCape paper's ``table:camerasintrinsics`` (focal length,
principal point, distortion per camera and model) and ``table:baselines`` (relative pose of
neighbouring cameras), with every estimate printed beside its truth and its error.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import IbiscapeError

from .calibrate import CalibrationResult

__all__ = ["TruthComparison", "compare_with_truth", "format_report", "truth_from_sequence"]

FloatArray = npt.NDArray[np.float64]


def truth_from_sequence(doc: Mapping[str, Any]) -> dict[str, tuple[CameraModel, FloatArray]]:
    """True cameras of a ``sequence.yaml`` mapping: name -> (model, ``T_body_cam``)."""
    cams = doc.get("cameras")
    if not isinstance(cams, dict):
        return {}
    out = {}
    for name, entry in cams.items():
        if not isinstance(entry, dict):
            continue
        try:
            cam = CameraModel.from_kalibr(entry)
            T = np.array(entry.get("T_body_cam", np.eye(4)), np.float64).reshape(4, 4)
        except (IbiscapeError, ValueError, TypeError):
            continue
        out[str(name)] = (cam, T)
    return out


@dataclass(frozen=True)
class TruthComparison:
    """Estimates beside their truth.

    Attributes
    ----------
    cameras : list of dict
        Per camera: ``name``, ``estimate``/``truth``/``error`` of ``fx, fy, cx, cy`` [px] and
        ``distortion_coeffs``.
    chain : list of dict
        Per neighbouring pair: baseline estimate/truth/error [mm], rotation error [deg],
        translation error vector [mm].
    """

    cameras: list[dict[str, Any]]
    chain: list[dict[str, Any]]

    @property
    def max_focal_error_px(self) -> float:
        return max((max(abs(c["error"]["fx"]), abs(c["error"]["fy"])) for c in self.cameras), default=0.0)

    @property
    def max_principal_point_error_px(self) -> float:
        return max((max(abs(c["error"]["cx"]), abs(c["error"]["cy"])) for c in self.cameras), default=0.0)

    @property
    def max_baseline_error_mm(self) -> float:
        return max((abs(c["baseline_error_mm"]) for c in self.chain), default=0.0)

    def to_dict(self) -> dict[str, Any]:
        return {"cameras": self.cameras, "chain": self.chain,
                "max_focal_error_px": self.max_focal_error_px,
                "max_principal_point_error_px": self.max_principal_point_error_px,
                "max_baseline_error_mm": self.max_baseline_error_mm}


def compare_with_truth(result: CalibrationResult,
                       truth: Mapping[str, tuple[CameraModel, FloatArray]]) -> TruthComparison | None:
    """Errors of every estimate against the true cameras (matched by name); None if none match."""
    rows = []
    for c in result.cameras:
        if c.name not in truth:
            continue
        t = truth[c.name][0]
        e = c.camera
        if (t.width_px, t.height_px) != (e.width_px, e.height_px):
            t = t.scaled(e.width_px, e.height_px)
        est = dict(zip(("fx", "fy", "cx", "cy"), e.intrinsics, strict=True))
        tru = dict(zip(("fx", "fy", "cx", "cy"), t.intrinsics, strict=True))
        t_coeffs = list(t.coeffs) if t.distortion == e.distortion or t.distortion != "none" else [0.0] * 4
        rows.append({
            "name": c.name, "model": result.model,
            "estimate": {**est, "distortion_coeffs": list(e.coeffs)},
            "std": {"fx": c.std["intrinsics"][0], "fy": c.std["intrinsics"][1],
                    "cx": c.std["intrinsics"][2], "cy": c.std["intrinsics"][3]},
            "truth": {**tru, "distortion_coeffs": t_coeffs, "distortion_model": t.distortion},
            "error": {k: est[k] - tru[k] for k in est}
            | {"distortion_coeffs": [a - b for a, b in zip(e.coeffs, t_coeffs, strict=True)]},
        })
    chain = []
    for k, T in enumerate(result.T_cn_cnm1):
        a, b = result.cameras[k].name, result.cameras[k + 1].name
        if a not in truth or b not in truth:
            continue
        T_true = np.linalg.inv(truth[b][1]) @ truth[a][1]
        dR = T[:3, :3].T @ T_true[:3, :3]
        ang = float(np.degrees(np.arccos(np.clip((np.trace(dR) - 1) / 2, -1, 1))))
        bt, be = float(np.linalg.norm(T_true[:3, 3])), float(np.linalg.norm(T[:3, 3]))
        chain.append({"from": a, "to": b, "baseline_estimate_m": be, "baseline_truth_m": bt,
                      "baseline_error_mm": 1e3 * (be - bt),
                      "baseline_std_mm": 1e3 * result.baselines_std_m[k],
                      "rotation_error_deg": ang,
                      "translation_error_mm": [1e3 * v for v in (T[:3, 3] - T_true[:3, 3])],
                      "t_estimate_m": T[:3, 3].tolist(), "t_truth_m": T_true[:3, 3].tolist()})
    if not rows and not chain:
        return None
    return TruthComparison(rows, chain)


def _g(v: float) -> str:
    return f"{v:.4g}" if abs(v) < 1e-2 and v != 0 else f"{v:.4f}"


def format_report(result: CalibrationResult, truth: TruthComparison | None = None) -> list[str]:
    """Human-readable lines: per camera intrinsics +- std, Kalibr's residual line, the chain, and
    the ground-truth tables when given."""
    lines = [f"model        {result.model}    target {result.target!r}",
             f"views        {result.n_views} used"
             + (f" of {result.extra['views_detected']} searched" if "views_detected" in result.extra else "")
             + (f"; {result.renumbered_views} renumbered for consistent stereo corners"
                if result.renumbered_views else "")]
    for c in result.cameras:
        cam, sd = c.camera, c.std
        lines.append(f"{c.name}")
        lines.append("  intrinsics   " + "  ".join(
            f"{n} {v:.3f} +- {s:.3f}" for n, v, s in zip(("fx", "fy", "cx", "cy"), cam.intrinsics,
                                                           sd["intrinsics"], strict=True)))
        lines.append(f"  distortion   {cam.distortion} " + "  ".join(
            f"{_g(v)} +- {_g(s)}" for v, s in zip(cam.coeffs, sd["distortion_coeffs"], strict=True)))
        r = c.residuals
        lines.append(f"  reprojection {r.kalibr()} px   rms {r.rms_px:.4f} px   "
                     f"({r.n_views} views, {r.n_corners} corners, {c.n_rejected} rejected)")
    for k, T in enumerate(result.T_cn_cnm1):
        a, b = result.cameras[k].name, result.cameras[k + 1].name
        t = T[:3, 3]
        lines.append(f"T_{b}_{a}   t = [{t[0]:.5f}, {t[1]:.5f}, {t[2]:.5f}] m   baseline "
                     f"{1e3 * result.baselines_m[k]:.2f} +- {1e3 * result.baselines_std_m[k]:.2f} mm")
    lines.append(f"rms          {result.rms_px:.4f} px over all cameras")
    unc = result.extra.get("uncertainty")
    if unc:
        lines.append("std          the larger of each camera's own residual variance and a per-view "
                     "(cluster-robust) estimate"
                     + (f", x{unc['inflation']:g}" if unc.get("inflation", 1.0) != 1.0 else ""))
    if truth is not None:
        lines.append("")
        lines.append("against ground truth (table:camerasintrinsics)")
        lines.append(f"  {'camera':<16}{'':>9}{'fx':>10}{'fy':>10}{'cx':>10}{'cy':>10}   distortion")
        for row in truth.cameras:
            label = f"{row['name']}-{result.model.split('-')[1]}"
            for what in ("estimate", "truth", "error"):
                d = row[what]
                lines.append(f"  {label if what == 'estimate' else '':<16}{what:>9}"
                             + "".join(f"{d[k]:>10.3f}" for k in ("fx", "fy", "cx", "cy"))
                             + "   [" + ", ".join(_g(v) for v in d["distortion_coeffs"]) + "]")
        if truth.chain:
            lines.append("against ground truth (table:baselines)")
            for ch in truth.chain:
                lines.append(
                    f"  {ch['from']} -> {ch['to']}: baseline {1e3 * ch['baseline_estimate_m']:.2f} mm "
                    f"(truth {1e3 * ch['baseline_truth_m']:.2f}, error {ch['baseline_error_mm']:+.2f} mm), "
                    f"rotation error {ch['rotation_error_deg']:.4f} deg, t error ["
                    + ", ".join(f"{v:+.2f}" for v in ch["translation_error_mm"]) + "] mm")
    return lines
