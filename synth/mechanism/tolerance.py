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
refined (the same number as refining all). The bounds come from the samples, in one compiled
pass (:func:`synth.mechanism.tolerance_kernel.window_bounds`): the window's sample extremes
(~0.02° wide), and the refinement's two stages followed on a cubic interpolation of the
samples, whose error a fourth difference bounds (~5e-5° wide); 2–5 draws are left to refine.
That is ~65 samples a draw for a 60° dwell (~105 for 135°, the draws sampled every 2° only
near the first draw's best window), plus 36 exact points for a draw refined, instead of a
720-sample turn plus ~100 refinement points. The samples are ψ alone, sampled, and the best
start found on them, in one compiled pass per draw
(:func:`synth.mechanism.tolerance_kernel.window_samples`: the two closing triangles and the
angle, ~35 ns a sample against the whole position kernel's ~85).
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
from synth.parallel_rows import over_rows
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
    "toleranced_deviations",
    "unit_draws",
]

#: Random six-bars drawn per candidate.
DRAWS = 256
#: The percentile of the draws' deviations reported (%).
PERCENTILE = 95.0
#: Seed of the draws: the same workshop for every candidate and every run.
SEED = 44_2026
#: Estimated cost (ns) of one six-bar's :func:`toleranced_deviation` at :data:`DRAWS` draws
#: (2–4.5 ms measured on the 2-core machine): :func:`toleranced_deviations` splits six-bars
#: over threads from two on.
SIXBAR_NS = 2_500_000
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
#: Grid steps either side of the first draw's best window start within which every draw's
#: best start is looked for on samples taken every step
#: (:func:`synth.mechanism.tolerance_kernel.window_samples`).
ZONE = 8
#: Grid steps between the samples taken elsewhere, which show a start there worse.
OUTSIDE_STEP = 4
#: How many times the larger nearby fourth difference of the samples the interpolated bounds
#: allow for ψ⁽⁴⁾h⁴ between samples (:mod:`synth.mechanism.tolerance_kernel`): ψ is smooth and
#: slowly varying wherever :func:`clear_of_limits` holds.
SAFETY = 4.0


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


def toleranced_deviations(
    sixbars: Sequence[SixBar],
    tolerance: float,
    centres: Sequence[Sequence[float]],
    length: float,
    *,
    draws: int = DRAWS,
    seed: int = SEED,
) -> list[float | None]:
    """:func:`toleranced_deviation` of each of ``sixbars`` (rad or None), ``centres[k]`` the
    dwell middles of ``sixbars[k]`` (rad): the same numbers, the six-bars split over threads
    (:func:`synth.parallel_rows.over_rows`) and each six-bar's draws on one.

    A candidate's 256 draws are too few to split with profit (the hand-off's CPU time is ~0.1–1
    ms against its 2–4.5 ms; :mod:`synth.mechanism.tolerance_kernel`), a query's candidates
    are not: one hand-off for the lot. On the 2-core machine, shared, two threads took 25–30 %
    off the wall time for ~10 % more CPU (docs/tolerance.md)."""
    if not (math.isfinite(tolerance) and tolerance >= 0):
        raise ValueError(f"tolerance must be a finite length >= 0, got {tolerance!r}")
    if len(centres) != len(sixbars):
        raise ValueError(f"centres: one sequence per six-bar ({len(sixbars)}), got {len(centres)}")
    out: list[float | None] = [None] * len(sixbars)

    def block(lo: int, hi: int) -> None:
        for k in range(lo, hi):  # each block writes its own entries only
            out[k] = toleranced_deviation(sixbars[k], tolerance, centres[k], length, draws=draws, seed=seed)

    over_rows(len(sixbars), block, SIXBAR_NS * len(sixbars) * (draws / DRAWS))
    return out


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
    from synth.mechanism.tolerance_kernel import limits_clear  # numba: imported on first use

    batch, _ = perturbed(sixbar, tolerance, np.vstack([np.zeros(DIMENSIONS), np.eye(DIMENSIONS)]))
    params, rpr = kernel_inputs(batch)
    return limits_clear(params, rpr, crank_grid(LIMIT_SAMPLES), PIN_ON_PIVOT_EPS)


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
    c − L to c + L only, on one grid the draws share, and every step only near the first
    draw's best window (:func:`synth.mechanism.tolerance_kernel.window_samples`).

    With ``percentile`` (%), only the draws that can decide that percentile are refined
    (:func:`deciding_draws`, on the bounds of
    :func:`synth.mechanism.tolerance_kernel.window_bounds`); the others get a bound on their side of
    it, so the percentile (numpy's linear interpolation) is the one of every draw refined, and
    the array is good for nothing else."""
    from synth.mechanism.dwell_ends_kernel import refine_deviation_windows  # numba: imported on first use
    from synth.mechanism.tolerance_kernel import window_bounds, window_samples  # numba: imported on first use

    n = len(batch)
    params, rpr = kernel_inputs(batch)
    h = 2 * math.pi / WINDOW_SAMPLES
    nL = int(math.floor(length / h + 1e-9))  # samples i..i+nL lie in [φ_i, φ_i + L]
    rows = np.arange(n)
    windows = []
    for centre in centres:
        c = np.mod(float(centre) - beta, 2 * math.pi)  # the dwell middle in each draw's frame
        i_lo = np.ceil((c - length) / h - 1e-9).astype(np.int64)
        span = np.floor(c / h + 1e-9).astype(np.int64) - i_lo + 1
        J = int(span.max())
        # the draws' frames turn by |β| ≲ t/d: their samples share one grid from sample
        # `first` on (its sines and cosines made once), and every draw reads it as its slab,
        # draw r's from column i_lo − 1 − first: its starts j are columns off + j
        first = int(i_lo.min()) - 1
        off = i_lo - 1 - first
        shared = (first + np.arange(int(off.max()) + J + nL + 4)) * h
        middle = np.rint(c / h).astype(np.int64) - first  # each draw's angles are taken from there
        slab, jbest, dev, _ = window_samples(params, rpr, shared, middle, 1 + off, off + span, nL, ZONE, OUTSIDE_STEP)
        i_lo = np.full(n, first + 1)
        windows.append((slab, i_lo, jbest, c, dev))
    out = np.empty(n)
    todo = rows
    if percentile is not None:
        # each draw's refined figure, bounded from its samples (synth.mechanism.tolerance_kernel)
        lower, upper, low, high = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
        for slab, i_lo, jbest, c, dev in windows:
            bounds = window_bounds(slab, i_lo, jbest + 1, nL, length, c, dev, h, SAFETY, REFINE_POINTS, FINE_POINTS)
            lower, upper = np.maximum(lower, bounds[0]), np.maximum(upper, bounds[1])
            low, high = np.maximum(low, bounds[2]), np.maximum(high, bounds[3])
        need, out = deciding_draws(np.maximum(lower, low), np.minimum(upper, high), percentile)
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
