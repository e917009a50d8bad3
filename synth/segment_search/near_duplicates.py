"""Near-duplicate segments of one linkage, compiled (:mod:`synth.segment_search.segments`, stage 3).

Two segments of one linkage and kind are near-duplicates when their coupler points lie within
50 tolerances of each other and their intervals overlap by more than half of the shorter one
(intervals may be expressed a turn apart). Within a group, longest first, each segment still
kept removes the later ones it duplicates (greedy): the longest of each cluster stays.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["duplicates"]


@numba.njit(cache=True, nogil=True)
def duplicates(uv, start, end, dwell, bounds, reach):
    """Per segment (grouped, longest first within a group: group g is ``bounds[g] :
    bounds[g + 1]``), whether an earlier kept segment of its group duplicates it; ``reach``:
    how close two coupler points must be (crank lengths)."""
    dead = np.zeros(uv.size, np.bool_)
    for g in range(bounds.size - 1):
        for i in range(bounds[g], bounds[g + 1]):
            if dead[i]:
                continue
            for j in range(i + 1, bounds[g + 1]):
                if dead[j] or not abs(uv[i] - uv[j]) < reach:
                    continue
                lo, hi = max(start[i], start[j]), min(end[i], end[j])
                for shift in (-2 * math.pi, 2 * math.pi):
                    lo2, hi2 = max(start[i], start[j] + shift), min(end[i], end[j] + shift)
                    if hi2 - lo2 > hi - lo:
                        lo, hi = lo2, hi2
                if hi - lo > 0.5 * min(dwell[i], dwell[j]):
                    dead[j] = True
    return dead
