"""The candidate stage's reads of the exact path, compiled: how far each grid candidate's path
follows its osculating line or circle (:mod:`synth.segment_search.segments`, stages 1–2).

For a candidate at crank step j of a linkage (coupler point ``uv``; osculating line through
``point`` along ``direction``, or circle about ``point`` of ``radius``) the path is sampled on
the search's crank grid, z_k = A_k + e^{iθ_k}·uv (docs/curvature.md §3), and measured with
:func:`synth.segment_search.minimum_zone_kernel.deviation_at`:

* :func:`osculating_scores`: the deviation at the offsets ±h, ±2h, ±4h (h = half the minimum
  dwell): a candidate whose path leaves ``band`` at both ±h cannot hold the minimum dwell
  (any such interval around j contains one of them); the others are scored by
  Σ_k (|dev(−kh)| + |dev(kh)|)/k⁴ (a Δφ⁴ stretch deviates k⁴ times more at k times the
  offset), the smaller the better. Ten path points per candidate instead of a whole run.
* :func:`osculating_runs`: for the local bests, the run of samples within ``band`` and within
  ``eps`` contiguous with j, each way, stopping where the path leaves ``band``.
"""

from __future__ import annotations

import numba
import numpy as np

from synth.segment_search.minimum_zone_kernel import deviation_at

__all__ = ["osculating_runs", "osculating_scores"]

#: Further offsets (multiples of h) at which the score looks at the path, with weight 1/k⁴.
SCORE_OFFSETS = (2, 4)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _deviation(A, E, row, k, m, uv, kind, point, direction, radius):
    """|deviation| of linkage ``row``'s path at crank step ``k`` (cyclic)."""
    k = k % m
    return abs(deviation_at(A[row, k] + E[row, k] * uv, kind, point, direction, radius))


@numba.njit(cache=True, nogil=True, error_model="numpy")
def osculating_scores(A, E, uv, point, direction, radius, ok, kind, half, band):
    """Scores of every grid candidate: (n, m, K) arrays ``uv``, ``point``, ``direction``,
    ``radius``, ``ok`` (the candidate exists) over ``A``, ``E`` (n, m). Returns (alive, score):
    alive = ok and within ``band`` at −h or +h; score = −Σ (see the module) where alive, −inf
    elsewhere."""
    n, m, K = uv.shape
    alive = np.zeros((n, m, K), np.bool_)
    score = np.full((n, m, K), -np.inf)
    steps = np.array([-half, half] + [s * f * half for f in SCORE_OFFSETS for s in (-1, 1)])
    power = np.array([1.0, 1.0] + [float(f**4) for f in SCORE_OFFSETS for _ in (-1, 1)])  # k⁴ per offset
    pin = np.empty(steps.size, np.complex128)
    turn = np.empty(steps.size, np.complex128)
    for i in range(n):
        for j in range(m):
            for t in range(steps.size):  # the path's samples at the offsets, for every ray
                k = (j + steps[t]) % m
                pin[t], turn[t] = A[i, k], E[i, k]
            for q in range(K):
                if not ok[i, j, q]:
                    continue
                u, p, d, r = uv[i, j, q], point[i, j, q], direction[i, j, q], radius[i, j, q]
                minus = abs(deviation_at(pin[0] + turn[0] * u, kind, p, d, r))
                plus = abs(deviation_at(pin[1] + turn[1] * u, kind, p, d, r))
                if not (minus <= band or plus <= band):
                    continue
                s = minus + plus
                for t in range(2, steps.size, 2):
                    s += (
                        abs(deviation_at(pin[t] + turn[t] * u, kind, p, d, r))
                        + abs(deviation_at(pin[t + 1] + turn[t + 1] * u, kind, p, d, r))
                    ) / power[t]
                alive[i, j, q] = True
                score[i, j, q] = -s
    return alive, score


@numba.njit(cache=True, nogil=True, error_model="numpy")
def osculating_runs(A, E, row, step, uv, point, direction, radius, kind, reach, band, eps):
    """Per candidate (linkage ``row``, crank ``step``, ``uv`` and osculating geometry, each
    (C,)): samples within ``band`` contiguous with the step on its left and on its right, up to
    ``reach`` each way, and the same within ``eps`` (≤ ``band``). Each is −1 on both sides when
    the step itself is outside. Returns (left, right, eps_left, eps_right)."""
    C = row.size
    m = A.shape[1]
    out = np.full((4, C), -1, np.int64)
    for c in range(C):
        i, j, u, p, d, r = row[c], step[c], uv[c], point[c], direction[c], radius[c]
        at = _deviation(A, E, i, j, m, u, kind, p, d, r)
        if not at <= band:
            continue
        for side in range(2):
            sign = -1 if side == 0 else 1
            inner = at <= eps
            run = inner_run = 0
            for k in range(1, reach + 1):
                dev = _deviation(A, E, i, j + sign * k, m, u, kind, p, d, r)
                if not dev <= band:
                    break
                run = k
                if inner and dev <= eps:
                    inner_run = k
                else:
                    inner = False
            out[side, c] = run
            out[2 + side, c] = inner_run if at <= eps else -1
    return out[0], out[1], out[2], out[3]
