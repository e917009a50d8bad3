"""Extremes of ψ's samples, compiled: what the dwell and deviation searches of
:mod:`synth.mechanism.output_range` ask of the samples before and between the points they evaluate
exactly — each local extreme raised (lowered) to its parabola's vertex
(:func:`vertex_bounds`), and the largest and smallest sample over ranges of samples
(:func:`range_extremes`), and over windows of one width sliding by one sample
(:func:`sliding_extremes`).

Each range query reads its own range, one pass (a few hundred samples at most: a dwell or a
window of the 0.5° grid). It replaced sparse tables (binary lifting), which cost more to
build for every row and level than all of a search's queries. Max and min round nothing, so
the answers are those of any exhaustive reading; the vertices are the same operations as
:func:`kinematics.loop.parabola_vertex`'s: both bit for bit
(``tests/synth/test_sample_ranges.py``).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike

from synth.parallel_rows import over_rows
from synth.types import F64

__all__ = [
    "parabola_rise",
    "range_extremes",
    "range_max_min",
    "sliding_extremes",
    "sliding_rows",
    "vertex_bounds",
]


@numba.njit(cache=True, nogil=True)
def parabola_rise(ym, y0, yp):
    """Scalar :func:`kinematics.loop.parabola_vertex`, the same operations: (the second
    difference D = y₋ − 2y₀ + y₊, the vertex's rise over y₀ −(y₋ − y₊)²/(8D), 0 where D = 0)."""
    den = ym - 2 * y0 + yp
    if den == 0:
        return den, 0.0
    diff = ym - yp
    return den, -(diff**2 / (8 * den))


@numba.njit(cache=True, nogil=True)
def range_max_min(upper, lower, r, s, n):
    """(max of ``upper``, min of ``lower``) over samples [s, s + n) of row ``r``; (+inf, −inf)
    for a range that is empty or runs off the samples (never within a band)."""
    if s < 0 or n < 1 or s + n > upper.shape[1]:
        return math.inf, -math.inf
    a, b = upper[r, s], lower[r, s]
    for i in range(s + 1, s + n):
        a = max(a, upper[r, i])
        b = min(b, lower[r, i])
    return a, b


@numba.njit(cache=True, nogil=True)
def _extremes(upper, lower, start, count, hi, lo):
    R, K = start.shape
    for r in range(R):
        for k in range(K):
            hi[r, k], lo[r, k] = range_max_min(upper, lower, r, start[r, k], count[r, k])


@numba.njit(cache=True, nogil=True)
def sliding_rows(values, first, count, width, hi, lo):
    """:func:`sliding_extremes` into ``hi`` and ``lo`` (``(R, ≥ count)``): row r's windows of
    ``width[r]`` samples of ``values`` ``(R, T)`` from ``first + j``, j < ``count``."""
    R, T = values.shape
    top, bottom = np.empty(T, np.int64), np.empty(T, np.int64)  # indices, values monotone
    for r in range(R):
        w = width[r]
        if w < 1 or first < 0 or first + count - 1 + w > T:  # some window off the samples: read each
            for j in range(count):
                hi[r, j], lo[r, j] = range_max_min(values, values, r, first + j, w)
            continue
        t0 = t1 = b0 = b1 = 0  # deque [t0, t1) of maxima, [b0, b1) of minima
        for i in range(first, first + count - 1 + w):
            x = values[r, i]
            while t1 > t0 and values[r, top[t1 - 1]] <= x:
                t1 -= 1
            top[t1] = i
            t1 += 1
            while b1 > b0 and values[r, bottom[b1 - 1]] >= x:
                b1 -= 1
            bottom[b1] = i
            b1 += 1
            j = i - w + 1 - first  # the window [first + j, i] is complete
            if j >= 0:
                while top[t0] < first + j:
                    t0 += 1
                while bottom[b0] < first + j:
                    b0 += 1
                hi[r, j], lo[r, j] = values[r, top[t0]], values[r, bottom[b0]]


def sliding_extremes(values: F64, first: int, count: int, width: ArrayLike) -> tuple[F64, F64]:
    """(max, min) of ``values`` ``(R, T)`` over the windows [first + j, first + j + width[r])
    of each row, j < ``count``: :func:`range_extremes` of those windows, the same numbers, in
    one pass per row (two monotone queues, O(count + width) instead of O(count · width)).
    Shape ``(R, count)``."""
    values = np.ascontiguousarray(values, dtype=float)
    R = values.shape[0]
    w = np.ascontiguousarray(np.broadcast_to(np.asarray(width, np.int64), (R,)))
    hi, lo = np.empty((R, count)), np.empty((R, count))
    sliding_rows(values, int(first), int(count), w, hi, lo)
    return hi, lo


def range_extremes(upper: F64, lower: F64, start: ArrayLike, count: ArrayLike) -> tuple[F64, F64]:
    """(max of ``upper``, min of ``lower``) over the samples [start, start + count) of each
    row: ``upper``, ``lower`` ``(R, T)`` (the same array for a plain max and min), ``start``
    and ``count`` integer arrays broadcast to ``(R, ...)``, row r's queries in ``[r]``;
    +inf and −inf for a range that is empty or runs off the samples. Shape: the broadcast."""
    s, n = np.broadcast_arrays(np.asarray(start, np.int64), np.asarray(count, np.int64))
    R = upper.shape[0]
    if s.shape[:1] != (R,):
        raise ValueError(f"the queries' first axis must be the {R} rows")
    s2, n2 = np.ascontiguousarray(s.reshape(R, -1)), np.ascontiguousarray(n.reshape(R, -1))
    hi, lo = np.empty(s2.shape), np.empty(s2.shape)
    _extremes(np.ascontiguousarray(upper, dtype=float), np.ascontiguousarray(lower, dtype=float), s2, n2, hi, lo)
    return hi.reshape(s.shape), lo.reshape(s.shape)


@numba.njit(cache=True, nogil=True)
def _vertex_bounds(E, upper, lower):
    R, T = E.shape
    for r in range(R):
        upper[r, 0], lower[r, 0] = E[r, 0], E[r, 0]
        upper[r, T - 1], lower[r, T - 1] = E[r, T - 1], E[r, T - 1]
        for i in range(1, T - 1):
            ym, y0, yp = E[r, i - 1], E[r, i], E[r, i + 1]
            den, rise = parabola_rise(ym, y0, yp)
            step = min(abs(rise), abs(den))  # a vertex far outside its step is no peak
            # + 0.0 where nothing is lifted, as the array expression adds it (−0.0 → 0.0)
            upper[r, i] = y0 + (step if (den < 0 and y0 >= ym and y0 >= yp) else 0.0)
            lower[r, i] = y0 - (step if (den > 0 and y0 <= ym and y0 <= yp) else 0.0)


def vertex_bounds(E: F64) -> tuple[F64, F64]:
    """(upper, lower) of samples ``E`` ``(R, T)``: each interior sample that is a local maximum
    (minimum) raised (lowered) to the vertex of the parabola through it and its two
    neighbours (:func:`kinematics.loop.parabola_vertex`), by at most the second difference
    (a vertex far outside its step is no peak); the end samples and the others as they are."""
    E = np.ascontiguousarray(E, dtype=float)
    upper, lower = np.empty_like(E), np.empty_like(E)
    # ~3 ns a sample
    over_rows(E.shape[0], lambda lo, hi: _vertex_bounds(E[lo:hi], upper[lo:hi], lower[lo:hi]), 3 * E.size)
    return upper, lower
