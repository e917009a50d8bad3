"""The toleranced draws' dwell windows, compiled: their ψ samples and best grid starts
(:func:`window_samples`), and the two bounds of their refined deviations that
:func:`synth.mechanism.tolerance.toleranced_deviation` decides its refined draws on
(:func:`window_bounds`), one pass per row each.

The samples are ψ alone: the four-bar's closing triangle for the coupler point and the output
dyad's for the rocker (RPR: the slot through the pin), each without the statuses, rates and
placeholders of :mod:`synth.mechanism.sixbar_kernel` (every draw here assembles over the whole
turn), and the angle taken from the draw's direction at its dwell middle, where an odd series
replaces the library's arctangent. ~35 ns a sample against the position kernel's ~85, which
computed every joint and the transmission angles. A sample's ψ depends on no other sample
(but for its 2π branch), so sampling a draw at some columns or at all gives the same values.

The bounds, per draw and dwell window, from the samples of ψ every grid step (the slab the
refinement reads, :func:`synth.mechanism.dwell_ends_kernel.refine_deviation_windows`) and the
best grid start:

- the samples' bounds: below, the range of the samples every refined window holds, or the
  grid's range where that is less; above, the range of the samples over the window from the
  grid start (one sample more where the length is not a whole number of steps), widened by
  an eighth of their largest second difference on each side (how far ψ can rise between
  two samples);
- the interpolated bounds: the refinement's two stages followed with ψ at the window ends
  taken from the cubic through the four nearest samples instead of computed, each value
  allowed the cubic's error, bounded by ``safety`` times the nearby fourth difference.

The numpy form of these bounds ran ~40 whole-array operations per call: at 256 draws, more
than 1 ms, about what refining every draw costs. Here each row is a few hundred operations in
one loop, 0.2 ms for 256 draws, and both bounds are taken for every draw.
``tests/synth/test_tolerance.py`` holds every draw's refined figure inside both bounds.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numba
import numpy as np

from kinematics.loop import COINCIDENT_EPS, TOGGLE_EPS
from synth.parallel_rows import one_signature, over_rows
from synth.types import F64

__all__ = ["limits_clear", "window_bounds", "window_samples"]


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


def window_samples(
    params: F64,
    rpr: np.ndarray,
    phi: F64,
    ref: np.ndarray,
    first: np.ndarray,
    last: np.ndarray,
    nL: int,
    zone: int,
    step: int,
) -> tuple[F64, np.ndarray, F64, np.ndarray]:
    """ψ (rad) of each draw (``params``/``rpr``: :func:`synth.mechanism.sixbar.kernel_inputs`
    of draws that assemble over the whole turn) on the crank grid ``phi`` (rad, one step apart,
    shared by the draws) where its windows of ``nL`` + 1 samples can start (columns
    ``first[i]`` … ``last[i]``), the best start's column less one, that window's range (rad),
    and which draws were sampled at every column. ``ref[i]``: the column of draw i's dwell
    middle, the direction its angles are taken from.

    The draws are near one another: the first is sampled at every column and its best start
    a₀ found; the others at every column only where a best start within ``zone`` columns of a₀
    reads its samples (from 5 before the start to 6 after its window's end, as the refinement
    and :func:`window_bounds` do) and every ``step``-th column elsewhere. A start outside the
    zone must be shown worse than the best inside by the every-``step``-th samples its window
    holds ((nL + 1) // step of them from the first at or after it); a draw where one is not is
    sampled whole, as the first is, and its best start taken among all. Where that would save
    less than a fifth of the samples, every draw is sampled whole. Columns not sampled (never
    read) are NaN. The draws are split over threads only from :data:`_SPLIT_NS` of estimated
    work (a candidate's 256 draws run in the caller's thread); the values do not depend on it."""
    n, G = params.shape[0], len(phi)
    cosg, sing = np.cos(phi), np.sin(phi)
    ref = np.clip(np.asarray(ref, dtype=np.int64), 0, G - 1)
    first = np.ascontiguousarray(first, dtype=np.int64)
    last = np.ascontiguousarray(last, dtype=np.int64)
    slab = np.full((n, G), math.nan)
    start, width = np.empty(n, np.int64), np.empty(n)
    whole = np.zeros(n, bool)
    every = np.arange(G)

    def rows(lo: int, hi: int, cols: np.ndarray, zs: int, ze: int, l0: int) -> None:
        sl = slice(lo, hi)
        _sample_rows(
            params[sl],
            rpr[sl],
            cosg,
            sing,
            ref[sl],
            first[sl],
            last[sl],
            nL,
            cols,
            zs,
            ze,
            l0,
            step,
            slab[sl],
            start[sl],
            width[sl],
            whole[sl],
        )

    def rows_whole(lo: int, hi: int) -> None:
        rows(lo, hi, every, 1, 0, 0)

    fine = 2 * zone + nL + 12  # columns sampled every step
    if fine + (G - fine) / step > 0.8 * G:  # little to save: every column
        _over_draws(n, rows_whole, _POINT_NS * n * G)
        return slab, start - 1, width, whole
    rows_whole(0, 1)
    zs, ze = int(start[0]) - zone, int(start[0]) + zone
    fine_lo, fine_hi = zs - 5, ze + nL + 6
    if start[0] < 0 or fine_lo < 0 or fine_hi >= G:  # the zone runs off the samples
        _over_draws(n - 1, lambda lo, hi: rows_whole(lo + 1, hi + 1), _POINT_NS * (n - 1) * G)
        return slab, start - 1, width, whole
    l0 = fine_lo % step
    taken = np.zeros(G, bool)
    taken[l0::step] = True
    taken[fine_lo : fine_hi + 1] = True
    cols = np.flatnonzero(taken)

    _over_draws(n - 1, lambda lo, hi: rows(lo + 1, hi + 1, cols, zs, ze, l0), _POINT_NS * (n - 1) * len(cols))
    return slab, start - 1, width, whole


#: Cost of one sample of :func:`window_samples` (ns, the 2-core machine): the four-bar's and
#: the dyad's closing triangles and the angle, with the zone's test and the best starts,
#: 30–68 ns (a whole call over the sampled columns of 256 draws, one thread, on each of the
#: eight requests' first answer; RPR the cheaper) against the full kernel's ~85.
_POINT_NS = 50
#: Estimated work (ns) below which a candidate's draws are sampled in the caller's thread,
#: whatever :func:`synth.parallel_rows.threads` says. A split's hand-off costs CPU time in both
#: threads (Python's share of the pool, a second dispatch of the kernel, cold caches):
#: 0.1–1 ms a candidate more than one thread (256 draws, their 0.5–2 ms sampling pass, the
#: 2-core machine shared), against the ≤ 5 ms a candidate must cost, and a wall time no
#: better (the other core busy). From 4 ms of work (1 024 draws and more) the hand-off is
#: within the noise of the CPU time (±5 % measured) and a free core can take half the work.
_SPLIT_NS = 4_000_000


def _over_draws(rows: int, work: Callable[[int, int], None], cost_ns: float) -> None:
    """:func:`synth.parallel_rows.over_rows` for batches of an estimated ``cost_ns`` (ns) from
    :data:`_SPLIT_NS` on; a smaller batch (a candidate's 256 draws) runs as one block in this
    thread, where it costs the least CPU time."""
    if cost_ns < _SPLIT_NS:
        work(0, rows)
    else:
        over_rows(rows, work, cost_ns)


def limits_clear(params: F64, rpr: np.ndarray, phi: F64, pin_eps: float) -> bool:
    """The test of :func:`synth.mechanism.tolerance.clear_of_limits` on its six-bars
    (``params``/``rpr``: :func:`synth.mechanism.sixbar.kernel_inputs` rows, the drawing first,
    then the drawing with each dimension moved by the whole tolerance) at the crank angles
    ``phi`` (rad, one turn, equally spaced): every four-bar's crank turns and it closes without
    a toggle, the drawing's output turns back (ψ ends within π of where it started), and at
    every sample the drawing's margin m from its output dyad's limit exceeds twice the sum of
    the moved six-bars' |Δm| plus the largest change of m between two samples. ``pin_eps``:
    the RPR's pin-on-pivot distance in units of the six-bar's size."""
    margin = np.empty((params.shape[0], len(phi)))
    args = (
        np.ascontiguousarray(params, dtype=float),
        np.ascontiguousarray(rpr, dtype=bool),
        np.cos(phi),
        np.sin(phi),
        float(pin_eps),
        margin,
    )
    return bool(_limits_clear(*args))


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _limits_clear(params, rpr, cosg, sing, pin_eps, margin):
    R, M = margin.shape
    turned, px, py = 0.0, 1.0, 0.0
    for i in range(R):
        p = params[i]
        a, b, c, d = p[0], p[1], p[2], p[3]
        br, u, v = p[4], p[5], p[6]
        dx, dy, rocker, rod = p[7], p[8], p[9], p[10]
        # the crank turns: the diagonal A–B0 sweeps [|d − a|, d + a] inside (|b − c|, b + c)
        if not (abs(b - c) < abs(d - a) and d + a < b + c and min(min(a, b), min(c, d)) > 0):
            return False
        size = max(max(max(a, b), max(c, d)), math.hypot(dx, dy))
        for j in range(M):
            cphi, sphi = cosg[j], sing[j]
            # closing_point's operations: the coupler's direction, and its toggle test
            rx, ry = d - a * cphi, -(a * sphi)
            r2 = rx * rx + ry * ry
            r = math.sqrt(r2)
            s12, d21 = b + c, c - b
            heron = (r + d21) * (s12 - r) * (r - d21) * (r + s12)
            if heron < 0 or r <= COINCIDENT_EPS * s12:
                return False
            root = math.sqrt(heron)
            inv_2r = 0.5 / (b * r)
            cb = (r2 - d21 * s12) * inv_2r
            sb = root * (br * inv_2r)
            if abs(r * sb) < TOGGLE_EPS * c:
                return False
            inv_r = 1.0 / r
            ct, st = (rx * cb - ry * sb) * inv_r, (rx * sb + ry * cb) * inv_r
            zx = a * cphi + (ct * u - st * v)
            zy = a * sphi + (ct * v + st * u)
            dist = math.hypot(dx - zx, dy - zy)
            if rpr[i]:
                margin[i, j] = dist - pin_eps * size
            else:
                margin[i, j] = min((rocker + rod) - dist, dist - abs(rocker - rod))
            if i == 0:  # the drawing's output turns back: ψ's steps summed over the turn
                ex, ey = _direction(params[0], rpr[0], cphi, sphi)
                if j > 0:
                    turned += math.atan2(ey * px - ex * py, ex * px + ey * py)
                px, py = ex, ey
    if abs(turned) >= math.pi:
        return False
    between = 0.0  # what the grid can miss: the largest change between two samples, round the turn
    for k in range(M):
        between = max(between, abs(margin[0, (k + 1) % M] - margin[0, k]))
    for j in range(M):
        spread = 0.0  # the linear bound of how far the tolerance moves the margin
        for i in range(1, R):
            spread += abs(margin[i, j] - margin[0, j])
        if not margin[0, j] > 2.0 * spread + between:
            return False
    return True


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


#: |tan| of an angle from a draw's reference direction below which its arctangent is the odd
#: series (terms to t¹⁵: the next, t¹⁷/17, is under 1e-26·|t| at 1/32).
_SERIES_TAN = 1.0 / 32.0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _direction(p, rpr, cphi, sphi):
    """The output's direction at crank angle φ (cos φ, sin φ) of the six-bar of parameter row
    ``p`` (:func:`synth.mechanism.sixbar.kernel_inputs`' columns), as an unnormalised vector
    (X, Y) with ψ = atan2(Y, X): the closed forms of
    :func:`synth.mechanism.sixbar_kernel.closing_point` for the four-bar's coupler angle and the
    RRR's rocker, without a status, placeholders or the rates. Only for a six-bar that
    assembles at φ (the draws of :func:`synth.mechanism.tolerance.clear_of_limits`).

    Both loops are circles of radii l₁ and l₂ about the two ends of R: the first link's
    direction is (R(r² − (l₂ − l₁)(l₁ + l₂)) ± iR·√H)/(2l₁r²) with Heron's
    H = (r² − (l₂ − l₁)²)((l₁ + l₂)² − r²), r = |R|; the second's is (l₁e₁ − R)/l₂. The coupler
    needs its unit direction (one division); ψ needs no scale at all, so the RRR's rocker is
    2r²(l₁e₁ − R) and the RPR's slot P − D."""
    a, b, c, d, br, u, v = p[0], p[1], p[2], p[3], p[4], p[5], p[6]
    rx, ry = d - a * cphi, -(a * sphi)
    r2 = rx * rx + ry * ry
    d21, s12 = c - b, b + c
    near = r2 - d21 * s12
    root = math.sqrt(max((r2 - d21 * d21) * (s12 * s12 - r2), 0.0)) * br
    w = 1.0 / (2.0 * b * r2)
    ct = (rx * near - ry * root) * w
    st = (rx * root + ry * near) * w
    zx = a * cphi + (ct * u - st * v)
    zy = a * sphi + (ct * v + st * u)
    if rpr:
        return zx - p[7], zy - p[8]
    rx, ry = p[7] - zx, p[8] - zy
    r2 = rx * rx + ry * ry
    d21, s12 = p[9] - p[10], p[10] + p[9]
    root = math.sqrt(max((r2 - d21 * d21) * (s12 * s12 - r2), 0.0)) * p[11]
    far = r2 + d21 * s12
    return -(rx * far) - ry * root, -(ry * far) + rx * root


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _sample_row(params, rpr, cosg, sing, i, ref, cols, count, slab):
    """ψ (rad) of draw ``i`` at the ``count`` grid columns ``cols[:count]`` (increasing) into
    row i of ``slab``: ψ at column ``ref`` (the dwell middle) plus the angle from that direction,
    each on the 2π branch nearest the previous column's. A column's value depends on no other
    column but through that branch, so a draw sampled at some columns or at all of them has
    the same ψ at each."""
    p = params[i]
    kind = rpr[i]
    X, Y = _direction(p, kind, cosg[ref], sing[ref])
    norm = math.hypot(X, Y)
    cr, sr = X / norm, Y / norm
    base = math.atan2(sr, cr)
    prev = 0.0
    for q in range(count):
        j = cols[q]
        X, Y = _direction(p, kind, cosg[j], sing[j])
        x, y = X * cr + Y * sr, Y * cr - X * sr
        # near the reference (the dwell) the arctangent's odd series (a division and seven
        # multiply-adds) instead of the library's atan2 (~35 ns)
        if x > 0.0 and abs(y) <= _SERIES_TAN * x:
            t = y / x
            tt = t * t
            series = -1.0 / 15.0
            series = 1.0 / 13.0 + tt * series
            series = -1.0 / 11.0 + tt * series
            series = 1.0 / 9.0 + tt * series
            series = -1.0 / 7.0 + tt * series
            series = 1.0 / 5.0 + tt * series
            series = -1.0 / 3.0 + tt * series
            rel = t + t * (tt * series)
        else:
            rel = math.atan2(y, x)
        if q > 0:
            if rel - prev > math.pi:
                rel -= 2.0 * math.pi
            elif rel - prev < -math.pi:
                rel += 2.0 * math.pi
        prev = rel
        slab[i, j] = base + rel


@numba.njit(cache=True, nogil=True)
def _best_start(slab, i, first, last, nL, top, bottom):
    """The start column in [first, last] of row i's window of nL + 1 samples with the least
    range (the first such), and that range; (−1, inf) for an empty interval. Every window
    holds column ``last`` when last − first ≤ nL: the extremes of [s, last] (a suffix) and of
    [last, s + nL] (a prefix) make each window's in one pass (``top``/``bottom``: scratch)."""
    if last < first:
        return -1, math.inf
    best, best_range = -1, math.inf
    if last - first <= nL:
        hi, lo = -math.inf, math.inf
        for s in range(last, first - 1, -1):
            hi, lo = max(hi, slab[i, s]), min(lo, slab[i, s])
            top[s - first], bottom[s - first] = hi, lo
        hi, lo = slab[i, last], slab[i, last]
        for s in range(first, last + 1):
            if s > first:
                hi, lo = max(hi, slab[i, s + nL]), min(lo, slab[i, s + nL])
            else:
                for col in range(last, s + nL + 1):
                    hi, lo = max(hi, slab[i, col]), min(lo, slab[i, col])
            width = max(hi, top[s - first]) - min(lo, bottom[s - first])
            if width < best_range:
                best, best_range = s, width
        return best, best_range
    for s in range(first, last + 1):  # starts farther apart than a window: each read whole
        hi, lo = slab[i, s], slab[i, s]
        for col in range(s + 1, s + nL + 1):
            hi, lo = max(hi, slab[i, col]), min(lo, slab[i, col])
        if hi - lo < best_range:
            best, best_range = s, hi - lo
    return best, best_range


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _sample_rows(params, rpr, cosg, sing, ref, first, last, nL, cols, zs, ze, l0, step, slab, start, width, whole):
    """Rows of :func:`window_samples` sampled at ``cols`` (every column of the fine stretch and
    every ``step``-th, from ``l0``, elsewhere), their best start in the zone [zs, ze]; a row
    whose starts outside the zone are not all shown worse by the lattice is sampled whole
    (``whole[i]`` set) and its best start taken among all. With zs > ze, every row is sampled
    whole."""
    n, G = slab.shape
    every = np.arange(G)
    top, bottom = np.empty(G), np.empty(G)
    lattice = (G - 1 - l0) // step + 1  # columns l0, l0 + step, …
    held = (nL + 1) // step  # lattice samples in a window from the first at or after its start
    for i in range(n):
        if zs > ze:
            whole[i] = True
            _sample_row(params, rpr, cosg, sing, i, ref[i], every, G, slab)
            start[i], width[i] = _best_start(slab, i, first[i], last[i], nL, top, bottom)
            continue
        _sample_row(params, rpr, cosg, sing, i, ref[i], cols, cols.shape[0], slab)
        s, best = _best_start(slab, i, max(zs, first[i]), min(ze, last[i]), nL, top, bottom)
        redo = not (best < math.inf) or held < 1
        seen, seen_range = -1, 0.0
        x = first[i]
        while not redo and x <= last[i]:
            if zs <= x <= ze:  # the zone's own starts are compared one by one
                x = ze + 1
                continue
            at = (x - l0 + step - 1) // step
            if at > lattice - held:
                redo = True
                break
            if at != seen:
                hi, lo = -math.inf, math.inf
                for k in range(at, at + held):
                    col = l0 + k * step
                    hi, lo = max(hi, slab[i, col]), min(lo, slab[i, col])
                seen, seen_range = at, hi - lo
            if not seen_range > best:
                redo = True
            x += 1
        if redo:
            whole[i] = True
            _sample_row(params, rpr, cosg, sing, i, ref[i], every, G, slab)
            s, best = _best_start(slab, i, first[i], last[i], nL, top, bottom)
        start[i], width[i] = s, best
