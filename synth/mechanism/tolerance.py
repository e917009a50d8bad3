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

Lengths are in the six-bar's unit (a :class:`~synth.query.candidates.Candidate`'s six-bar is in the
user's unit, so ``t`` is too); angles in radians. Pure: no I/O.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np

from synth.kinds import OutputKind
from synth.mechanism.output_range import output_deviation
from synth.mechanism.sixbar import ExactOutput, SixBar, SixBars, crank_grid, simulate
from synth.types import F64

__all__ = ["DRAWS", "PERCENTILE", "SEED", "deviation_draws", "perturbed", "toleranced_deviation", "unit_draws"]

#: Random six-bars drawn per candidate.
DRAWS = 256
#: The percentile of the draws' deviations reported (%).
PERCENTILE = 95.0
#: Seed of the draws: the same workshop for every candidate and every run.
SEED = 44_2026
#: Toleranced dimensions, in the columns of :func:`unit_draws`: a, b, c, u, v, L, ρ, then
#: A0 x, A0 y, B0 x, B0 y, D x, D y (an RPR ignores L and ρ).
DIMENSIONS = 13
#: Crank samples of each draw's simulation: the query's grid (the nominal figure's).
SAMPLES = 720


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
    sixbar: SixBar, tolerance: float, centres: Sequence[float], length: float, *, draws: int = DRAWS, seed: int = SEED
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
    """
    if not (math.isfinite(tolerance) and tolerance >= 0):
        raise ValueError(f"tolerance must be a finite length >= 0, got {tolerance!r}")
    batch, beta = perturbed(sixbar, tolerance, unit_draws(draws, seed))
    rrr = not batch.rpr[0]
    lengths = [batch.a, batch.b, batch.c, batch.d] + ([batch.rocker, batch.rod] if rrr else [])
    made = np.all(np.stack(lengths) > 0, axis=0)  # a tolerance as large as a link: no such part
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
    assemble (more than 5 % of them)."""
    dev = deviation_draws(sixbar, tolerance, centres, length, draws=draws, seed=seed)
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
