"""IMU noise model read off an Allan deviation curve (IEEE Std 952-1997, Annex C).

Per axis:

- white noise density ``N`` (angle / velocity random walk): the line of slope -1/2,
  ``sigma(tau) = N / sqrt(tau)``, read at tau = 1 s;
- rate random walk ``K`` (bias random walk): the line of slope +1/2,
  ``sigma(tau) = K sqrt(tau / 3)``, read at tau = 3 s;
- bias instability ``B``: the curve's minimum divided by ``sqrt(2 ln 2 / pi) = 0.664``.

The ranges of the two lines are found from the local log-log slope of the curve (or given).
Inside each range the other noise's contribution (``N^2 / tau`` or ``K^2 tau / 3``) is removed
before the fixed-slope fit, alternating twice, so that a range near the cross-over is not biased.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ibiscape_eval.core.errors import IbiscapeError, Remedy
from ibiscape_eval.core.numbers import finite_or_none

from .allan import AllanResult

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

__all__ = ["BIAS_INSTABILITY_FACTOR", "BIAS_INSTABILITY_UNC_INFLATION", "MIN_EDF_BIAS",
           "AxisNoise", "NoiseModel", "fit_noise_model"]

#: ``sqrt(2 ln 2 / pi)``: the flicker-noise floor of the Allan deviation is ``0.664 B``.
BIAS_INSTABILITY_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)
#: The chi-squared half-width at the minimum understates B's error on a flicker floor (the
#: minimum is picked among correlated, noisy points; a floor still mixed with white noise reads
#: high): ``benchmarks/bench_allan.py --coverage`` (white + flicker + random walk, 16 seeds x 6
#: axes) measured 1 sigma covering 62 %, 2 sigma 90 % (factor 1.20 needed), while on the bowl of a
#: white + random-walk record it is honest (70 % / 94 %, tests/imu/test_allan_coverage.py).  The
#: reported sigma is the half-width times this compromise, which keeps both within 60-75 % and
#: 90-98 %: flicker 64 % / 93 %, white + random walk 72 % / 95 %.
BIAS_INSTABILITY_UNC_INFLATION = 1.05
#: The minimum at the last trustworthy tau is a floor when the local slope there is above
#: ``-FLOOR_SLOPE`` (else the curve is still falling).
FLOOR_SLOPE = 0.2


@dataclass(frozen=True)
class AxisNoise:
    """Noise parameters of one axis.  Units follow the input samples ``u`` (rad/s or m/s^2).

    Attributes
    ----------
    name : str
    noise_density, noise_density_unc : float
        ``N`` and its one-sigma uncertainty, u/sqrt(Hz) (rad/s/sqrt(Hz), m/s^2/sqrt(Hz)).
        NaN when no slope -1/2 region exists.
    random_walk, random_walk_unc : float
        ``K`` and its uncertainty, u*sqrt(Hz) (rad/s^2/sqrt(Hz), m/s^3/sqrt(Hz)).  NaN when the
        record is too short to show the random walk (see ``notes``).
    bias_instability, bias_instability_unc : float
        ``B`` and its uncertainty, u.  NaN when the curve has no minimum.
    bias_tau_s : float
        Tau of the curve's minimum, s.
    white_range_s, walk_range_s : tuple of float or None
        Tau ranges used for the -1/2 and +1/2 fits, s.
    discrete_sigma : float
        Per-sample white-noise sigma at the record's rate, ``N sqrt(rate)``, u.
    discrete_walk_sigma : float
        Per-sample bias step, ``K / sqrt(rate)``, u.
    notes : tuple of str
        Why a parameter is NaN, or what to be careful about.
    """

    name: str
    noise_density: float
    noise_density_unc: float
    random_walk: float
    random_walk_unc: float
    bias_instability: float
    bias_instability_unc: float
    bias_tau_s: float
    white_range_s: tuple[float, float] | None
    walk_range_s: tuple[float, float] | None
    discrete_sigma: float
    discrete_walk_sigma: float
    notes: tuple[str, ...]


@dataclass(frozen=True)
class NoiseModel:
    """Noise parameters of every axis of an :class:`~ibiscape_eval.imu.AllanResult`."""

    axes: tuple[AxisNoise, ...]
    rate_hz: float
    duration_s: float

    def __getitem__(self, name: str) -> AxisNoise:
        for a in self.axes:
            if a.name == name:
                return a
        raise KeyError(name)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.axes)

    def _split(self, gyro: Sequence[str] | None, accel: Sequence[str] | None
               ) -> tuple[Sequence[str], Sequence[str]]:
        if gyro is None or accel is None:
            if len(self.axes) != 6:
                raise IbiscapeError(
                    f"name the gyro and accelerometer axes: the model has {len(self.axes)} axes, "
                    "not the usual six (three gyro then three accelerometer)")
            gyro = self.names[:3] if gyro is None else gyro
            accel = self.names[3:] if accel is None else accel
        return gyro, accel

    def kalibr(self, gyro: Sequence[str] | None = None,
               accel: Sequence[str] | None = None) -> dict[str, float]:
        """Kalibr ``imu.yaml`` densities: the largest value over the given gyro and accelerometer
        axes (continuous time); NaN where an axis lacks the parameter (e.g. a record too short
        to show the random walk), so that a caller can refuse to write it.  Without arguments
        the usual six axes are taken as three gyro then three accelerometer axes."""
        gyro, accel = self._split(gyro, accel)

        def largest(names: Sequence[str], attr: str) -> float:
            vals = [getattr(self[n], attr) for n in names]
            return math.nan if any(not math.isfinite(v) for v in vals) else float(max(vals))

        return {
            "accelerometer_noise_density": largest(accel, "noise_density"),
            "accelerometer_random_walk": largest(accel, "random_walk"),
            "gyroscope_noise_density": largest(gyro, "noise_density"),
            "gyroscope_random_walk": largest(gyro, "random_walk"),
        }

    def kalibr_values(
        self,
        *,
        random_walk_fallback: tuple[float, float] | None = None,
        inflate: float = 1.0,
        gyro: Sequence[str] | None = None,
        accel: Sequence[str] | None = None,
    ) -> tuple[dict[str, float], list[str]]:
        """The four values of a Kalibr ``imu.yaml`` and the comments that explain them.

        A random walk the record cannot show (NaN in :meth:`kalibr`) is taken from
        ``random_walk_fallback = (gyro, accel)`` (rad/s^2/sqrt(Hz), m/s^3/sqrt(Hz)) and said so in
        a comment; without a fallback, or when a noise density is missing, an
        :class:`IbiscapeError` names what is missing and the option that helps.  Every value is
        multiplied by ``inflate`` (Kalibr users often inflate the noise for a real system),
        recorded in a comment.
        """
        if not (math.isfinite(inflate) and inflate > 0):
            raise IbiscapeError(f"inflate must be a positive number, got {inflate!r}")
        vals = self.kalibr(gyro, accel)
        notes: list[str] = []
        for key in ("gyroscope_noise_density", "accelerometer_noise_density"):
            if not math.isfinite(vals[key]):
                raise IbiscapeError(f"{key} could not be determined (no slope -1/2 region); "
                                    "give {0}", hint=(Remedy("white_range"),))
        missing = [k for k in ("gyroscope_random_walk", "accelerometer_random_walk")
                   if not math.isfinite(vals[k])]
        if missing:
            if random_walk_fallback is None:
                raise IbiscapeError(
                    f"{', '.join(missing)} could not be determined (the record of "
                    f"{self.duration_s:.4g} s is too short to show the random walk): record "
                    "longer, give {0}, or set it with {1}",
                    hint=(Remedy("walk_range"), Remedy("random_walk_fallback")))
            fb = dict(zip(("gyroscope_random_walk", "accelerometer_random_walk"),
                          random_walk_fallback, strict=True))
            for k in missing:
                if not (math.isfinite(fb[k]) and fb[k] > 0):
                    raise IbiscapeError(f"random-walk fallback for {k} must be positive, "
                                        f"got {fb[k]!r}")
                vals[k] = float(fb[k])
                notes.append(f"{k}: not determined by this {self.duration_s:.4g} s record; "
                             f"fallback {fb[k]:.6g} given by the user")
        if inflate != 1.0:
            vals = {k: v * inflate for k, v in vals.items()}
            notes.append(f"every value inflated by a factor {inflate:g} (--inflate)")
        return vals, notes

    def kalibr_discrete(self, gyro: Sequence[str] | None = None,
                        accel: Sequence[str] | None = None) -> dict[str, float]:
        """Per-sample (discrete-time) sigmas of :meth:`kalibr` at the record's rate ``r``:
        noise ``N sqrt(r)`` and bias step ``K / sqrt(r)`` (what a CARLA-style simulator or a
        discrete filter takes); NaN where :meth:`kalibr` has NaN."""
        k = self.kalibr(gyro, accel)
        root = math.sqrt(self.rate_hz)
        return {
            "gyroscope_noise_sigma": k["gyroscope_noise_density"] * root,
            "gyroscope_bias_step_sigma": k["gyroscope_random_walk"] / root,
            "accelerometer_noise_sigma": k["accelerometer_noise_density"] * root,
            "accelerometer_bias_step_sigma": k["accelerometer_random_walk"] / root,
        }

    def to_dict(self) -> dict[str, Any]:
        """Strict-JSON document: ``rate_hz, duration_s`` and one entry per axis with every field
        (NaN as null, ranges as lists, notes as a list)."""

        def val(v: Any) -> Any:
            if isinstance(v, float):
                return finite_or_none(v)
            if isinstance(v, tuple):
                return [val(x) for x in v]
            return v

        return {
            "rate_hz": float(self.rate_hz),
            "duration_s": float(self.duration_s),
            "axes": {a.name: {k: val(getattr(a, k)) for k in AxisNoise.__dataclass_fields__
                              if k != "name"} for a in self.axes},
        }

    def __repr__(self) -> str:
        lines = [f"NoiseModel(rate_hz={self.rate_hz:.6g}, duration_s={self.duration_s:.6g},"]
        for a in self.axes:
            lines.append(f"  {a.name}: N={a.noise_density:.4g} +- {a.noise_density_unc:.2g}, "
                         f"K={a.random_walk:.4g} +- {a.random_walk_unc:.2g}, "
                         f"B={a.bias_instability:.4g}")
        return "\n".join(lines) + ")"

    def _repr_html_(self) -> str:
        import html

        head = "".join(f"<th>{h}</th>" for h in ("axis", "N", "N unc", "K", "K unc", "B",
                                                "B unc", "notes"))
        rows = [f"<caption>IMU noise, {self.rate_hz:.6g} Hz, {self.duration_s:.6g} s</caption>",
                f"<tr>{head}</tr>"]
        for a in self.axes:
            cells = [a.name] + [f"{v:.4g}" for v in (
                a.noise_density, a.noise_density_unc, a.random_walk, a.random_walk_unc,
                a.bias_instability, a.bias_instability_unc)] + ["; ".join(a.notes)]
            rows.append("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in cells) + "</tr>")
        return "<table>" + "".join(rows) + "</table>"

    def to_frame(self) -> pd.DataFrame:
        """One row per axis with every numeric field and the notes joined by '; '."""
        import pandas as pd

        rows = []
        for a in self.axes:
            row = {k: getattr(a, k) for k in AxisNoise.__dataclass_fields__ if k != "notes"}
            row["notes"] = "; ".join(a.notes)
            rows.append(row)
        return pd.DataFrame(rows).set_index("name")


_WALK_EXTEND_SLOPE = 0.2
#: The bias-instability minimum is sought among taus with at least this many degrees of freedom:
#: the minimum of a flat, noisy floor picks its lowest (least certain) points otherwise.
MIN_EDF_BIAS = 30.0


def _local_slopes(logt: np.ndarray, logs: np.ndarray, half_width_dec: float) -> np.ndarray:
    """Least-squares slope of log sigma vs log tau over a window of +-half_width decades."""
    out = np.full(logt.size, np.nan)
    for i in range(logt.size):  # over taus (tens), not samples
        sel = np.abs(logt - logt[i]) <= half_width_dec + 1e-12
        if sel.sum() < 3:
            sel = np.zeros(logt.size, dtype=bool)
            sel[max(0, i - 1) : i + 2] = True
        if sel.sum() >= 2:
            x = logt[sel] - logt[sel].mean()
            out[i] = float(np.dot(x, logs[sel] - logs[sel].mean()) / np.dot(x, x))
    return out


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Contiguous runs of True as (start, stop) index pairs."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def _fixed_slope_fit(var: np.ndarray, taus: np.ndarray, edf: np.ndarray, slope: float,
                     tau_read: float, *, edf_of: str = "max") -> tuple[float, float]:
    """Fit sigma = c * tau^slope (log space, weights edf) and return (sigma(tau_read), rel unc).

    The relative uncertainty combines the scatter about the line with the chi-squared spread of
    one point (neighbouring overlapping taus are strongly correlated, so their count does not
    shrink it): the best-determined point (``edf_of="max"``, the white-noise fit) or a typical
    one (``"mean"``, the random-walk fit, whose long-tau points are far less certain; measured
    coverage in tests/imu/test_allan_coverage.py)."""
    ok = var > 0
    if not ok.any():
        return math.nan, math.nan
    lt = np.log(taus[ok])
    ls = 0.5 * np.log(var[ok])
    w = edf[ok]
    offs = ls - slope * lt
    c = float(np.sum(w * offs) / np.sum(w))
    resid_var = float(np.sum(w * (offs - c) ** 2) / np.sum(w)) if offs.size > 1 else 0.0
    if edf_of == "max":
        # white noise: the best point's chi-squared spread, plus the scatter about the line as
        # the uncertainty of a mean over the fitted points (the scatter of one point overstated
        # N's error ~2x: z-scores of sd 0.54 over 240 simulated axes)
        rel = math.sqrt(1.0 / (2.0 * float(np.max(w))) + resid_var / max(offs.size, 1))
    else:
        rel = math.sqrt(1.0 / (2.0 * float(np.mean(w))) + resid_var)
    return math.exp(c + slope * math.log(tau_read)), rel


def _in_range(taus: np.ndarray, rng: tuple[float, float], what: str) -> np.ndarray:
    lo, hi = float(min(rng)), float(max(rng))
    sel = (taus >= lo * (1 - 1e-9)) & (taus <= hi * (1 + 1e-9))
    if not sel.any():
        raise IbiscapeError(
            f"the {what} range [{lo:g}, {hi:g}] s contains no tau of the curve "
            f"(taus run from {taus[0]:g} to {taus[-1]:g} s)"
        )
    return sel


@dataclass(frozen=True, eq=False)
class _Curve:
    """The taus of an Allan curve, their equivalent degrees of freedom and which are usable."""

    taus: np.ndarray
    edf: np.ndarray
    usable: np.ndarray


def _white_selection(c: _Curve, slopes: np.ndarray, slope_tolerance: float,
                     white_range_s: tuple[float, float] | None) -> np.ndarray:
    """Taus of the white-noise fit: the given range, else the first run of slope -1/2."""
    if white_range_s is not None:
        return _in_range(c.taus, white_range_s, "white-noise")
    cand = c.usable & (np.abs(slopes + 0.5) <= slope_tolerance)
    runs = _runs(cand)
    w_sel = np.zeros(c.taus.size, dtype=bool)
    if runs:
        w_sel[runs[0][0] : runs[0][1]] = True
    return w_sel


def _walk_selection(c: _Curve, slopes: np.ndarray, slope_tolerance: float,
                    walk_range_s: tuple[float, float] | None, w_sel: np.ndarray) -> np.ndarray:
    """Taus of the random-walk fit: the given range, else the most informative run of slope
    +1/2, widened while the curve keeps rising, and none if it starts before the white range
    ends."""
    if walk_range_s is not None:
        return _in_range(c.taus, walk_range_s, "random-walk")
    taus, edf, usable = c.taus, c.edf, c.usable
    cand = usable & (np.abs(slopes - 0.5) <= slope_tolerance)
    runs = [r for r in _runs(cand) if r[1] - r[0] >= 2]
    k_sel = np.zeros(taus.size, dtype=bool)
    if runs:  # the run with the most information (sum of edf), usually the earliest
        best = max(runs, key=lambda r: float(edf[r[0] : r[1]].sum()))
        k_sel[best[0] : best[1]] = True
        # widened to the end of the usable curve while it keeps rising: a 0.1-decade
        # range gave uncertainties that covered the truth far less often than stated
        for i in range(best[1], taus.size):  # over taus (tens), not samples
            if not (usable[i] and slopes[i] > _WALK_EXTEND_SLOPE):
                break
            k_sel[i] = True
    if w_sel.any() and k_sel.any() and taus[k_sel][0] <= taus[w_sel][-1]:
        k_sel[:] = False
    return k_sel


def _fit_white_and_walk(var: np.ndarray, c: _Curve, w_sel: np.ndarray,
                        k_sel: np.ndarray) -> tuple[float, float, float, float]:
    """``(N, N's relative sigma, K, K's relative sigma)``, alternating: N with the K part
    removed, K with the N part removed (NaN where a range is empty)."""
    taus, edf = c.taus, c.edf
    N = K = math.nan
    n_rel = k_rel = math.nan
    for _ in range(3):
        if w_sel.any():
            v = var[w_sel] - (K**2 * taus[w_sel] / 3.0 if math.isfinite(K) else 0.0)
            N, n_rel = _fixed_slope_fit(v, taus[w_sel], edf[w_sel], -0.5, 1.0)
        if k_sel.any():
            v = var[k_sel] - (N**2 / taus[k_sel] if math.isfinite(N) else 0.0)
            K, k_rel = _fixed_slope_fit(v, taus[k_sel], edf[k_sel], 0.5, 3.0,
                                        edf_of="mean")
    return N, n_rel, K, k_rel


def _range_notes(c: _Curve, slopes: np.ndarray, w_sel: np.ndarray,
                 k_sel: np.ndarray) -> list[str]:
    """Why N or K is missing (no slope -1/2 or +1/2 region)."""
    notes: list[str] = []
    if not w_sel.any():
        notes.append(
            "no slope -1/2 region at short taus: the white noise is hidden (filtered or "
            "quantised data?); give --white-range to force a fit"
        )
    if not k_sel.any():
        last = np.flatnonzero(c.usable)
        t_last = float(c.taus[last[-1]]) if last.size else float(c.taus[-1])
        s_last = float(slopes[last[-1]]) if last.size else math.nan
        notes.append(
            f"record too short to see the rate random walk: no slope +1/2 region up to "
            f"tau = {t_last:.4g} s (local slope there {s_last:+.2f}); record for longer or "
            "give --walk-range"
        )
    return notes


def _bias_instability(result: AllanResult, j: int, c: _Curve, slopes: np.ndarray,
                      notes: list[str]) -> tuple[float, float, float]:
    """``(B, its sigma, its tau)``: the minimum over the trustworthy part of the curve (NaN
    with a note when the curve is still falling at its end)."""
    adev, taus = result.adev[:, j], c.taus
    many = np.flatnonzero(c.edf >= MIN_EDF_BIAS)
    idx = many if many.size >= 3 else np.flatnonzero(c.usable)
    if not idx.size:
        return math.nan, math.nan, math.nan
    # the minimum of the curve smoothed over three neighbouring taus (0.2 decade): the
    # lowest single point of a flat, noisy floor is a downward fluctuation whose
    # chi-squared bounds understate B's error (1 sigma covered 25 % of such axes)
    sm = adev[idx]
    if idx.size >= 3:
        sm = np.convolve(np.log(np.maximum(sm, 1e-300)), np.ones(3) / 3.0, mode="same")
        sm[0], sm[-1] = np.log(max(adev[idx[0]], 1e-300)), np.log(max(adev[idx[-1]], 1e-300))
        sm = np.exp(sm)
    k_min = int(np.argmin(sm))
    i_min = int(idx[k_min])
    if i_min == idx[-1] and not (slopes[i_min] > -FLOOR_SLOPE):
        notes.append(
            f"curve still falling at tau = {taus[i_min]:.4g} s: no bias-instability floor "
            "in this record"
        )
        return math.nan, math.nan, math.nan
    B = float(sm[k_min] / BIAS_INSTABILITY_FACTOR)
    rel_half = (result.adev_hi[i_min, j] - result.adev_lo[i_min, j]) / 2.0 / adev[i_min]
    return B, float(B * rel_half * BIAS_INSTABILITY_UNC_INFLATION), float(taus[i_min])


def _fit_axis(result: AllanResult, j: int, name: str, c: _Curve, *,
              white_range_s: tuple[float, float] | None,
              walk_range_s: tuple[float, float] | None, slope_tolerance: float) -> AxisNoise:
    """N, K and B of axis ``j`` (see :func:`fit_noise_model`)."""
    taus, rate = c.taus, result.rate_hz
    adev = result.adev[:, j]
    logt = np.log10(taus)
    with np.errstate(divide="ignore"):
        logs = np.log10(adev)
    slopes = np.full(taus.size, np.nan)
    if c.usable.sum() >= 2:
        slopes[c.usable] = _local_slopes(logt[c.usable], logs[c.usable], 0.25)
    w_sel = _white_selection(c, slopes, slope_tolerance, white_range_s)
    k_sel = _walk_selection(c, slopes, slope_tolerance, walk_range_s, w_sel)
    N, n_rel, K, k_rel = _fit_white_and_walk(adev**2, c, w_sel, k_sel)
    notes = _range_notes(c, slopes, w_sel, k_sel)
    B, B_unc, tau_b = _bias_instability(result, j, c, slopes, notes)
    return AxisNoise(
        name=name, noise_density=N, noise_density_unc=N * n_rel, random_walk=K,
        random_walk_unc=K * k_rel, bias_instability=B, bias_instability_unc=B_unc,
        bias_tau_s=tau_b,
        white_range_s=(float(taus[w_sel][0]), float(taus[w_sel][-1])) if w_sel.any() else None,
        walk_range_s=(float(taus[k_sel][0]), float(taus[k_sel][-1])) if k_sel.any() else None,
        discrete_sigma=N * math.sqrt(rate), discrete_walk_sigma=K / math.sqrt(rate),
        notes=tuple(notes),
    )


def fit_noise_model(
    result: AllanResult,
    *,
    white_range_s: tuple[float, float] | None = None,
    walk_range_s: tuple[float, float] | None = None,
    slope_tolerance: float = 0.12,
    min_edf: float = 4.0,
) -> NoiseModel:
    """Read N, K and B of every axis off an Allan deviation curve.

    Parameters
    ----------
    result : AllanResult
        Output of :func:`~ibiscape_eval.imu.allan_deviation`.
    white_range_s, walk_range_s : (float, float), optional
        Tau ranges (s) of the slope -1/2 (white noise) and +1/2 (random walk) fits, overriding the
        automatic choice.
    slope_tolerance : float
        Automatic ranges: taus whose local slope (least squares over +-0.25 decade) lies within
        this distance of -1/2 (first run from the short end) or +1/2 (last run).
    min_edf : float
        Taus with fewer equivalent degrees of freedom are too noisy for the automatic ranges and
        for the minimum.

    Returns
    -------
    NoiseModel
        Per-axis :class:`AxisNoise`.  A parameter that the curve does not show is NaN with the
        reason in ``notes`` (e.g. a record too short to see the random walk), never a guess.
    """
    taus = np.asarray(result.taus_s, dtype=np.float64)
    edf = np.asarray(result.edf, dtype=np.float64)
    usable = edf >= min_edf
    if usable.sum() < 2:
        usable = edf >= 1.0
    rate = result.rate_hz
    curve = _Curve(taus=taus, edf=edf, usable=usable)
    axes = [
        _fit_axis(result, j, name, curve, white_range_s=white_range_s, walk_range_s=walk_range_s,
                  slope_tolerance=slope_tolerance)
        for j, name in enumerate(result.names)
    ]
    return NoiseModel(axes=tuple(axes), rate_hz=float(rate), duration_s=result.duration_s)
