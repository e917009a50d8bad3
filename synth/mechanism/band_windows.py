"""The longest window within a band from every start sample, compiled: what the dwell search
of :mod:`synth.mechanism.output_range` starts from.

Per row of samples (ψ over two turns, each local extreme raised or lowered to its parabola's
vertex: ``upper``, ``lower``), from every start s < m the longest window [s, s + n) with
n ≤ m whose spread — the largest ``upper`` minus the smallest of ``upper[s]`` and
``lower[s + 1 : s + n]`` — is within the band, and that window's two extremes. Feasibility
only shrinks as a window grows and only grows as its start moves on, so one pass per row
with two monotone queues (the window's running maximum and minimum) finds every start's
window in O(T): the window's end never moves back. Extremes are exact (max and min round
nothing), so the windows are the same as any exhaustive search's, bit for bit
(``tests/synth/test_band_windows.py``).

The first sample counts with ``upper`` on both sides: the binary-lifting search this replaces
did so, and the dwell bounds and refinement were checked with it.
"""

from __future__ import annotations

import numba
import numpy as np

from synth.parallel_rows import one_signature, over_rows

__all__ = ["longest_windows"]


@numba.njit(cache=True, nogil=True)
def _windows(upper, lower, band, m, length, w_max, w_min):
    R, T = upper.shape
    qmax = np.empty(T, np.int64)  # indices of upper, values decreasing: the window's maximum first
    qmin = np.empty(T, np.int64)  # indices of lower past the start, values increasing
    for r in range(R):
        b = band[r]
        hmax = tmax = 0  # queue head and tail
        hmin = tmin = 0
        e = 0  # the window is [s, e)
        for s in range(m):
            if e <= s:  # a fresh window: the start sample alone (always kept)
                e = s + 1
                hmax = tmax = 0
                hmin = tmin = 0
                qmax[tmax] = s
                tmax += 1
            else:  # the start moved on: its sample leaves both queues
                while hmax < tmax and qmax[hmax] < s:
                    hmax += 1
                while hmin < tmin and qmin[hmin] <= s:
                    hmin += 1
            while e < T and e - s < m:
                hi = max(upper[r, qmax[hmax]], upper[r, e])  # the queue holds e − 1 at least
                lo = upper[r, s]
                if hmin < tmin:
                    lo = min(lo, lower[r, qmin[hmin]])
                lo = min(lo, lower[r, e])
                if not hi - lo <= b:
                    break
                while tmax > hmax and upper[r, qmax[tmax - 1]] <= upper[r, e]:
                    tmax -= 1
                qmax[tmax] = e
                tmax += 1
                while tmin > hmin and lower[r, qmin[tmin - 1]] >= lower[r, e]:
                    tmin -= 1
                qmin[tmin] = e
                tmin += 1
                e += 1
            length[r, s] = e - s
            w_max[r, s] = upper[r, qmax[hmax]]
            lo = upper[r, s]
            if hmin < tmin:
                lo = min(lo, lower[r, qmin[hmin]])
            w_min[r, s] = lo


def longest_windows(
    upper: np.ndarray, lower: np.ndarray, band: np.ndarray, m: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(length, max, min), each ``(R, m)``: from every start s < ``m`` of each row of ``upper``
    and ``lower`` (``(R, T)`` float64, T ≥ 2m − 1, ``lower`` ≤ ``upper``), the longest window
    of at most ``m`` samples whose spread is within ``band`` (``(R,)``, ≥ 0; see the module
    docstring), and its largest ``upper`` and smallest value."""
    upper = np.ascontiguousarray(upper, dtype=np.float64)
    lower = np.ascontiguousarray(lower, dtype=np.float64)
    band = np.ascontiguousarray(band, dtype=np.float64)
    R = upper.shape[0]
    length = np.empty((R, m), np.int64)
    w_max = np.empty((R, m))
    w_min = np.empty((R, m))
    # band arrives writable or read-only (a broadcast): one compile for both
    one_signature(_windows, (upper, lower, band, int(m), length, w_max, w_min), read_only=(2,))
    over_rows(
        R,
        lambda lo, hi: _windows(
            upper[lo:hi], lower[lo:hi], band[lo:hi], int(m), length[lo:hi], w_max[lo:hi], w_min[lo:hi]
        ),
        5 * R * upper.shape[1],
    )  # ~5 ns a sample
    return length, w_max, w_min
