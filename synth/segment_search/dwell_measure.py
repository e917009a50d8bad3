"""A candidate's dwell interval, grown on its exact path with minimum-zone fits (compiled).

The measurement stage of the segment search (:mod:`synth.segment_search.segments`, stage 3). A candidate is a
coupler point ``uv`` of a linkage, its osculating line or circle, a centre sample on the fine
crank grid and a half-window of fine samples; the path is sampled over the window,
z = A(φ) + e^{iθ(φ)}·uv (docs/curvature.md §3). At each tolerance level ε (half-width of the
band, crank lengths), the widest first, each level starting from the previous level's fit:

1. the **run**: the window samples within ε of the current geometry contiguous with the centre;
2. up to ``tries`` times: fit the minimum-zone geometry (:func:`synth.segment_search.minimum_zone_kernel.fit_row`)
   to ``spread`` samples over the run widened by ``ext`` on each side (the target); accept it
   when its peak deviation over the target (:func:`synth.segment_search.minimum_zone_kernel.window_peak`) is inside
   the band by ``margin``, and take its run; then widen by what the band's growth law predicts
   — a minimum-zone band over a stretch of length L grows like L⁴ (four-point contact), so
   L·(ε/h)^¼ just fits (times ``safety``).

A candidate with no run at a level keeps its geometry. Each candidate is measured on its own:
its result does not depend on which candidates share its batch (the numpy form this replaces
stopped every row's tries when no row of the batch could still grow).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from synth.segment_search.minimum_zone_kernel import deviation_at, fit_row, window_peak

__all__ = ["measure_dwells"]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _run(absdev, band, centre, size, z, kind, point, direction, radius, have_lo, have_hi):
    """[lo, hi] of the samples with |deviation| ≤ ``band`` from the geometry (``point``,
    ``direction``, ``radius``) contiguous with ``centre`` (hi < lo, namely [centre + 1, centre],
    when the centre itself is outside). ``absdev`` holds the deviations of the samples
    ``have_lo``..``have_hi`` already (none when ``have_lo`` > ``have_hi``); the others are
    worked out as the run reaches them: a run is a fraction of its window, and the deviation
    over the whole window was most of the measurement's time."""
    if have_lo > have_hi:
        have_lo, have_hi = centre + 1, centre
    while have_lo > centre:
        have_lo -= 1
        absdev[have_lo] = abs(deviation_at(z[have_lo], kind, point, direction, radius))
    while have_hi < centre:
        have_hi += 1
        absdev[have_hi] = abs(deviation_at(z[have_hi], kind, point, direction, radius))
    if not absdev[centre] <= band:
        return centre + 1, centre
    lo = centre
    while lo > 0:
        if lo - 1 < have_lo:
            have_lo = lo - 1
            absdev[have_lo] = abs(deviation_at(z[have_lo], kind, point, direction, radius))
        if not absdev[lo - 1] <= band:
            break
        lo -= 1
    hi = centre
    while hi < size - 1:
        if hi + 1 > have_hi:
            have_hi = hi + 1
            absdev[have_hi] = abs(deviation_at(z[have_hi], kind, point, direction, radius))
        if not absdev[hi + 1] <= band:
            break
        hi += 1
    return lo, hi


@numba.njit(cache=True, nogil=True, error_model="numpy")
def measure_dwells(
    A, E, link, centre, uv, kind, width, point, direction, radius, levels, tries, iterations, spread, margin, safety
):
    """Measure candidates at ``levels`` (band half-widths, crank lengths, in measuring order).

    ``A`` (mf,): the crank pin over the fine grid; ``E`` (N, mf): e^{iθ} of each linkage;
    per candidate: ``link`` (its row of ``E``), ``centre`` (fine sample of its generating
    angle), ``uv``, ``kind`` (a ``SegmentKind`` code), ``width`` (half-window, fine samples),
    and its osculating ``point``, unit ``direction`` (lines) and ``radius`` (arcs). ``spread``:
    the fit's sample positions over its target, from 0 to 1.

    Returns, per (candidate, level): the run [lo, hi] in window samples (0 … 2·width; hi < lo:
    no dwell), whether it reached the window's edge, and the fitted point, direction, radius.

    Each level starts from the previous one's fit, so levels go from the narrowest up: a wider
    band's minimum-zone geometry may pass up to its ε off the centre (on a symmetric quartic
    stretch the centre is one of its extremes), outside a narrower band.
    """
    n, nlev = link.size, levels.size
    mf = A.size
    lo_out = np.zeros((n, nlev), np.int64)
    hi_out = np.zeros((n, nlev), np.int64)
    truncated = np.zeros((n, nlev), np.bool_)
    p_out = np.zeros((n, nlev), np.complex128)
    d_out = np.ones((n, nlev), np.complex128)
    r_out = np.zeros((n, nlev))
    longest = 2 * width.max() + 1 if n else 1
    z = np.empty(longest, np.complex128)
    dev = np.empty(longest)
    trial = np.empty(longest)
    zs = np.empty(spread.size, np.complex128)
    work = np.empty((6, spread.size))
    for i in range(n):
        w = width[i]
        size = 2 * w + 1
        k = kind[i]
        for j in range(size):
            idx = (centre[i] + j - w) % mf
            z[j] = A[idx] + E[link[i], idx] * uv[i]
        p, d, r = point[i], direction[i], radius[i]
        for level in range(nlev):
            eps = levels[level]
            lo, hi = _run(dev, eps, w, size, z, k, p, d, r, 1, 0)
            ext = max((hi - lo + 1) // 4, 1)
            for _ in range(tries):
                if hi < lo:
                    break  # no run: nothing to grow from, the geometry stays
                t_lo = min(max(lo - ext, 0), size - 1)
                t_hi = min(max(hi + ext, 0), size - 1)
                for q in range(spread.size):
                    zs[q] = z[t_lo + int(np.rint(spread[q] * (t_hi - t_lo)))]
                p2, d2, r2 = fit_row(zs, k, p, d, r, iterations, work)
                for j in range(t_lo, t_hi + 1):  # what the peak reads; the run reads on as it needs
                    trial[j] = abs(deviation_at(z[j], k, p2, d2, r2))
                h = window_peak(trial, t_lo, t_hi)
                ok = h <= eps * (1 - margin)
                if ok:
                    p, d, r = p2, d2, r2
                    lo, hi = _run(trial, eps, w, size, z, k, p, d, r, t_lo, t_hi)
                target = (t_hi - t_lo + 1) * (eps / max(h, 1e-300)) ** 0.25 * safety
                # capped at the window before it becomes an integer (beyond it the target is
                # clipped anyway): an exact fit (h = 0) predicts a stretch of ~1e74 samples;
                # a fit that failed (h NaN) predicts nothing
                grow = min((target - (hi - lo + 1)) / 2, size) if math.isfinite(target) else 0.0
                ext = max(math.floor(grow), 1 if ok else 0)
            lo_out[i, level], hi_out[i, level] = lo, hi
            truncated[i, level] = lo == 0 or hi == size - 1
            p_out[i, level], d_out[i, level], r_out[i, level] = p, d, r
    return lo_out, hi_out, truncated, p_out, d_out, r_out
