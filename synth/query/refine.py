"""Exact refinement of retrieved six-bars (pure: no click, no database, no I/O).

A six-bar the atlas yields is exact but not optimal: its four-bar proportions come from a
sweep grid, its coupler point from a scan, its dyad from a fit to a stored line or circle.
:func:`refine` moves every continuous dimension a little — the four-bar's b, c, d (crank
a = 1 fixed), the coupler point u, v, the output pivot D (x, y) and, for an RRR, the rocker L
and the rod ρ; assembly branches fixed — to meet the request (dwell and swing within their
tolerances, with a margin, and every limit of :class:`~synth.query.candidates.Request`) and, among
designs that do, to minimise the output deviation over the requested dwell window.

Method: a batched elitist (1 + λ) evolution strategy in a scaled space, every six-bar of
every candidate of one iteration simulated exactly in one vectorised call
(:func:`~synth.mechanism.sixbar.simulate` on a ``SAMPLES`` crank grid). A dimension p₀ moves as
p = p₀ + s·x with s = |p₀| for a length and max(|p₀|, 1) for a coordinate, x in the box
[−``radius``, ``radius``] (a trust region of a few percent: the result stays near the
retrieved design). Each iteration draws λ mirrored Gaussian steps of size σ per candidate and
keeps the best point if it is better; σ grows ×1.25 after a success and shrinks ×0.6 after a
failure (a success rule), and a candidate stops when σ < ``radius``·1e-3 or its objective has
not fallen by 1 % in ``STALL`` iterations.

That is the polish, for six-bars that meet the request. A near miss of a sparse answer is
refined by the reach first (``reach=True``, :func:`_reach`): a CMA-ES per candidate
(:mod:`synth.query.batched_cma`) in a wider box (``REACH_RADIUS``), with more iterations, whose
adapted covariance follows the narrow valleys along which a miss comes to meet the request.

For ``--band auto`` (:mod:`synth.query.band_search`), :func:`stiller` runs the reach's search
in the reach's box with no band holding the dwell: the deviation over the requested dwell
minimised for itself, every other constraint held as for a near miss, from a small first step
(a still rest is lost to a relative change of 1e-5 in one length); the band search measures
and checks the result (~35 000 trial six-bars per request).

The reach's CMA-ES (the near misses' and the stillest rest's: thousands of trial six-bars a
candidate) judges its trials by the compiled loop figures (:mod:`synth.query.refine_kernel`:
one pass per six-bar, the numpy path's objective to ~1e-12), where the numpy path spent two
thirds of its time re-reading the motion; a request with ``--max-accel`` takes the numpy path,
which has ψ″. The polish keeps the numpy path: its few hundred trials a candidate are not
worth the kernel's compilation on a first run (``dwell demo`` only polishes).

Objective (on the grid, cheap): the deviation g(D) / band, g(L) the smallest peak-to-peak of ψ
over a crank window of length L containing the retrieved dwell's middle
(:func:`~synth.mechanism.output_range.output_deviation`), D the requested dwell; plus ``PENALTY`` × the sum of
the constraint excesses, each in its own unit and zero inside a margin: the dwell
through g(D − tol/2) ≤ band (a dwell at least that long) and g(D + tol/2) ≥ band (none longer),
|swing − S| ≤ swing_tol/2, the transmission angles, the link ratio, the torque arm, the
clearance and the peak acceleration. A six-bar that already meets the request is held, in
the loop, to no worse than it is on the ranking's objectives the grid can measure: its dwell
within its own dwell error of the request (g(D − e₀) ≤ band, g(D + e₀) ≥ band), its worst
transmission angle and its peak |ψ″| (:func:`~synth.query.refine_objective.hold_bounds`) — a stiller rest bought with a longer
dwell, a poorer transmission or a harder output would be refused by the check. A six-bar that
does not assemble over the turn, toggles or revolves is worse than any other.

The result is then checked as the query checks any six-bar: rounded to what its id holds
(:func:`~synth.query.candidate_ids.round_dimensions`), its full figures from
:func:`~synth.mechanism.figures.sixbar_figures` (720 samples, refined dwell ends), and kept only if it
meets the request and — for a six-bar that met it before — it is no worse on any of the
ranking's objectives and better on one (:func:`better_or_equal`: the dwell error, the
deviation, the worst transmission angle, the footprint and the peak output acceleration);
otherwise the original is kept. A refinement that only trades one objective for another is
not kept: the designer asked for the same six-bar, better.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from synth.kinds import OutputKind
from synth.mechanism.figures import SixBarFigures, sixbar_figures
from synth.mechanism.sixbar import SixBar, SixBars, crank_grid
from synth.query.batched_cma import cma_es
from synth.query.candidate_ids import dimension_vector, round_dimensions, sixbar_like
from synth.query.candidates import Request
from synth.query.evaluate import meets
from synth.query.refine_objective import WORST, better_or_equal, hold_bounds, request_bounds, trial_objective

__all__ = ["PARAMETERS", "Evaluate", "Refinement", "descend", "refine", "stiller"]

#: The dimensions moved, in the order of the optimisation vector (crank-normalised; a = 1).
PARAMETERS = ("b", "c", "d", "u", "v", "pivot_x", "pivot_y", "rocker", "rod")
_LENGTHS = np.array([1, 1, 1, 0, 0, 0, 0, 1, 1], bool)
#: Crank samples of the simulation inside the loop (1°); the check uses the query's 720.
SAMPLES = 360
#: Trust region: largest relative change of a dimension (see the module docstring).
RADIUS = 0.05
#: Trial six-bars per candidate and iteration (mirrored pairs), and iterations at most.
POPULATION = 10
ITERATIONS = 20
#: A candidate stops when its objective has not fallen by ``STALL_GAIN`` (relative) over the
#: last ``STALL`` iterations.
STALL = 6
STALL_GAIN = 0.01
#: The reach (near misses toward a request they miss; see :func:`_reach`): a wider trust
#: region, CMA-ES's first step size (a fraction of it), population and iterations at most.
#: Measured on ``standard`` with the 16 nearest misses of six sparse requests (RRR 150°/30°,
#: 150°/45°, 150°/60°, 120°/90°, two rests of 90° and of 120°): 32 of the 96 reached at
#: 0.2/0.25/16/160 (27 s for the six), 16 at 100 iterations, 37 at 200 (30 s), 26 with a
#: population of 12, 30 with a first step of 0.5.
REACH_RADIUS = 0.2
REACH_SIGMA = 0.25
REACH_POPULATION = 16
REACH_ITERATIONS = 160
#: The reach stops a candidate at an objective below this (it meets the request, its deviation
#: over the requested dwell inside the band); the polish takes it on.
REACHED = 1.0
#: The search for the stillest rest (:func:`stiller`, the reach's population): its box, first
#: step (a fraction of the box) and iterations. The reach's box: a long rest is made stiller
#: only by moving the four-bar and the dyad together, and far (``--band auto`` on ``standard``
#: reaches 0.027° for RPR 135°/15° in a box of 0.05, 0.0104° in one of 0.2). A first step of a
#: twentieth of it: a rest of a few thousandths of a degree is lost to a relative change of
#: 1e-5 in one length alone, and CMA-ES learns the directions along which the rest stays. It
#: takes most of 300 iterations to learn them: 150 reach 0.021° there, 450 no more than 300.
STILL_RADIUS = 0.2
STILL_SIGMA = 0.05
STILL_ITERATIONS = 300


@dataclass(frozen=True, slots=True)
class Refinement:
    """The outcome for one six-bar.

    Attributes
    ----------
    sixbar : SixBar
        The refined six-bar (crank-normalised, dimensions as its id holds them), or the
        original if refinement did not find a better one that meets the request.
    figures : SixBarFigures
        Exact figures of ``sixbar`` (:func:`~synth.mechanism.figures.sixbar_figures`, crank lengths).
    before : SixBarFigures
        The original's figures, as given.
    refined : bool
        True if ``sixbar`` is the refined one.
    meets : bool
        Whether ``figures`` meet the request.
    evaluations : int
        Six-bars simulated in the loop for this one.
    """

    sixbar: SixBar
    figures: SixBarFigures
    before: SixBarFigures
    refined: bool
    meets: bool
    evaluations: int


#: evaluate(x, who): the objective of steps x (len(who), T, 9) of the candidates ``who``.
Evaluate = Callable[[np.ndarray, np.ndarray], np.ndarray]


def descend(
    evaluate: Evaluate, start: np.ndarray, radius: float, iterations: int, population: int, seed: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The polish: the batched elitist (1 + λ) evolution strategy of the module docstring, from
    x = 0 (the dimension rows ``start``, (K, 9)) for every candidate at once. Returns the steps
    x (K, 9) in the scaled space, the objective there and the six-bars each candidate simulated."""
    K = len(start)
    rng = np.random.default_rng(seed)
    lam = population + population % 2
    x = np.zeros((K, 9))
    fx = evaluate(x[:, None, :], np.arange(K))[:, 0]
    sigma = np.full(K, 0.25 * radius)
    count = np.ones(K, int)
    active = fx < WORST
    history = [fx.copy()]
    for _ in range(iterations):
        who = np.flatnonzero(active)
        if not len(who):
            break
        z = rng.standard_normal((len(who), lam // 2, 9))
        z = np.concatenate([z, -z], axis=1)
        trial = np.clip(x[who, None, :] + sigma[who, None, None] * z, -radius, radius)
        ft = evaluate(trial, who)
        count[who] += lam
        j = np.argmin(ft, axis=1)
        best = ft[np.arange(len(who)), j]
        better = best < fx[who] - 1e-12 * np.abs(fx[who])
        x[who[better]] = trial[better, j[better]]
        fx[who[better]] = best[better]
        sigma[who] *= np.where(better, 1.25, 0.6)
        sigma[who] = np.minimum(sigma[who], radius)
        active[who] = sigma[who] > 1e-3 * radius
        history.append(fx.copy())
        if len(history) > STALL:
            active &= fx < (1 - STALL_GAIN) * history[-1 - STALL]
    return x, fx, count


def _reach(
    evaluate: Evaluate,
    start: np.ndarray,
    radius: float,
    iterations: int,
    population: int,
    seed: int,
    stop_below: float = REACHED,
    sigma: float = REACH_SIGMA,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The reach: a CMA-ES per candidate (:func:`synth.query.batched_cma.cma_es`: all candidates'
    populations simulated in one call per iteration; box [−radius, radius]), from x = 0 at the
    dimension rows ``start`` (K, 9), until it is ``REACHED`` or stops. Each candidate's steps
    are drawn from a generator seeded by ``seed`` and its own starting row, so its reach does
    not depend on which other misses are reached with it. Returns the best steps x (K, 9)
    found (0 where nothing beat the start), the objective there and the six-bars each
    candidate simulated. ``stop_below``: the objective at which a candidate stops; ``sigma``:
    the first step, a fraction of ``radius``.

    Why not the polish: a near miss meets the request only after the dimensions move together
    along a narrow valley (a longer rest at the same band couples every length and the coupler
    point), where an isotropic step size collapses; CMA-ES learns that valley's shape. At RRR
    150°/30° on ``standard`` the polish brought none of 16 misses to the request, this 13."""
    rngs = [np.random.default_rng([seed, *row.view(np.uint64).tolist()]) for row in start]
    result = cma_es(
        evaluate,
        np.zeros_like(start),
        sigma * radius,
        rngs,
        population=population,
        iterations=iterations,
        box=radius,
        stop_below=stop_below,
        tol_sigma=1e-3 * radius,
    )
    return result.x, result.f, result.evaluations


@dataclass(frozen=True, slots=True)
class _Trials:
    """What every trial six-bar of one refinement is simulated and judged with: the request,
    per candidate its kinds of link (RPR or RRR, assembly branches), the crank angles its
    dwells sit around (rad, (K, C)) and its bounds (:func:`hold_bounds`), the loop's crank grid
    and the objective (``stillest``: :func:`~synth.query.refine_objective.trial_objective`'s
    stillest rest); the reach's trials are judged from the compiled loop figures."""

    request: Request
    rpr: np.ndarray
    branch: np.ndarray
    dyad_branch: np.ndarray
    centres: np.ndarray
    bounds: np.ndarray
    phi: np.ndarray
    stillest: bool = False

    @classmethod
    def of(
        cls,
        request: Request,
        sixbars: Sequence[SixBar],
        before: Sequence[SixBarFigures],
        samples: int,
        stillest: bool = False,
    ) -> _Trials:
        """The trials of ``sixbars`` (each with at least the request's dwells in ``before``)."""
        return cls(
            request,
            np.array([sb.dyad.kind is OutputKind.RPR for sb in sixbars]),
            np.array([sb.branch for sb in sixbars]),
            np.array([sb.dyad.branch for sb in sixbars]),
            np.array([[0.5 * (d.start + d.end) for d in f.dwells[: request.dwells]] for f in before]),
            request_bounds(request, len(before)) if stillest else hold_bounds(request, before),
            crank_grid(samples),
            stillest,
        )

    def steps(
        self,
        search: Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]],
        start: np.ndarray,
        only: np.ndarray,
        *args,
        compiled: bool = False,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``search`` run (``*args`` then its seed last) for the candidates ``only`` from their
        dimension rows in ``start`` (K, 9), in the space scaled at them: every candidate's rows
        after it (the others as they were), its objective there (inf for the others) and the
        six-bars it simulated. ``compiled``: its trials judged from the compiled loop figures
        (the reach's; see the module docstring for why not the polish's)."""
        K = len(start)
        scale = np.where(_LENGTHS, np.abs(start), np.maximum(np.abs(start), 1.0))
        scale[self.rpr, 7:] = 0.0  # an RPR has no rocker or rod

        def evaluate(x: np.ndarray, who: np.ndarray) -> np.ndarray:
            """x (len(who), T, 9) → (len(who), T); ``who`` indexes ``only``."""
            T = x.shape[1]
            g = only[who]
            rep = lambda a: np.repeat(a[g], T, axis=0)  # noqa: E731
            p = (start[g, None, :] + scale[g, None, :] * x).reshape(-1, 9)
            f = trial_objective(
                self.request,
                p,
                rep(self.branch),
                rep(self.rpr),
                rep(self.dyad_branch),
                rep(self.centres),
                rep(self.bounds),
                self.phi,
                stillest=self.stillest,
                compiled=compiled,
            )
            return f.reshape(len(who), T)

        x, f, n = search(evaluate, start[only], *args)
        end, objective, count = start.copy(), np.full(K, np.inf), np.zeros(K, int)
        end[only] = start[only] + scale[only] * x
        objective[only], count[only] = f, n
        return end, objective, count


def refine(
    request: Request,
    sixbars: Sequence[SixBar],
    before: Sequence[SixBarFigures],
    *,
    reach: bool = False,
    radius: float = RADIUS,
    iterations: int = ITERATIONS,
    population: int = POPULATION,
    samples: int = SAMPLES,
    check_samples: int = 720,
    seed: int = 0,
) -> list[Refinement]:
    """Refine each six-bar of ``sixbars`` toward ``request`` (see the module docstring).

    Parameters
    ----------
    request : Request
        What to meet (its limits in crank lengths: the six-bars are crank-normalised).
    sixbars : sequence of SixBar
        Crank-normalised six-bars (a = 1), e.g. a query's candidates or nearest misses.
    before : sequence of SixBarFigures
        Their exact figures (:func:`~synth.mechanism.figures.sixbar_figures` with the request's band and
        dwell, crank lengths): where their dwells sit, and the deviation to beat.
    reach : bool
        For six-bars that miss the request: the reach (:func:`_reach`, ``REACH_RADIUS``,
        ``REACH_POPULATION``, ``REACH_ITERATIONS``) first, then the polish from where it
        stopped.
    radius : float
        The polish's trust region, the largest relative change of a dimension.
    iterations, population : int
        The polish's iterations at most, and trial six-bars per candidate and iteration (even).
    samples : int
        Crank samples of the simulation in the loop.
    check_samples : int
        Crank samples of the final check (the query's).
    seed : int
        Seed of the steps: the same input gives the same refinement.

    Returns
    -------
    list of Refinement, one per six-bar, in order.
    """
    if len(sixbars) != len(before):
        raise ValueError("refine needs the figures of every six-bar")
    if not (0 < radius < 0.5) or iterations < 0 or population < 2:
        raise ValueError("refine needs 0 < radius < 0.5, iterations >= 0 and population >= 2")
    dwells = request.dwells
    rows = [k for k, f in enumerate(before) if f.acceptable and len(f.dwells) >= dwells]
    out = [Refinement(sb, f, f, False, meets(request, f), 0) for sb, f in zip(sixbars, before)]
    if not rows:
        return out
    K = len(rows)
    p0 = np.array([dimension_vector(sixbars[k]) for k in rows])
    trials = _Trials.of(request, [sixbars[k] for k in rows], [before[k] for k in rows], samples)

    # the polish; with ``reach``, the candidates it leaves short of the request are reached
    # for, then polished again
    p, f, count = trials.steps(descend, p0, np.arange(K), radius, iterations, population, seed)
    short = np.flatnonzero(f >= REACHED)
    if reach and len(short):
        p, _, n = trials.steps(_reach, p, short, REACH_RADIUS, REACH_ITERATIONS, REACH_POPULATION, seed, compiled=True)
        count += n
        p, _, n = trials.steps(descend, p, short, radius, iterations, population, seed)
        count += n

    # the check: rounded as the id holds it, then the query's exact figures
    moved = [k for k in range(K) if np.any(p[k] != p0[k])]
    if not moved:
        return out
    refined = [round_dimensions(sixbar_like(p[k], sixbars[rows[k]])) for k in moved]
    figures = sixbar_figures(
        SixBars.from_sixbars(refined),
        band=request.band,
        dwell_length=request.dwell,
        dwells=dwells,
        samples=check_samples,
    )
    for k, sb, f in zip(moved, refined, figures):
        i = rows[k]
        old = out[i]
        if not meets(request, f):
            out[i] = Refinement(old.sixbar, old.figures, old.before, False, old.meets, int(count[k]))
            continue
        if old.meets and not better_or_equal(request, f, old.before):
            out[i] = Refinement(old.sixbar, old.figures, old.before, False, True, int(count[k]))
        else:
            out[i] = Refinement(sb, f, old.before, True, True, int(count[k]))
    for k in range(K):
        if k not in moved:
            i = rows[k]
            out[i] = Refinement(out[i].sixbar, out[i].figures, out[i].before, False, out[i].meets, int(count[k]))
    return out


def stiller(
    request: Request,
    sixbars: Sequence[SixBar],
    before: Sequence[SixBarFigures],
    *,
    radius: float = STILL_RADIUS,
    iterations: int = STILL_ITERATIONS,
    population: int = REACH_POPULATION,
    samples: int = SAMPLES,
    seed: int = 0,
) -> list[SixBar]:
    """Each six-bar of ``sixbars`` moved to the stillest rest the reach's search (a CMA-ES per
    candidate, :func:`_reach`, run to its ``iterations`` — no objective stops it) finds in the
    box of ``radius``: the deviation over the requested dwell minimised for itself, no band holding
    the dwell, every other constraint of ``request`` held as the refinement holds a near miss's
    (the ``stillest`` objective of :func:`~synth.query.refine_objective.trial_objective`, in
    units of ``request.band``). Rounded as an id holds it; the six-bar itself where nothing
    was better or it has fewer dwells in ``before`` (its figures at some band) than asked.
    Nothing is checked here: the band search measures each result's band and checks it
    there (:mod:`synth.query.band_search`)."""
    rows = [k for k, f in enumerate(before) if f.acceptable and len(f.dwells) >= request.dwells]
    out = list(sixbars)
    if not rows:
        return out
    p0 = np.array([dimension_vector(sixbars[k]) for k in rows])
    trials = _Trials.of(request, [sixbars[k] for k in rows], [before[k] for k in rows], samples, stillest=True)
    p, _, _ = trials.steps(
        _reach, p0, np.arange(len(rows)), radius, iterations, population, seed, -np.inf, STILL_SIGMA, compiled=True
    )
    for k, i in enumerate(rows):
        if np.any(p[k] != p0[k]):
            out[i] = round_dimensions(sixbar_like(p[k], sixbars[i]))
    return out
