"""Pose-pair selection for relative errors: by frames, path length, rotation angle or time.

``consecutive`` reproduces evo's non-overlapping pairs: starting at pose 0, the end of a pair is
the first pose at which the quantity accumulated since its start reaches ``delta``, and the next
pair starts there.  That greedy scan carries state from step to step, so it runs in numba.
``all`` takes every start pose ``i`` and the pose ``j > i`` whose accumulated quantity is the
closest to ``delta`` (first one on ties), found by binary search and kept when within
``rel_tol * delta`` (evo's tolerance): O(n log n).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.jit import lazy_njit

IntArray = npt.NDArray[np.intp]
FloatArray = npt.NDArray[np.float64]

@lazy_njit()
def greedy_scan_kernel(steps: FloatArray, delta: float) -> npt.NDArray[np.int64]:  # pragma: no cover
    out = np.empty(steps.shape[0] + 1, dtype=np.int64)
    out[0] = 0
    m = 1
    acc = 0.0
    for k in range(steps.shape[0]):
        acc += steps[k]
        if acc >= delta:
            out[m] = k + 1
            m += 1
            acc = 0.0
    return out[:m]


def _greedy_scan(steps: FloatArray, delta: float) -> npt.NDArray[np.int64]:
    """Indices 0 = i0 < i1 < ... where the sum of ``steps`` since the last index reaches delta.

    The running sum restarts from 0.0 at each chosen index and adds the per-step values in
    order, exactly like evo's filters, so the chosen poses agree bit for bit.
    """
    result: npt.NDArray[np.int64] = greedy_scan_kernel(np.ascontiguousarray(steps, dtype=np.float64),
                                               float(delta))
    return result


def pairs_by_frames(n: int, delta: int, *, all_pairs: bool) -> tuple[IntArray, IntArray]:
    """Pairs ``(i, i + delta)``: every start (``all``) or every ``delta``-th (consecutive)."""
    if all_pairs:
        first = np.arange(max(n - delta, 0), dtype=np.intp)
        return first, first + delta
    ids = np.arange(0, n, delta, dtype=np.intp)
    return ids[:-1], ids[1:]


def pairs_by_steps(
    steps: FloatArray, delta: float, *, all_pairs: bool, rel_tol: float
) -> tuple[IntArray, IntArray]:
    """Pairs by an accumulated non-negative per-step quantity ``steps`` (shape ``(n - 1,)``)."""
    if not all_pairs:
        ids = _greedy_scan(steps, delta).astype(np.intp)
        return ids[:-1], ids[1:]
    n = steps.shape[0] + 1
    if n < 2:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    cum = np.concatenate(([0.0], np.cumsum(steps)))
    first = np.arange(n - 1, dtype=np.intp)
    k = np.searchsorted(cum, cum[first] + delta, side="left")
    # Candidates around the insertion point; the exact distances decide (rounding of the sum).
    cand = np.stack([k - 2, k - 1, k, k + 1], axis=1)
    cand = np.clip(cand, first[:, None] + 1, n - 1)
    # First index of each candidate's plateau (a standing still segment): evo's argmin takes
    # the earliest of equal values.
    plateau = np.searchsorted(cum, cum[cand], side="left")
    cand = np.maximum(plateau, first[:, None] + 1)
    err = np.abs((cum[cand] - cum[first][:, None]) - delta)
    # Smallest error, then smallest index.
    best_err = err.min(axis=1)
    big = np.iinfo(np.intp).max
    second = np.where(err == best_err[:, None], cand, big).min(axis=1)
    keep = best_err <= rel_tol * delta
    return first[keep], second[keep].astype(np.intp)
