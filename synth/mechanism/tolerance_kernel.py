"""Bounds of the toleranced draws' refined deviations from their samples alone, compiled: the
two bounds :func:`synth.mechanism.tolerance.toleranced_deviation` decides its refined draws on,
one pass per row.

Per draw and dwell window, from the samples of ψ every grid step (the slab the refinement
reads, :func:`synth.mechanism.dwell_ends_kernel.refine_deviation_windows`) and the best grid
start:

- the samples' bounds: below, the range of the samples every refined window holds, or the
  grid's range where that is less; above, the range of the samples over the window from the
  grid start (one sample more where the length is not a whole number of steps), widened by
  an eighth of their largest second difference on each side (how far ψ can rise between
  two samples);
- the interpolated bounds: the refinement's two stages followed with ψ at the window ends
  taken from the cubic through the four nearest samples instead of computed, each value
  allowed the cubic's error, bounded by ``safety`` times the nearby fourth difference.

The numpy form of these bounds ran ~40 whole-array operations per call: at 256 draws, more
than 1 ms, about what refining every draw costs, so it paid only where the samples' bounds
left more than a third of the draws open. Here each row is a few hundred operations in one
loop, 0.2 ms for 256 draws, and both bounds are taken for every draw.
``tests/synth/test_tolerance.py`` holds every draw's refined figure inside both bounds.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from synth.parallel_rows import one_signature
from synth.types import F64

__all__ = ["window_bounds"]


def window_bounds(
    slab: F64,
    i_lo: np.ndarray,
    k: np.ndarray,
    nL: int,
    length: float,
    c: F64,
    dev: F64,
    h: float,
    safety: float,
    steps: int,
    fine: int,
) -> tuple[F64, F64, F64, F64]:
    """(lower, upper) of the samples and (lower, upper) interpolated (rad, each ``(R,)``) of
    what :func:`~synth.mechanism.dwell_ends_kernel.refine_deviation_windows` returns for each
    row given the same ``slab`` (samples from i_lo − 1 on, step ``h`` rad), best grid start at
    slab offset ``k`` with range ``dev``, ``nL`` grid steps per window, window ``length`` (rad)
    that must contain ``c`` (rad), and ``steps`` + 1 and ``fine`` + 1 points in its two stages.
    A row whose interpolated bounds cannot be taken (a first-stage winner not clear of the
    other starts by the interpolation's error, stencils off the slab, ``nL`` < 2) gets [0, inf)
    for them."""
    R = slab.shape[0]
    out = np.empty((4, R))
    args = (
        np.ascontiguousarray(slab, dtype=float),
        np.ascontiguousarray(i_lo, dtype=np.int64),
        np.ascontiguousarray(k, dtype=np.int64),
        int(nL),
        float(length),
        np.ascontiguousarray(c, dtype=float),
        np.ascontiguousarray(dev, dtype=float),
        float(h),
        float(safety),
        int(steps),
        int(fine),
        out,
    )
    one_signature(_bounds, args)
    _bounds(*args)
    return out[0], out[1], out[2], out[3]


@numba.njit(cache=True, nogil=True)
def _cubic(slab, r, base, at):
    """ψ at slab column ``base + at`` of row ``r`` from the cubic through the four nearest
    samples (Lagrange's weights, in the order of operations of the numpy form)."""
    whole = math.floor(at)
    t = at - whole
    a, b, c, d = t + 1, t, t - 1, t - 2
    m = base + int(whole)
    ad, bc = a * d, b * c
    value = (bc * d) * (-1 / 6) * slab[r, m - 1] + (a * c * d) * 0.5 * slab[r, m]
    value += (ad * b) * (-0.5) * slab[r, m + 1]
    return value + (a * bc) * (1 / 6) * slab[r, m + 2]


@numba.njit(cache=True, nogil=True)
def _fourth(slab, r, first):
    """The largest |fourth difference| of the ten samples from column ``first`` − 3 of row r."""
    y = np.empty(10)
    for i in range(10):
        y[i] = slab[r, first - 3 + i]
    for order in range(4):
        for i in range(9 - order):
            y[i] = y[i + 1] - y[i]
    worst = 0.0
    for i in range(6):
        worst = max(worst, abs(y[i]))
    return worst


@numba.njit(cache=True, nogil=True)
def _ranges(fv, gv, top, bottom, f, lo, hi, out):
    """Each window q of a stage: the range of its starts q … Q − 1 (``fv``), its ends 0 … q
    (``gv``) and ``top``/``bottom`` between; +inf where its start ``f[q]`` is not in [lo, hi]."""
    n = fv.shape[0]
    s_hi, s_lo = -math.inf, math.inf
    for q in range(n - 1, -1, -1):  # suffix extremes of the starts
        s_hi, s_lo = max(s_hi, fv[q]), min(s_lo, fv[q])
        out[q] = s_hi
        out[n + q] = s_lo
    p_hi, p_lo = -math.inf, math.inf
    for q in range(n):
        p_hi, p_lo = max(p_hi, gv[q]), min(p_lo, gv[q])
        high = max(max(out[q], p_hi), top)
        low = min(min(out[n + q], p_lo), bottom)
        out[q] = high - low if (f[q] >= lo and f[q] <= hi) else math.inf


@numba.njit(cache=True, nogil=True)
def _bounds(slab, i_lo, k, nL, length, c, dev, h, safety, steps, fine, out):
    R, cols = slab.shape
    span = length / h
    reach = nL + 1 + (1 if nL * h < length - 1e-12 else 0)
    q1, q3 = steps + 1, fine + 1
    fv, gv, f = np.empty(q1), np.empty(q1), np.empty(q1)
    fv3, gv3, f3, t3 = np.empty(q3), np.empty(q3), np.empty(q3), np.empty(q3)
    r1, r3 = np.empty(2 * q1), np.empty(2 * q3)
    for q in range(q3):
        t3[q] = -1.0 + q * (2.0 / fine)
    t3[fine] = 1.0
    edge_at = np.array([0, 1, nL - 1, nL, nL + 1])
    d = 2 * h / steps
    last = int(math.floor(span - 0.25))
    for r in range(R):
        kr = k[r]
        # the samples' bounds: the window from the grid start and the samples every refined
        # window holds (one step after the start to one before the end)
        hi_w, lo_w, bend = -math.inf, math.inf, 0.0
        for i in range(reach):
            hi_w, lo_w = max(hi_w, slab[r, kr + i]), min(lo_w, slab[r, kr + i])
            if i >= 2:
                bend = max(bend, abs(slab[r, kr + i] - 2 * slab[r, kr + i - 1] + slab[r, kr + i - 2]))
        floor_range = 0.0
        if nL >= 2:
            hi_in, lo_in = -math.inf, math.inf
            for i in range(1, nL):
                hi_in, lo_in = max(hi_in, slab[r, kr + i]), min(lo_in, slab[r, kr + i])
            floor_range = hi_in - lo_in
        out[0, r] = min(floor_range, dev[r])
        out[1, r] = hi_w - lo_w + 2 * (bend / 8)
        out[2, r], out[3, r] = 0.0, math.inf
        p0 = kr - 1  # the kernel's first start f₀ = grid start − h, in slab columns
        if nL < 2 or p0 < 4 or p0 + last + 6 >= cols:
            continue
        e = safety * (9 / 16) / 24 * max(_fourth(slab, r, p0 - 1), _fourth(slab, r, p0 + last)) + 1e-13
        # stage 1: steps + 1 starts over the two steps around the grid start (the kernel's own
        # arithmetic for f), their ends L later
        s_lo = (i_lo[r] - 2 + kr) * h
        for q in range(q1):
            f[q] = s_lo + 2 * h * (q / steps)
            at = 2 * (q / steps)
            fv[q] = _cubic(slab, r, p0, at)
            gv[q] = _cubic(slab, r, p0, at + span)
        # the samples between a window's exact points: the core k + 2 … k + nL − 2 that both
        # stages hold, and a few edges
        core_hi, core_lo = -math.inf, math.inf
        for i in range(max(nL - 3, 0)):
            core_hi, core_lo = max(core_hi, slab[r, p0 + 3 + i]), min(core_lo, slab[r, p0 + 3 + i])
        top, bottom = core_hi, core_lo
        if nL >= 3:  # offset k + nL − 1 is the first stage's last sample
            top, bottom = max(top, slab[r, kr + nL - 1]), min(bottom, slab[r, kr + nL - 1])
        lo_f, hi_f = c[r] - length - 1e-12, c[r] + 1e-12
        _ranges(fv, gv, top, bottom, f, lo_f, hi_f, r1)
        j, best, runner_up = 0, r1[0], math.inf
        for q in range(1, q1):
            if r1[q] < best:
                runner_up = best
                j, best = q, r1[q]
            else:
                runner_up = min(runner_up, r1[q])
        if not (best + 4 * e < runner_up and best < math.inf):
            continue
        if nL >= 4:
            # stage 2: fine + 1 starts within one first-stage step of the winner, each window
            # holding the samples strictly inside (f_best + d, f_best − d + L) and the first
            # stage's starts after the winner and ends before it
            f_best = f[j]
            i0 = int(math.floor((f_best + d) / h - (i_lo[r] - 1))) + 1
            end = int(math.ceil((f_best - d + length) / h - (i_lo[r] - 1)))
            top, bottom = core_hi, core_lo
            for t in range(5):
                col = kr + edge_at[t]
                if col - i0 >= 0 and col < end:
                    top, bottom = max(top, slab[r, col]), min(bottom, slab[r, col])
            for q in range(q1):
                if q > j:
                    top, bottom = max(top, fv[q]), min(bottom, fv[q])
                elif q < j:
                    top, bottom = max(top, gv[q]), min(bottom, gv[q])
            for q in range(q3):
                f3[q] = f_best + d * t3[q]
                offset = 2 * (j / steps) + (d / h) * t3[q]
                fv3[q] = _cubic(slab, r, p0, offset)
                gv3[q] = _cubic(slab, r, p0, offset + span)
            _ranges(fv3, gv3, top, bottom, f3, lo_f, hi_f, r3)
            for q in range(q3):
                best = min(best, r3[q])
        out[2, r], out[3, r] = max(best - 2 * e, 0.0), best + 2 * e
