"""The dwell refinement's pair search compiled (:func:`longest_pair`'s
work): for each query, the longest (start, end) pair of exact points within the band, one
pass over the start × end points instead of ``(queries, starts, ends)`` temporaries.

The same operations in the same order as the numpy expressions it replaced (suffix and
prefix extremes, the band test per pair, the linear share of the next step), so the pairs
and every figure are the same bit for bit (``tests/synth/test_pair_search.py`` keeps the
numpy form as the reference).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["longest_pair", "longest_pairs", "pair_query"]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def pair_query(left_at, lv, right_at, rv, hi_in, lo_in, b, scratch, last_of):
    """One query: start points ``left_at``/``lv``, end points ``right_at``/``rv`` (1-D,
    ascending), the extremes ``hi_in``/``lo_in`` of what lies between, the band ``b``;
    ``scratch`` ``(7, max(nl, nr))`` and ``last_of`` ``(nl,)`` are work space. Returns (jl, jr,
    start, end, low, high, inner_hi, inner_lo, reach) as :func:`longest_pairs` describes."""
    nl, nr = lv.shape[0], rv.shape[0]
    Hl, Ll, pr_max, pr_min, sl_max, sl_min = scratch[0], scratch[1], scratch[2], scratch[3], scratch[4], scratch[5]
    f_of = scratch[6]
    # suffix extremes of the starts, prefix extremes of the ends
    sl_max[nl - 1], sl_min[nl - 1] = lv[nl - 1], lv[nl - 1]
    for j in range(nl - 2, -1, -1):
        sl_max[j] = max(lv[j], sl_max[j + 1])
        sl_min[j] = min(lv[j], sl_min[j + 1])
    pr_max[0], pr_min[0] = rv[0], rv[0]
    for j in range(1, nr):
        pr_max[j] = max(pr_max[j - 1], rv[j])
        pr_min[j] = min(pr_min[j - 1], rv[j])
    for j in range(nl):
        Hl[j] = max(hi_in, sl_max[j])
        Ll[j] = min(lo_in, sl_min[j])
    best, best_score = 0, -np.inf
    for jl in range(nl):
        ok_l = (Hl[jl] - Ll[jl]) <= b
        cnt = 0
        for jr in range(nr):
            ok_r = (pr_max[jr] - pr_min[jr]) <= b
            top = max(Hl[jl], pr_max[jr])
            bottom = min(Ll[jl], pr_min[jr])
            if ok_l and ok_r and (top - bottom) <= b:
                cnt += 1
        last = max(cnt - 1, 0)
        u = rv[last]
        v = rv[min(last + 1, nr - 1)]
        up = min(Ll[jl], pr_min[last]) + b
        down = max(Hl[jl], pr_max[last]) - b
        if v > up:
            f = (up - u) / (v - u)
        elif v < down:
            f = (u - down) / (u - v)
        else:
            f = 0.0
        # the share of the next step the band still holds, ψ linear there
        f = min(max(f, 0.0), 1.0) if (cnt < nr and np.isfinite(f)) else 0.0
        score = (last + f) - jl if cnt > 0 else -np.inf
        last_of[jl], f_of[jl] = last, f
        if score > best_score:
            best, best_score = jl, score
    jl, jr = best, last_of[best]
    start, end = left_at[jl], right_at[jr]
    high = max(Hl[jl], pr_max[jr])
    low = min(Ll[jl], pr_min[jr])
    inner_hi = max(max(hi_in, sl_max[jl + 1] if jl + 1 < nl else -np.inf), pr_max[jr - 1] if jr >= 1 else -np.inf)
    inner_lo = min(min(lo_in, sl_min[jl + 1] if jl + 1 < nl else np.inf), pr_min[jr - 1] if jr >= 1 else np.inf)
    reach = end + f_of[jl] * (right_at[1] - right_at[0])
    return jl, jr, start, end, low, high, inner_hi, inner_lo, reach


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _pairs(left_at, lv, right_at, rv, hi_in, lo_in, band, out_i, out_f):
    Q, nl = lv.shape
    scratch = np.empty((7, max(nl, rv.shape[1])))
    last_of = np.empty(nl, np.int64)
    for q in range(Q):
        jl, jr, start, end, low, high, inner_hi, inner_lo, reach = pair_query(
            left_at[q], lv[q], right_at[q], rv[q], hi_in[q], lo_in[q], band[q], scratch, last_of
        )
        out_i[q, 0], out_i[q, 1] = jl, jr
        out_f[q, 0], out_f[q, 1], out_f[q, 2], out_f[q, 3] = start, end, low, high
        out_f[q, 4], out_f[q, 5], out_f[q, 6] = inner_hi, inner_lo, reach


def longest_pairs(left_at, lv, right_at, rv, hi_in, lo_in, band):
    """:func:`longest_pair` for queries flattened to ``(Q, points)``
    (``left_at``, ``lv``: start points and their ψ; ``right_at``, ``rv``: end points; each
    ascending, C-contiguous float64), ``hi_in``, ``lo_in``, ``band`` ``(Q,)``: (start, end,
    low, high, inner_hi, inner_lo, reach), each ``(Q,)``."""
    Q = lv.shape[0]
    out_i = np.empty((Q, 2), np.int64)
    out_f = np.empty((Q, 7))
    _pairs(left_at, lv, right_at, rv, hi_in, lo_in, band, out_i, out_f)
    return tuple(out_f[:, k] for k in range(7))


def longest_pair(left_at, lv, right_at, rv, hi_in, lo_in, band):
    """The longest (start, end) pair of exact points, start among ``left_at`` and end among
    ``right_at`` (each ascending, the left ones before the right ones), whose values and the
    interior's extremes (``hi_in``, ``lo_in``: everything strictly between the two point sets)
    stay within ``band``. Shapes ``(R, ...)`` plus the points axis. Returns start, end, low,
    high, the extremes of what lies strictly inside (start, end) less one point at each end
    (for a finer stage), and the end's linear estimate beyond the last point (ranks pairs).

    For each start the feasible ends are a prefix (the range only grows): its last end, and
    the share of the next step the band still holds, ψ linear there, rank the pairs — the
    lengths of pairs that the points alone would tie (a slowly drifting output gives many)
    differ. Compiled, one query at a time (:func:`longest_pairs`); the dwell refinement of
    :func:`synth.mechanism.output_range.dwell_intervals` calls it."""
    shape = np.shape(hi_in)
    R = shape[0]
    nl, nr = lv.shape[-1], rv.shape[-1]

    def flat(x, n):
        return np.ascontiguousarray(np.broadcast_to(x, shape + (n,)).reshape(-1, n), dtype=float)

    b = np.broadcast_to(np.asarray(band, float).reshape((R,) + (1,) * (len(shape) - 1)), shape)
    per_query = (np.ascontiguousarray(np.broadcast_to(x, shape).ravel(), dtype=float) for x in (hi_in, lo_in, b))
    out = longest_pairs(flat(left_at, nl), flat(lv, nl), flat(right_at, nr), flat(rv, nr), *per_query)
    return tuple(x.reshape(shape) for x in out)
