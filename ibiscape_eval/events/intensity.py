"""Log-intensity images from events: a leaky (high-pass) integrator of the event polarities.

Every event says that the log intensity of its pixel changed by ``+C_pos`` or ``-C_neg``
(``../shared/FORMATS.md``, the DVS model), so summing the signed thresholds of a pixel's events
gives ``L(t) - L(t0)``.  Pure integration keeps the unknown first image ``-L(t0)`` forever and
lets threshold mismatch drift; the high-pass filter of Scheerlinck, Barnes and Mahony
("Continuous-time intensity estimation using event cameras", ACCV 2018, eq. 7 without frames)
forgets both with a cut-off ``alpha = 1 / tau``:

    dL_hat/dt = sum_i C_i delta(t - t_i) - alpha L_hat

whose exact solution at a time ``t`` after the state's time ``t_s`` is linear in the events:

    L_hat(t) = exp(-alpha (t - t_s)) L_hat(t_s) + sum_{t_s <= t_i < t} C_i exp(-alpha (t - t_i))

so one window of events is one ``bincount`` (no per-event loop).  On a moving camera the result is
the current log image minus its motion-smeared past: the board's squares are filled, not edges.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.events import Events

__all__ = ["estimate_contrast_ratio", "leaky_integrate"]


def leaky_integrate(state: npt.NDArray[np.float64], t_state_ns: int, events: Events, t_end_ns: int, *,
                    width_px: int, tau_s: float, contrast: tuple[float, float] = (0.3, 0.3)
                    ) -> npt.NDArray[np.float64]:
    """Advance the high-pass log-intensity estimate from ``t_state_ns`` to ``t_end_ns``.

    Parameters
    ----------
    state : ndarray (H * W,) float64
        ``L_hat`` at ``t_state_ns`` (zeros to start), flattened row-major; not modified.
    events
        The events of ``[t_state_ns, t_end_ns)``, sorted by time.
    width_px
        Sensor width (pixel index ``y * width + x``).
    tau_s
        Time constant ``1 / alpha`` [s]: how long the estimate remembers.
    contrast : (C_pos, C_neg)
        Contrast thresholds of positive and negative events (log-intensity units).

    Returns
    -------
    ndarray (H * W,) float64
        ``L_hat`` at ``t_end_ns``.
    """
    if not tau_s > 0:
        raise IbiscapeError(f"tau_s must be > 0, got {tau_s}")
    if int(t_end_ns) < int(t_state_ns):
        raise IbiscapeError(f"integration end {t_end_ns} ns before the state's time {t_state_ns} ns")
    rate = 1e-9 / float(tau_s)
    out = state * np.exp(-rate * (int(t_end_ns) - int(t_state_ns)))
    if len(events):
        c = np.where(events.p, float(contrast[0]), -float(contrast[1]))
        # exponent is <= 0 for events inside the window: no overflow
        wts = c * np.exp(-rate * (int(t_end_ns) - events.t_ns).astype(np.float64))
        w = int(width_px)
        h = out.size // w
        if int(events.x.max()) >= w or int(events.y.max()) >= h:
            raise IbiscapeError(f"events reach pixel ({int(events.x.max())}, {int(events.y.max())}), "
                                f"outside the {w}x{h} sensor; give the right sensor size")
        pix = events.y.astype(np.int64) * w + events.x
        out += np.bincount(pix, weights=wts, minlength=out.size)
    return out


def estimate_contrast_ratio(n_positive: int, n_negative: int) -> float:
    """``C_neg / C_pos`` from event counts, assuming the scene's log intensity neither brightens nor
    darkens on the whole over the recording (``C_pos n_pos = C_neg n_neg``); 1 without events."""
    if n_positive <= 0 or n_negative <= 0:
        return 1.0
    return float(n_positive) / float(n_negative)
