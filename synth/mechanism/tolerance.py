"""How a six-bar's rest degrades under manufacturing tolerance: the output deviation over its
dwell window when every link length and every fixed-pivot coordinate is off by up to ±t.

A six-bar as made differs from the one drawn: each link length (crank a, coupler b, rocker c,
the coupler pin's place u, v on the coupler plate, RRR rocker L and rod ρ) and each coordinate
of the fixed pivots A0, B0 and D is off by some δ ∈ [−t, t]. :func:`deviation_draws` makes
``draws`` such six-bars (independent uniform δ, one seeded generator: the same draws for every
candidate, so two candidates are compared on the same workshop), simulates them exactly as one
batch (:func:`synth.mechanism.sixbar.simulate`, the compiled kernel) and measures on each the output
deviation the nominal figure measures (:func:`synth.mechanism.output_range.output_deviation`: the
smallest peak-to-peak of ψ over a window of the requested dwell length containing the dwell's
middle, refined on the exact path). :func:`toleranced_deviation` is their 95th percentile.

Why a percentile of random draws and not the worst corner: an RRR six-bar has 13 toleranced
dimensions (an RPR 11), so 2¹³ = 8 192 corners — thirty times the draws — and the deviation,
a peak-to-peak of a nonlinear path over a window that moves with the design, is not monotone
in the dimensions, so the worst case need not sit on a corner at all. Real parts scatter
inside their tolerance; the 95th percentile of 256 draws is what 19 in 20 assemblies stay
within, stable to a few per cent between seeds.

A moved A0 or B0 turns the ground line by β = arg(B0′ − A0′): the draw is simulated in its own
frame (A0′ at the origin, B0′ on +x, D′ rotated by −β), where the crank angle of the nominal
dwell's middle is φ − β; ψ's offset by β does not change a peak-to-peak. A draw that cannot
assemble somewhere on the turn (or revolves) counts as infinitely bad; when more than 5 % of
the draws do, the toleranced deviation is None ("does not survive this tolerance").

Only the dwell windows are simulated when no draw can meet a limit of its linkage
(:func:`clear_of_limits`: the four-bar's crank condition exactly on each draw, the output
dyad's distance from its limit against a linear bound of how far the tolerance moves it):
then every draw assembles over the whole turn and its output rocks as the drawing's does, and
ψ is needed only where a window of the requested length containing the dwell middle can lie,
sampled every 2° and refined on the exact path (:func:`_window_deviations`); for the
percentile alone, only the draws whose bounds leave them able to be its order statistics are
refined (the same number as refining all). The bounds come from the samples: first the
window's sample extremes; where those leave more than :data:`CLOSER_BOUNDS` draws open (a
six-bar whose draws spread less than a grid step moves ψ), the refinement's two stages
followed on a cubic interpolation of the samples, whose error a fourth difference bounds
(:func:`_refined_bounds`: ~1e-4° wide, a few draws left to refine). That is ~70 exact
points a draw for a 60° dwell, plus 36 for a draw refined, instead of a 720-sample turn plus
~100 refinement points.
Measured against the whole-turn path on the answers of eight requests on ``standard`` (80
six-bars, docs/tolerance.md), the 95th percentile moves by at most 0.0006° (0.6 %), well
inside its spread between seeds.
Otherwise (a draw may not assemble) every draw is simulated over the whole turn on the query's
720-sample grid, as the nominal figure is.

Lengths are in the six-bar's unit (a :class:`~synth.query.candidates.Candidate`'s six-bar is in the
user's unit, so ``t`` is too); angles in radians. Pure: no I/O.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from synth.kinds import OutputKind
from synth.mechanism.output_range import output_deviation
from synth.mechanism.sixbar import (
    PIN_ON_PIVOT_EPS,
    ExactOutput,
    SixBar,
    SixBars,
    crank_grid,
    kernel_inputs,
    simulate,
)
from synth.types import F64

__all__ = [
    "DRAWS",
    "PERCENTILE",
    "SEED",
    "clear_of_limits",
    "crank_turns",
    "deciding_draws",
    "deviation_draws",
    "perturbed",
    "toleranced_deviation",
    "unit_draws",
]

#: Random six-bars drawn per candidate.
DRAWS = 256
#: The percentile of the draws' deviations reported (%).
PERCENTILE = 95.0
#: Seed of the draws: the same workshop for every candidate and every run.
SEED = 44_2026
#: Toleranced dimensions, in the columns of :func:`unit_draws`: a, b, c, u, v, L, ρ, then
#: A0 x, A0 y, B0 x, B0 y, D x, D y (an RPR ignores L and ρ).
DIMENSIONS = 13
#: Crank samples of the whole-turn simulation of each draw (the query's grid, the nominal
#: figure's): the path taken when a draw may meet a limit of its output dyad.
SAMPLES = 720
#: Crank samples per turn of the grid the draws' dwell windows are sampled on (2°): between
#: samples only the window's inside is read, where ψ is nearly still (the ends are refined).
WINDOW_SAMPLES = 180
#: Exact points of the first and the second refinement stage of a window's placement.
REFINE_POINTS = 8
FINE_POINTS = 8
#: Crank samples of the test that no draw meets a limit (:func:`clear_of_limits`).
LIMIT_SAMPLES = 90
#: How many times the larger nearby fourth difference of the samples the bounds allow for
#: ψ⁽⁴⁾h⁴ between samples (:func:`_cubic`): ψ is smooth and slowly varying wherever
#: :func:`clear_of_limits` holds.
SAFETY = 4.0
#: Draws left undecided by the grid's bounds above which the interpolated bounds
#: (:func:`_refined_bounds`, ~40 array operations whatever the count) cost less than refining
#: them (~4 µs a draw).
CLOSER_BOUNDS = 96


@functools.lru_cache(maxsize=8)
def unit_draws(draws: int = DRAWS, seed: int = SEED) -> F64:
    """``(draws, 13)`` independent uniform offsets in [−1, 1] (columns as :data:`DIMENSIONS`),
    the same for a given ``seed`` (made once per process: read-only)."""
    unit = np.random.default_rng(seed).uniform(-1.0, 1.0, (int(draws), DIMENSIONS))
    unit.flags.writeable = False
    return unit


def perturbed(sixbar: SixBar, tolerance: float, unit: F64) -> tuple[SixBars, F64]:
    """The draws of ``sixbar`` made with offsets ``tolerance · unit`` (``unit`` from
    :func:`unit_draws`), each in its own frame, and the turn β of each draw's ground line (rad):
    a crank angle φ of the drawing is φ − β in the draw's frame."""
    dev = float(tolerance) * np.asarray(unit, dtype=float)
    n = dev.shape[0]
    dy = sixbar.dyad
    a0 = dev[:, 7] + 1j * dev[:, 8]
    ground = (sixbar.d + dev[:, 9] + 1j * dev[:, 10]) - a0
    d = np.abs(ground)
    turn = np.conj(ground) / d  # e^{−iβ}
    pivot = (dy.pivot + dev[:, 11] + 1j * dev[:, 12] - a0) * turn
    rrr = dy.kind is OutputKind.RRR
    ones = np.ones(n)
    batch = SixBars(
        sixbar.a + dev[:, 0],
        sixbar.b + dev[:, 1],
        sixbar.c + dev[:, 2],
        d,
        sixbar.branch * ones,
        sixbar.u + dev[:, 3],
        sixbar.v + dev[:, 4],
        np.full(n, not rrr),
        pivot,
        (dy.rocker + dev[:, 5]) if rrr else 0.0 * ones,
        (dy.rod + dev[:, 6]) if rrr else 0.0 * ones,
        dy.branch * ones,
    )
    return batch, np.angle(ground)


def deviation_draws(
    sixbar: SixBar,
    tolerance: float,
    centres: Sequence[float],
    length: float,
    *,
    draws: int = DRAWS,
    seed: int = SEED,
    whole_turn: bool = False,
) -> F64:
    """The output deviation (rad) of each of ``draws`` six-bars made within ±``tolerance`` of
    ``sixbar``: per draw the largest over the dwells of the smallest peak-to-peak of ψ over a
    window of ``length`` (rad) containing the dwell middle ``centres[k]`` (crank angles of the
    drawing, rad); +inf for a draw that does not assemble over the whole turn or revolves.

    Parameters
    ----------
    sixbar : SixBar
        The six-bar as drawn (any length unit).
    tolerance : float
        Largest offset of each dimension (the six-bar's unit, ≥ 0).
    centres : sequence of float
        The middles of the nominal dwells (rad).
    length : float
        Requested dwell length (rad).
    draws, seed : int
        :func:`unit_draws`' arguments.
    whole_turn : bool
        Simulate every draw over the whole turn even where :func:`clear_of_limits` allows the
        dwell windows alone (the reference the windows are tested against).
    """
    return _draws(sixbar, tolerance, centres, length, draws, seed, whole_turn, None)


def _draws(
    sixbar: SixBar,
    tolerance: float,
    centres: Sequence[float],
    length: float,
    draws: int,
    seed: int,
    whole_turn: bool,
    percentile: float | None,
) -> F64:
    """:func:`deviation_draws`; with ``percentile``, good only for that percentile (the
    dwell-window path then refines only the draws that decide it, :func:`_window_deviations`)."""
    if not (math.isfinite(tolerance) and tolerance >= 0):
        raise ValueError(f"tolerance must be a finite length >= 0, got {tolerance!r}")
    batch, beta = perturbed(sixbar, tolerance, unit_draws(draws, seed))
    rrr = not batch.rpr[0]
    lengths = [batch.a, batch.b, batch.c, batch.d] + ([batch.rocker, batch.rod] if rrr else [])
    made = np.all(np.stack(lengths) > 0, axis=0)  # a tolerance as large as a link: no such part
    if not whole_turn and made.all() and crank_turns(batch).all() and clear_of_limits(sixbar, tolerance):
        return _window_deviations(batch, beta, centres, length, percentile=percentile)
    if not made.all():  # those draws are simulated as placeholders (crank-sized links) and flagged
        fix = lambda x: np.where(made, x, 1.0)  # noqa: E731
        batch = SixBars(
            fix(batch.a),
            fix(batch.b),
            fix(batch.c),
            fix(batch.d),
            batch.branch,
            batch.u,
            batch.v,
            batch.rpr,
            batch.pivot,
            fix(batch.rocker) if rrr else batch.rocker,
            fix(batch.rod) if rrr else batch.rod,
            batch.dyad_branch,
        )
    phi = crank_grid(SAMPLES)
    motion = simulate(batch, phi, order=1)
    psi, dpsi1 = motion.psi, motion.dpsi[0]
    ok = made & np.all(motion.status == 0, axis=1) & (np.abs(psi[:, -1] - psi[:, 0]) < math.pi)
    worst = np.zeros(len(batch))
    for centre in centres:
        # the window's middle in the draw's frame, back in [φ₀, φ₀ + 2π)
        c = np.mod(float(centre) - beta - phi[0], 2 * math.pi) + phi[0]
        dev, _ = output_deviation(phi, psi, c, length, psi_at=ExactOutput(batch), dpsi1=dpsi1)
        worst = np.maximum(worst, dev)
    return np.where(ok, worst, math.inf)


def toleranced_deviation(
    sixbar: SixBar, tolerance: float, centres: Sequence[float], length: float, *, draws: int = DRAWS, seed: int = SEED
) -> float | None:
    """The :data:`PERCENTILE`-th percentile (rad) of :func:`deviation_draws` (numpy's linear
    interpolation between order statistics), or None where it falls on draws that do not
    assemble (more than 5 % of them). The same number, refining only the draws that can
    decide it."""
    dev = _draws(sixbar, tolerance, centres, length, draws, seed, False, PERCENTILE)
    value = float(np.percentile(dev, PERCENTILE)) if np.isfinite(dev).all() else _percentile_inf(dev)
    return value if math.isfinite(value) else None


def _percentile_inf(dev: F64) -> float:
    """The percentile with +inf draws sorted last (numpy's interpolation would give nan at an
    inf − inf); +inf if it reaches them."""
    s = np.sort(dev)
    pos = PERCENTILE / 100.0 * (len(s) - 1)
    lo, hi = int(math.floor(pos)), int(math.ceil(pos))
    if not math.isfinite(s[hi]):
        return math.inf
    return float(s[lo] + (s[hi] - s[lo]) * (pos - lo))


def clear_of_limits(sixbar: SixBar, tolerance: float) -> bool:
    """Whether no six-bar within ±``tolerance`` of ``sixbar`` meets a limit of its output dyad
    anywhere on the turn, by a margin: then every draw assembles over the whole turn and turns
    the output as often as the drawing (zero times: the turn count cannot jump without a
    limit being crossed), and only the dwell windows need simulating.

    The margin m(φ) is the distance (length) of the output dyad from its limit: an RRR's
    rod-to-pivot distance r = |D − P| inside (|L − ρ|, L + ρ), an RPR's pin off its slot's
    pivot. Perturbed one dimension at a time by the whole tolerance, m moves by Δₖ(φ); a draw
    moves it by at most Σₖ|Δₖ(φ)| to first order. The test asks m(φ) > 2·Σₖ|Δₖ(φ)| (room for
    the second order) plus the largest change of m between two samples (what the grid can
    miss), at every sample of a ``LIMIT_SAMPLES`` grid. The four-bar's limits are checked
    exactly on each draw (:func:`crank_turns`)."""
    unit = np.vstack([np.zeros(DIMENSIONS), np.eye(DIMENSIONS)])
    batch, _ = perturbed(sixbar, tolerance, unit)
    if not crank_turns(batch).all():
        return False
    from synth.mechanism.sixbar_kernel import sixbar_positions  # numba: imported on first use

    # the kernel without simulate's motion records (~80 µs of this test's ~500): the coupler
    # point z, ψ and the statuses are all it reads
    params, rpr = kernel_inputs(batch)
    points, angles, _, _, status = sixbar_positions(params, rpr, crank_grid(LIMIT_SAMPLES)[None, :], PIN_ON_PIVOT_EPS)
    if np.any(status != 0) or abs(angles[0, 0, -1] - angles[0, 0, 0]) >= math.pi:
        return False
    r = np.abs(batch.pivot[:, None] - points[1])
    if batch.rpr[0]:
        size = np.maximum.reduce([batch.a, batch.b, batch.c, batch.d, np.abs(batch.pivot)])
        margin = r - PIN_ON_PIVOT_EPS * size[:, None]
    else:
        reach = (batch.rocker + batch.rod)[:, None]
        fold = np.abs(batch.rocker - batch.rod)[:, None]
        margin = np.minimum(reach - r, r - fold)
    spread = np.sum(np.abs(margin[1:] - margin[0]), axis=0)
    between = float(np.max(np.abs(np.diff(margin[0], append=margin[0, :1]))))
    return bool(np.all(margin[0] > 2.0 * spread + between))


def crank_turns(batch: SixBars) -> NDArray[np.bool_]:
    """Whether each four-bar's crank turns fully: the diagonal from the crank pin to B0 sweeps
    [|d − a|, d + a], and the coupler and rocker must close a triangle on every length of it,
    |b − c| < |d − a| and d + a < b + c (strict: at equality the linkage toggles)."""
    a, b, c, d = batch.a, batch.b, batch.c, batch.d
    return (np.abs(b - c) < np.abs(d - a)) & (d + a < b + c) & (np.minimum.reduce([a, b, c, d]) > 0)


def _window_deviations(
    batch: SixBars, beta: F64, centres: Sequence[float], length: float, *, percentile: float | None = None
) -> F64:
    """:func:`deviation_draws` of draws that all assemble (:func:`clear_of_limits`), simulated
    only where a window of ``length`` containing a dwell middle can lie.

    As :func:`output_deviation` does it, on a ``WINDOW_SAMPLES`` grid instead of the query's:
    in each draw's frame the window's start runs over [c − L, c] (c the dwell middle there),
    the best sample start is found from sliding extremes of the samples, then refined on the
    exact path in two stages of ``REFINE_POINTS`` and ``FINE_POINTS`` points
    (:func:`synth.mechanism.dwell_ends_kernel.refine_deviation_windows`). ψ is sampled from
    c − L to c + L only, on one grid the draws share.

    With ``percentile`` (%), only the draws that can decide that percentile are refined
    (:func:`deciding_draws`, on the samples' bounds, then on :func:`_refined_bounds` where
    those leave more than :data:`CLOSER_BOUNDS` open); the others get a bound on their side of
    it, so the percentile (numpy's linear interpolation) is the one of every draw refined, and
    the array is good for nothing else."""
    from synth.mechanism.dwell_ends_kernel import refine_deviation_windows  # numba: imported on first use
    from synth.mechanism.sample_ranges import sliding_extremes  # numba: imported on first use
    from synth.mechanism.sixbar_kernel import output_angles  # numba: imported on first use

    n = len(batch)
    params, rpr = kernel_inputs(batch)
    h = 2 * math.pi / WINDOW_SAMPLES
    nL = int(math.floor(length / h + 1e-9))  # samples i..i+nL lie in [φ_i, φ_i + L]
    rows = np.arange(n)
    upper, lower = np.zeros(n), np.zeros(n)
    windows = []
    for centre in centres:
        c = np.mod(float(centre) - beta, 2 * math.pi)  # the dwell middle in each draw's frame
        i_lo = np.ceil((c - length) / h - 1e-9).astype(np.int64)
        span = np.floor(c / h + 1e-9).astype(np.int64) - i_lo + 1
        J = int(span.max())
        W = J + nL + 4
        # the draws' frames turn by |β| ≲ t/d: their slabs share one grid (its sines and cosines
        # made once), each read from its own first sample i_lo − 1
        first = int(i_lo.min()) - 1
        shared = (first + np.arange(int(i_lo.max()) - first - 1 + W)) * h
        psi = output_angles(params, rpr, shared[None, :], PIN_ON_PIVOT_EPS)
        slab = np.ascontiguousarray(psi[rows[:, None], (i_lo - 1 - first)[:, None] + np.arange(W)[None, :]])
        # the window from sample i_lo + j (slab offset 1 + j) holds nL + 1 samples
        top, bottom = sliding_extremes(slab, 1, J, np.full(n, nL + 1))
        grid_range = np.where(np.arange(J)[None, :] < span[:, None], top - bottom, math.inf)
        jbest = np.argmin(grid_range, axis=1)
        dev = grid_range[rows, jbest]
        # The refinement's figure lies within the window's grid extremes: above the range of
        # the samples every refined window holds (one step after the grid start to one step
        # before its end), below that of the samples over [s, s + L] from the grid start s
        # (one more sample where L is not a whole number of steps), widened by how far ψ can
        # rise between two samples (an eighth of the largest second difference there).
        reach = nL + 1 + (nL * h < length - 1e-12)
        held = slab.ravel().take((W * rows + jbest + 1)[:, None] + np.arange(reach)[None, :])
        bend = np.abs(np.diff(held, 2, axis=1)).max(axis=1, initial=0.0) / 8
        inner = held[:, 1 : max(nL, 1)]
        floor = inner.max(axis=1) - inner.min(axis=1) if nL >= 2 else np.zeros(n)
        upper = np.maximum(upper, held.max(axis=1) - held.min(axis=1) + 2 * bend)
        lower = np.maximum(lower, np.minimum(floor, dev))
        windows.append((slab, i_lo, jbest, c, dev))
    out = upper
    todo = rows
    if percentile is not None:
        need, out = deciding_draws(lower, upper, percentile)
        if need.sum() > CLOSER_BOUNDS:  # the grid's bounds decide too few: interpolate
            sub = np.flatnonzero(need)
            low, high = np.zeros(len(sub)), np.zeros(len(sub))
            for slab, i_lo, jbest, c, _ in windows:
                lo_c, hi_c = _refined_bounds(slab[sub], i_lo[sub], jbest[sub] + 1, nL, float(length), c[sub], h)
                low, high = np.maximum(low, lo_c), np.maximum(high, hi_c)
            lower[sub], upper[sub] = np.maximum(lower[sub], low), np.minimum(upper[sub], high)
            need, out = deciding_draws(lower, upper, percentile)
        todo = np.flatnonzero(need)
    worst = np.zeros(len(todo))
    for slab, i_lo, jbest, c, dev in windows:
        refined, _ = refine_deviation_windows(
            params,
            rpr,
            todo,
            slab[todo],
            i_lo[todo],
            jbest[todo] + 1,
            np.full(len(todo), nL),
            np.full(len(todo), float(length)),
            c[todo],
            dev[todo],
            (i_lo[todo] + jbest[todo]) * h,
            0.0,
            h,
            PIN_ON_PIVOT_EPS,
            REFINE_POINTS,
            FINE_POINTS,
        )
        worst = np.maximum(worst, refined)
    out[todo] = worst
    return out


def deciding_draws(lower: F64, upper: F64, percentile: float) -> tuple[NDArray[np.bool_], F64]:
    """Which draws, their exact figure known to lie in [lower, upper], can be one of the two
    order statistics numpy interpolates the ``percentile`` (%) between (positions ⌊p⌋ and
    ⌈p⌉, p = percentile/100·(n − 1)), and a stand-in for the others.

    The k-th order statistic lies between the k-th smallest lower bound and the k-th smallest
    upper bound: a draw whose upper bound is under the ⌊p⌋-th lower bound stays below both
    order statistics (its stand-in: its upper bound), one whose lower bound is over the ⌈p⌉-th
    upper bound stays above them (its stand-in: its lower bound). With the deciding draws'
    exact figures put in, the stand-ins' percentile is the exact figures' percentile."""
    n = len(lower)
    pos = percentile / 100.0 * (n - 1)
    lo_k, hi_k = math.floor(pos), math.ceil(pos)
    below = np.partition(lower, lo_k)[lo_k]
    above = np.partition(upper, hi_k)[hi_k]
    return (upper >= below) & (lower <= above), np.where(lower > above, lower, upper)


def _cubic(flat: F64, row_start: NDArray[np.int64], at: F64) -> F64:
    """ψ (rad) at fractional positions ``at`` ``(R, P)`` (or ``(1, P)``) along each row of
    the samples, given as ``flat`` (rows laid end to end, row r's column 0 at ``row_start[r]``,
    shape ``(R, 1)``): the cubic through the four nearest samples. Its error bound is
    :func:`_error_bound`'s."""
    whole = np.floor(at)
    t = at - whole
    a, b, c, d = t + 1, t, t - 1, t - 2  # t less each node m − 1 … m + 2: Lagrange's weights
    m = row_start + whole.astype(np.int64)
    ad, bc = a * d, b * c
    value = (bc * d) * (-1 / 6) * flat.take(m - 1, mode="clip") + (a * c * d) * 0.5 * flat.take(m, mode="clip")
    value += (ad * b) * (-0.5) * flat.take(m + 1, mode="clip")
    return value + (a * bc) * (1 / 6) * flat.take(m + 2, mode="clip")


def _error_bound(flat: F64, row_start: NDArray[np.int64], first: NDArray[np.int64]) -> F64:
    """A bound (rad, ``(R,)``) of :func:`_cubic`'s error at positions whose cells start at
    columns ``first[:, i]`` … ``first[:, i] + 3`` of each row (``(R, B)``: B such blocks).

    Notes
    -----
    The cubic through samples m − 1 … m + 2 at m + t (0 ≤ t ≤ 1) is off by
    ψ⁽⁴⁾(ξ) h⁴ (t + 1) t (t − 1) (t − 2) / 24, at most 9/16 · ψ⁽⁴⁾h⁴ / 24; ψ⁽⁴⁾h⁴ is taken as
    :data:`SAFETY` times the largest fourth difference of the samples centred at m − 1 … m + 2
    (the cubic's stencil and one more each side), plus 1e-13 rad for rounding."""
    y = flat.take(row_start[:, :, None] + first[:, :, None] - 3 + np.arange(10)[None, None, :], mode="clip")
    return SAFETY * (9 / 16) / 24 * np.abs(np.diff(y, 4)).max(axis=(1, 2)) + 1e-13


def _window_ranges(starts: F64, ends: F64, top: F64, bottom: F64) -> F64:
    """The refinement's range of each window of a stage ``(R, Q)``: window q holds the stage's
    starts q … Q − 1 (ψ ``starts``), its ends 0 … q (``ends``) and points between whose
    extremes are ``top``, ``bottom`` ``(R,)``."""
    n = starts.shape[0]
    both = np.concatenate([starts[:, ::-1], ends])  # suffixes of the starts as prefixes
    high, low = np.maximum.accumulate(both, axis=1), np.minimum.accumulate(both, axis=1)
    high = np.maximum(np.maximum(high[:n, ::-1], high[n:]), top[:, None])
    return high - np.minimum(np.minimum(low[:n, ::-1], low[n:]), bottom[:, None])


def _refined_bounds(
    slab: F64, i_lo: NDArray[np.int64], k: NDArray[np.int64], nL: int, length: float, c: F64, h: float
) -> tuple[F64, F64]:
    """Bounds (rad) of what :func:`~synth.mechanism.dwell_ends_kernel.refine_deviation_windows`
    returns for each row, from the samples alone: its two stages followed with ψ at the
    window ends interpolated (:func:`_cubic`) instead of computed.

    ``slab`` holds the refinement's samples (from i_lo − 1 on); ``k`` is
    the best grid start's slab offset, ``nL`` the samples per grid window, ``length`` the
    window (rad), ``c`` the dwell middle (rad), ``h`` the grid step (rad). Where the first
    stage's winner is not clear of the other starts by the interpolation's error, where the
    interpolation's stencils run off the slab (a best grid start at an end of the starts
    allowed) or where the grid alone places the window (``nL`` < 2), the row gets [0, inf):
    it must be refined.

    Notes
    -----
    The refinement measures a window from f as the range of ψ at the exact points of its stage
    inside the window and the samples between (not a continuous range), and keeps the least
    among the starts allowed in [c − L, c]. With every exact value within E of its
    interpolation (E the row's error bound), each such range, and so their least, is within
    2E of the same computed on the interpolations."""
    n, cols = slab.shape
    if nL < 2:
        return np.zeros(n), np.full(n, math.inf)
    rows = np.arange(n)
    flat = slab.ravel()  # read with mode="clip": a row whose stencils leave it is not used
    row_start = (cols * rows)[:, None]
    # in columns of the slab, the kernel's first start f₀ = grid start − h lies at p0 and its
    # window's end at p0 + L/h; the stages' starts lie within [p0 − 1/4, p0 + 9/4]
    p0 = (k - 1)[:, None]
    span = length / h
    e = _error_bound(flat, row_start, np.hstack([p0 - 1, p0 + math.floor(span - 0.25)]))
    on_slab = (p0[:, 0] >= 4) & (p0[:, 0] + math.floor(span - 0.25) + 6 < cols)
    q1 = REFINE_POINTS + 1
    # stage 1: REFINE_POINTS + 1 starts over the two steps around the grid start (the
    # kernel's own arithmetic for f, to allow the same starts)
    step = np.arange(q1)[None, :] / REFINE_POINTS
    f = (i_lo - 2 + k)[:, None] * h + 2 * h * step
    fv, gv = np.hsplit(_cubic(flat, row_start + p0, np.hstack([2 * step, 2 * step + span])), 2)
    # The samples between a window's exact points: the first stage's are slab offsets k + 2 …
    # k + nL − 1, the second's those strictly inside (f_best + d, f_best − d + L), from i0 ∈
    # [k, k + 2] to one in [k + nL − 2, k + nL + 1]; both hold the core k + 2 … k + nL − 2,
    # whose extremes are taken once, and a few of the edges.
    core = flat.take(row_start + p0 + 3 + np.arange(max(nL - 3, 0))[None, :], mode="clip")
    core_hi, core_lo = core.max(axis=1, initial=-math.inf), core.min(axis=1, initial=math.inf)
    edge_at = np.array([0, 1, nL - 1, nL, nL + 1])  # offsets from k
    edge = flat.take(row_start + p0 + 1 + edge_at[None, :], mode="clip")
    last_in = nL >= 3  # offset k + nL − 1 is the first stage's last sample
    r1 = _window_ranges(
        fv,
        gv,
        np.maximum(core_hi, edge[:, 2]) if last_in else core_hi,
        np.minimum(core_lo, edge[:, 2]) if last_in else core_lo,
    )
    r1 = np.where((f >= (c - length)[:, None] - 1e-12) & (f <= c[:, None] + 1e-12), r1, math.inf)
    j = np.argmin(r1, axis=1)
    fine = r1[rows, j]
    points = np.arange(q1)[None, :]
    runner_up = np.where(points == j[:, None], math.inf, r1).min(axis=1)
    clear = (fine + 4 * e < runner_up) & np.isfinite(fine) & on_slab
    if nL >= 4:
        # stage 2: FINE_POINTS + 1 starts within one first-stage step of the winner, each
        # window holding the samples strictly inside (f_best + d, f_best − d + L) and the
        # first stage's starts after the winner and ends before it
        f_best = f[rows, j]
        d = 2 * h / REFINE_POINTS
        t3 = -1.0 + np.arange(FINE_POINTS + 1) * (2.0 / FINE_POINTS)
        t3[FINE_POINTS] = 1.0
        f3 = f_best[:, None] + d * t3[None, :]
        i0 = np.floor((f_best + d) / h - (i_lo - 1)).astype(np.int64) + 1
        end = np.ceil((f_best - d + length) / h - (i_lo - 1)).astype(np.int64)  # one past the last
        at = (k[:, None] + edge_at[None, :] - i0[:, None] >= 0) & (k[:, None] + edge_at[None, :] < end[:, None])
        after, before = points > j[:, None], points < j[:, None]
        top = np.maximum(
            np.maximum(core_hi, np.where(at, edge, -math.inf).max(axis=1)),
            np.where(after, fv, np.where(before, gv, -math.inf)).max(axis=1),
        )
        bottom = np.minimum(
            np.minimum(core_lo, np.where(at, edge, math.inf).min(axis=1)),
            np.where(after, fv, np.where(before, gv, math.inf)).min(axis=1),
        )
        offset = 2 * step[:, j].T + (d / h) * t3[None, :]  # f3 − f₀, in steps
        psi3 = _cubic(flat, row_start + p0, np.hstack([offset, offset + span]))
        r3 = _window_ranges(*np.hsplit(psi3, 2), top, bottom)
        r3 = np.where((f3 >= (c - length)[:, None] - 1e-12) & (f3 <= c[:, None] + 1e-12), r3, math.inf)
        # the refinement returns the second stage's best where it is below the first's
        fine = np.minimum(fine, r3.min(axis=1))
    return np.where(clear, np.maximum(fine - 2 * e, 0.0), 0.0), np.where(clear, fine + 2 * e, math.inf)
