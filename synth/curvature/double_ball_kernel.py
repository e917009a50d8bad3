"""The double-Ball-point search's box sweep, compiled (:mod:`synth.curvature.double_ball`).

Pairs of track segments of one linkage whose closed bounding boxes meet: per linkage, the
segments in order of their smallest x, each tested against the later ones up to the first
whose smallest x is beyond its largest. Comparisons only, so exact; it replaces a shapely
``STRtree`` per linkage (touching boxes count, as in a GEOS query).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["box_sweep"]


@numba.njit(cache=True, nogil=True)
def box_sweep(p0, p1, start, end, first, size, by_left):
    """Pairs (i, j), i < j, of segments p0→p1 whose closed boxes meet and that are not
    neighbours along the track (``end`` of one is the ``start`` sample of the other); linkage
    g holds segments ``first[g] : first[g] + size[g]``, and ``by_left[first[g] : first[g] +
    size[g]]`` are their indices in order of their smallest x (sorted by the caller: a sort
    compiled here, numba's ``np.argsort``, cost ~5 s of CPU to compile on a first run).
    Grouped by linkage, in no particular order within one."""
    n_max = size.max() if size.size else 0
    # one linkage's boxes in x order, copied contiguous for the inner loop
    x0, x1, y0, y1 = np.empty(n_max), np.empty(n_max), np.empty(n_max), np.empty(n_max)
    s_start, s_end = np.empty(n_max, np.int64), np.empty(n_max, np.int64)
    cap = 4 * p0.size + 64
    out_i, out_j = np.empty(cap, np.int64), np.empty(cap, np.int64)
    m = 0
    for g in range(first.size):
        lo, n = first[g], size[g]
        order = by_left[lo : lo + n]
        for a in range(n):
            k = order[a]
            u, v = p0[k], p1[k]
            x0[a], x1[a] = min(u.real, v.real), max(u.real, v.real)
            y0[a], y1[a] = min(u.imag, v.imag), max(u.imag, v.imag)
            s_start[a], s_end[a] = start[k], end[k]
        for a in range(n):
            if m + n > cap:  # room for every partner a could have
                cap = 2 * cap + n
                out_i = np.concatenate((out_i[:m], np.empty(cap - m, np.int64)))
                out_j = np.concatenate((out_j[:m], np.empty(cap - m, np.int64)))
            ax1, ay0, ay1, a_start, a_end, i = x1[a], y0[a], y1[a], s_start[a], s_end[a], order[a]
            for b in range(a + 1, n):
                if x0[b] > ax1:
                    break
                # every candidate is written, the count moves on only for a pair kept (no
                # branch to mispredict: most candidates are neighbours or miss in y)
                out_i[m] = i
                out_j[m] = order[b]
                keep = (y0[b] <= ay1) & (ay0 <= y1[b]) & (a_end != s_start[b]) & (s_end[b] != a_start)
                m += 1 if keep else 0
    i, j = out_i[:m], out_j[:m]
    return np.minimum(i, j), np.maximum(i, j)
