"""The RRR fit's closed-form direction ranking compiled (:class:`synth.dyad._RrrTerms`'s
``estimate``): per row and rocker direction, two passes over the path samples instead of a
dozen ``(rows, directions, samples)`` temporaries.

The same operations in the same order as the numpy expressions they replace (no fused
multiply-adds, reductions by max and min, which round nothing), so the fits are the same bit
for bit (``tests/synth/test_dyad.py`` compares them); the transcendental parts (the
direction's cosine and sine, the branch, the final arccos) stay in numpy around it.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["direction_estimates"]


@numba.njit(cache=True, nogil=True)
def _estimates(wx, wy, A, inv_a_rho, half, rho, c, s, branch, target, ratio, u_lo, u_hi, u_est, cos_max, feasible):
    R, J = c.shape
    S = wx.shape[1]
    for r in range(R):
        rho2 = rho[r] * rho[r]
        for j in range(J):
            cj, sj, bj = c[r, j], s[r, j], branch[r, j]
            hi = math.inf
            lo = -math.inf
            smax = -math.inf
            smin = math.inf
            for k in range(S):
                p = wx[r, k] * cj + wy[r, k] * sj
                q = wy[r, k] * cj - wx[r, k] * sj
                centre = -p * inv_a_rho[r, k]
                hi = min(hi, centre + half[r, k])
                lo = max(lo, centre - half[r, k])
                sk = q + bj * math.sqrt(max(rho2 - p * p, 0.0))
                smax = max(smax, sk)
                smin = min(smin, sk)
            lo = max(lo, 0.0)
            est = target[r] / max(smax - smin, 1e-12)
            u_try = ratio[r, j] * est
            u_lo[r, j], u_hi[r, j], u_est[r, j] = lo, hi, est
            feasible[r, j] = (lo <= hi) and (u_try <= hi)
            u_use = min(max(u_try, lo), max(hi, lo))
            worst = 0.0
            for k in range(S):
                p = wx[r, k] * cj + wy[r, k] * sj
                worst = max(worst, abs(A[r, k] * u_use + p / rho[r]))
            cos_max[r, j] = worst


def direction_estimates(wx, wy, A, inv_a_rho, half, rho, c, s, branch, target, ratio):
    """For samples ``wx, wy, A, inv_a_rho, half`` ``(R, S)`` (C-contiguous float64), radii
    ``rho`` and swings ``target`` ``(R,)``, direction cosines and sines ``c, s``, branches and
    scale ``ratio`` ``(R, J)``: (u_lo, u_hi, u_est, cos_max, feasible), each ``(R, J)`` —
    :meth:`synth.dyad._RrrTerms.estimate`'s quantities before its arccos."""
    R, J = c.shape
    out = [np.empty((R, J)) for _ in range(4)] + [np.empty((R, J), np.bool_)]
    _estimates(wx, wy, A, inv_a_rho, half, rho, c, s, branch, target, ratio, *out)
    return tuple(out)
