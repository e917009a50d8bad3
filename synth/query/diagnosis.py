"""Why nothing met a request (:class:`~synth.query.result.NoMatch`): every fitted six-bar's
excesses over the limits (:func:`misses_of`), the counts per constraint, the nearest six-bar and
the request it would meet (:func:`diagnose`); cheaper from bounds on the dwell without refinement
(:func:`diagnose_by_bounds`); the two diagnoses of an ``any`` request in one
(:func:`either_no_match`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Collection, Sequence

import numpy as np

from synth.kinds import SegmentKind
from synth.mechanism.figures import DwellBoundFigures, SixBarFigures, figures_with_dwell_bounds, footprints
from synth.mechanism.sixbar import SixBars
from synth.query.candidates import Request
from synth.query.contract import SegmentSource
from synth.query.evaluate import (
    SAMPLES,
    candidate_of,
    dwell_excess,
    figures_of,
    limit_excesses,
    scaled_figures,
    total_excess,
    violations,
)
from synth.query.fitting import Fitted, fit
from synth.query.result import CONSTRAINTS, NoMatch
from synth.query.segment_rows import SegmentRow
from synth.query.windows import select


def _loosened(request: Request, f: SixBarFigures) -> Request:
    """``request`` loosened just enough for a six-bar with figures ``f`` to meet it: the dwell
    and swing moved to the six-bar's own (rounded to 0.01°, tolerances kept), the limits
    widened to its transmission (down to the whole degree) and link ratio (up to 0.01)."""
    change: dict = {}
    excess = violations(request, f)
    if excess["dwell"] > 0:
        angles = [d.angle for d in f.dwells[: request.dwells]]
        change["dwell"] = math.radians(round(math.degrees(sum(angles) / len(angles)), 2))
        spread = max(abs(a - change["dwell"]) for a in angles)
        change["dwell_tol"] = max(request.dwell_tol, math.radians(math.ceil(math.degrees(spread) * 100) / 100))
    if excess["swing"] > 0:
        change["swing"] = math.radians(round(math.degrees(f.swing), 2))
        change["swing_tol"] = max(request.swing_tol, math.radians(0.01))
    if excess["step"] > 0:
        change["step"] = math.radians(round(math.degrees(f.step), 2))
        change["swing_tol"] = max(request.swing_tol, math.radians(0.01))
    if excess["transmission"] > 0:
        mu = min(f.transmission_fourbar, f.transmission_output)
        change["min_transmission"] = math.radians(math.floor(math.degrees(mu)))
    if excess["link_ratio"] > 0:
        change["max_link_ratio"] = math.ceil(f.link_ratio * 100) / 100
    if excess["arm"] > 0:
        change["min_arm"] = math.floor(f.build.arm * 1000) / 1000
    if excess["clearance"] > 0:
        change["min_clearance"] = math.floor(f.build.clearance * 1000) / 1000
    if excess["acceleration"] > 0:
        change["max_accel"] = math.ceil(f.build.dynamics(request.rpm)[1] * 100) / 100
    try:
        return dataclasses.replace(request, **change)
    except ValueError:
        return request


def misses_of(
    request: Request, fitted: Sequence[Fitted], known: dict[tuple, SixBarFigures] | None = None
) -> list[tuple[float, Fitted, SixBarFigures, dict]]:
    """Every fitted six-bar with its figures (no footprint; ``known``: figures at hand by
    :attr:`~synth.query.fitting.Fitted.key`) and excesses over the limits (:func:`violations`), nearest first by
    their sum (inf for one that does not assemble)."""
    if not fitted:
        return []
    known = known or {}
    rest = [f for f in fitted if f.key not in known]
    computed = (
        dict(zip((f.key for f in rest), figures_of(request, [f.sixbar() for f in rest], footprint=False)))
        if rest
        else {}
    )
    out = []
    for fit_ in fitted:
        fig = known[fit_.key] if fit_.key in known else computed[fit_.key]
        excess = violations(request, fig)
        out.append((total_excess(excess), fit_, fig, excess))
    return sorted(out, key=lambda t: t[0])  # stable: ties keep the fit order


def diagnose(
    request: Request, fitted: Sequence[Fitted], misses: list[tuple[float, Fitted, SixBarFigures, dict]] | None = None
) -> NoMatch:
    """Why none of ``fitted`` meets ``request`` (see :class:`NoMatch`); simulates them all
    unless their :func:`misses_of` are given."""
    rejected = dict.fromkeys(CONSTRAINTS, 0)
    if not fitted:
        return NoMatch(0, rejected, None, None)
    misses = misses_of(request, fitted) if misses is None else misses
    for _, _, _, excess in misses:
        for k, x in excess.items():
            rejected[k] += x > 0
    best_total, fit_, fig, _ = misses[0]
    found = _no_match(request, len(fitted), rejected, None if best_total == math.inf else (fit_, fig))
    return dataclasses.replace(found, reach=_reach(request, misses))


#: The transmission limit (rad) the sample's output dyads are fitted at when none meets the
#: request's: how far from it they reach (:func:`unfitted_reach`; ``fit_rrr`` needs one > 0).
LOOSE_TRANSMISSION = math.radians(0.5)


def unfitted_reach(
    request: Request, source: SegmentSource, kinds: tuple[SegmentKind, ...], rows: Sequence[SegmentRow] = ()
) -> tuple[tuple[str, float, float], str] | None:
    """:attr:`NoMatch.reach` and :attr:`~NoMatch.reach_among` of a request that fitted no
    six-bar: the transmission angle, with the largest smallest transmission angle (°) within
    reach, when that is below the request's limit — of the six-bars the sample's ``rows`` give
    with their output dyads fitted down to :data:`LOOSE_TRANSMISSION` (RRR 90° at a 120° swing
    on ``standard``: rows of that dwell, but no rocker that swings 120° transmits at 30°, the
    best 23.2°), or, when the sample held no row, of the
    four-bars the sample without the limit holds (RRR 10° at a 30° swing: the 49 arcs whose
    keys predict it all belong to four-bars below 10°). None when that figure is not below the
    limit: the transmission angle is then not what is in the way."""
    among = "fitted without the limit" if rows else "four-bars"
    if request.min_transmission <= 0:
        return None
    limit = math.degrees(request.min_transmission)
    if rows:
        loose = dataclasses.replace(request, min_transmission=min(LOOSE_TRANSMISSION, request.min_transmission))
        fits = [f for kind in kinds for f in fit(loose, [r for r in rows if r.kind == kind], kind)]
        if not fits:  # an RPR's fit has no transmission limit: the swing or clearance is in the way
            return None
        figures = [f for f in figures_of(loose, [f.sixbar() for f in fits], footprint=False) if f.acceptable]
        if not figures:
            return None
        best = math.degrees(max(min(f.transmission_fourbar, f.transmission_output) for f in figures))
    else:
        rows = select(source, dataclasses.replace(request, min_transmission=0.0), kinds)
        if not rows:
            return None
        best = math.degrees(max(r.fourbar_transmission_min for r in rows))
    return (("transmission", best, limit), among) if best < limit else None


def reach_beyond(
    request: Request, misses: list[tuple[float, Fitted, SixBarFigures, dict]], taken: Collection[str]
) -> tuple[str, float, float] | None:
    """The one constraint in the way of more six-bars than an answer holds
    (:attr:`~synth.query.result.QueryResult.short_of`): :attr:`NoMatch.reach` of ``misses``
    (:func:`misses_of`, nearest first) but those whose candidate id (before any refined
    dimensions) is one of ``taken`` — the fits the answer's six-bars were refined from."""
    return _reach(request, [m for m in misses if m[1].candidate_id(request.swing, dimensions=False) not in taken])


def _reach(
    request: Request, misses: list[tuple[float, Fitted, SixBarFigures, dict]]
) -> tuple[str, float, float] | None:
    """:attr:`NoMatch.reach` of ``misses`` (:func:`misses_of`, nearest first)."""
    alone = [
        (next(k for k, x in excess.items() if x > 0), fig)
        for total, _, fig, excess in misses
        if total < math.inf and sum(x > 0 for x in excess.values()) == 1
    ]
    if not alone:
        return None
    key = alone[0][0]
    figs = [fig for k, fig in alone if k == key]
    deg = math.degrees

    def nearest(values: list[float], target: float) -> float:
        return deg(min(values, key=lambda v: abs(v - target)))

    if key == "dwell":
        return (
            key,
            nearest([d.angle for f in figs for d in f.dwells[: request.dwells]], request.dwell),
            deg(request.dwell),
        )
    if key == "swing":
        return key, nearest([f.swing for f in figs], request.swing), deg(request.swing)
    if key == "step":
        return key, nearest([f.step for f in figs], request.step), deg(request.step)
    if key == "transmission":
        best = max(min(f.transmission_fourbar, f.transmission_output) for f in figs)
        return key, deg(best), deg(request.min_transmission)
    if key == "link_ratio":
        return key, min(f.link_ratio for f in figs), request.max_link_ratio
    if key == "acceleration":
        return key, min(f.build.dynamics(request.rpm)[1] for f in figs), request.max_accel
    if key == "arm":
        return key, max(f.build.arm for f in figs), request.min_arm
    return key, max(f.build.clearance for f in figs), request.min_clearance


def _no_match(
    request: Request, fitted: int, rejected: dict[str, int], nearest: tuple[Fitted, SixBarFigures] | None
) -> NoMatch:
    if nearest is None:
        return NoMatch(fitted, rejected, None, None)
    fit_, fig = nearest
    # the misses are simulated without the footprint: the one shown gets it
    fig = dataclasses.replace(fig, footprint=float(footprints(SixBars.from_sixbars([fit_.sixbar()]))[0]))
    loose = _loosened(request, fig)
    return NoMatch(fitted, rejected, dataclasses.replace(candidate_of(loose, fit_, fig), rank=1), loose)


def diagnose_by_bounds(
    request: Request, fitted: Sequence[Fitted], known: dict[tuple, SixBarFigures] | None = None
) -> NoMatch:
    """:func:`diagnose`, the same :class:`NoMatch`, refining the dwell ends only of the
    six-bars whose dwell decides something (single dwells; a double dwell is diagnosed by
    :func:`diagnose`).

    Every figure but the dwell is computed as :func:`~synth.mechanism.figures.sixbar_figures` does; the
    dwell's angle is bounded from the grid (:func:`~synth.mechanism.figures.figures_with_dwell_bounds`),
    which bounds its excess (convex in the angle: least at the requested dwell). A six-bar
    gets its exact figures when the bounds leave open whether it misses the dwell, or when
    its least possible total excess is not above the smallest total known to be reachable —
    until no six-bar not simulated exactly can be nearer (or as near: ties go to the fit
    order, as in :func:`diagnose`). ``known``: figures at hand by :attr:`~synth.query.fitting.Fitted.key`.

    The six-bars left open and those within the first reachable total are simulated exactly
    in one batch: the smallest reachable total only falls as exact figures replace bounds, so
    the six-bars it then leaves open are among them (the loop after it finds none left, but
    stays, as the rule's statement), and those beyond it have a least total above the nearest
    one's, so the nearest is the same. The constraint in the way (:attr:`NoMatch.reach`) is
    found the same way (:func:`_alone_misses`)."""
    known = dict(known or {})
    if request.dwells != 1 or not fitted:
        return diagnose(request, fitted, misses_of(request, fitted, known))
    rest = [k for k, f in enumerate(fitted) if f.key not in known]
    excess: dict[int, dict[str, float]] = {
        k: violations(request, known[f.key]) for k, f in enumerate(fitted) if f.key in known
    }
    figures = {k: known[f.key] for k, f in enumerate(fitted) if f.key in known}
    low_total: dict[int, float] = {}
    high_total: dict[int, float] = {}
    undecided: list[int] = []
    bound: dict[int, dict[str, float]] = {}  # excesses of the decided ones (dwell: its lower bound)
    if rest:
        rough = figures_with_dwell_bounds(
            SixBars.from_sixbars([fitted[k].sixbar() for k in rest]),
            band=request.band,
            samples=SAMPLES,
            accel=request.max_accel is not None,
        )
        least, most, lows, highs = bounded_excess(request, rough)
        rows = [dict(zip(CONSTRAINTS, values)) for values in zip(*(least[c] for c in CONSTRAINTS))]
        for k, row, lo, hi, worst in zip(rest, rows, lows, highs, most):
            low_total[k], high_total[k], bound[k] = lo, hi, row
            if (row["dwell"] > 0) != (worst > 0):
                undecided.append(k)

    def exact(ks: list[int]) -> None:
        if not ks:
            return
        for k, fig in zip(ks, figures_of(request, [fitted[k].sixbar() for k in ks], footprint=False)):
            figures[k], excess[k] = fig, violations(request, fig)
            low_total[k] = high_total[k] = total_excess(excess[k])

    for k in excess:
        low_total[k] = high_total[k] = total_excess(excess[k])
    reach = min(high_total.values())
    near = {k for k in rest if low_total[k] <= reach and low_total[k] < math.inf}
    exact(sorted(near.union(undecided)))
    while True:
        reach = min(high_total.values())
        need = [k for k in rest if k not in excess and low_total[k] <= reach and low_total[k] < math.inf]
        if not need:
            break
        exact(need)
    rejected = dict.fromkeys(CONSTRAINTS, 0)
    for k in range(len(fitted)):
        for key, x in (excess[k] if k in excess else bound[k]).items():
            rejected[key] += x > 0
    totals = [(low_total[k], k) for k in excess]
    best_total, best = min(totals)
    found = _no_match(request, len(fitted), rejected, None if best_total == math.inf else (fitted[best], figures[best]))
    return dataclasses.replace(
        found, reach=_reach(request, _alone_misses(fitted, figures, excess, bound, (low_total, high_total), exact))
    )


def _alone_misses(
    fitted: Sequence[Fitted],
    figures: dict[int, SixBarFigures],
    excess: dict[int, dict[str, float]],
    bound: dict[int, dict[str, float]],
    totals: tuple[dict[int, float], dict[int, float]],
    exact: Callable[[list[int]], None],
) -> list[tuple[float, Fitted, SixBarFigures, dict]]:
    """What :func:`_reach` reads of the full diagnosis's misses, from :func:`diagnose_by_bounds`'s
    state (``figures``, ``excess``: the six-bars with exact figures, which ``exact`` adds to;
    ``bound``: the excesses of the others, the dwell's its least; ``totals``: the least and
    most total excess of each): the six-bars that miss one constraint alone, nearest first,
    with exact figures wherever one can decide the figure shown.

    Which six-bars miss one constraint alone is known from the bounds: every figure but the
    dwell is exact there, and whether the dwell is missed is decided. A six-bar that misses
    only the dwell gets exact figures while its least total could make it the nearest of
    them; after that none left can be the nearest, nor hold a rest nearer the request when
    the nearest misses the dwell (the dwell's excess grows with the distance). When the
    nearest misses another constraint, every six-bar missing that one alone gets exact
    figures: the best figure on it is read from all of them."""
    low, high = totals

    def misses(k: int) -> dict[str, float]:
        return excess[k] if k in excess else bound[k]

    alone = [k for k in low if low[k] < math.inf and sum(x > 0 for x in misses(k).values()) == 1]
    if not alone:
        return []
    while True:
        reach = min(high[k] for k in alone)
        need = [k for k in alone if k not in excess and misses(k)["dwell"] > 0 and low[k] <= reach]
        if not need:
            break
        exact(need)
    nearest = min((low[k], k) for k in alone if k in excess or misses(k)["dwell"] == 0)[1]
    key = next(c for c, x in misses(nearest).items() if x > 0)
    if key != "dwell":
        exact([k for k in alone if k not in excess and misses(k)[key] > 0])
    return [(low[k], fitted[k], figures[k], excess[k]) for k in sorted(excess, key=lambda k: (low[k], k))]


def bounded_excess(
    request: Request, rough: DwellBoundFigures
) -> tuple[dict[str, list[float]], list[float], list[float], list[float]]:
    """Per row of ``rough``: the excesses :func:`violations` gives with the dwell at the angle
    of its bounds nearest the request (the least dwell excess: convex in the angle), the most
    dwell excess the bounds allow, and the least and most total excess (:func:`total_excess`,
    inf where the six-bar is not acceptable) — the same floats as those functions give row by
    row (the same operations in the same order), for a whole batch at once."""
    n = rough.swing.shape[0]
    ok = rough.acceptable
    w = 2.0 * math.pi * request.rpm / 60.0  # as Buildability.dynamics
    least = dict.fromkeys(CONSTRAINTS, np.zeros(n))
    least["dwell"] = dwell_excess(request, np.minimum(np.maximum(request.dwell, rough.dwell_low), rough.dwell_high))
    least.update(
        limit_excesses(
            request,
            swing=rough.swing,
            transmission=np.minimum(rough.transmission_fourbar, rough.transmission_output),
            link_ratio=rough.link_ratio,
            arm=np.where(rough.rpr, rough.arm, math.inf),
            clearance=rough.clearance,
            accel=rough.peak_accel * w * w,
        )
    )
    # a six-bar that is not acceptable misses on assembly alone (violations measures nothing else)
    least = {c: np.where(ok, x, 0.0) for c, x in least.items()}
    least["assembly"] = np.where(ok, 0.0, 1.0)
    most = np.maximum(dwell_excess(request, rough.dwell_low), dwell_excess(request, rough.dwell_high))
    low = high = np.zeros(n)
    for c in CONSTRAINTS:  # summed in the order of total_excess's sum over the dict
        low = low + least[c]
        high = high + (most if c == "dwell" else least[c])
    inf = np.full(n, math.inf)
    return (
        {c: x.tolist() for c, x in least.items()},
        most.tolist(),
        np.where(ok, low, inf).tolist(),
        np.where(ok, high, inf).tolist(),
    )


def either_no_match(request: Request, diagnoses: Sequence[NoMatch | None]) -> NoMatch | None:
    """The :class:`NoMatch` of an ``any`` request from those of its RPR and RRR answers: the
    six-bars fitted and the rejections summed, the nearest the nearer of the two (the smaller
    sum of excesses, :func:`violations`; RPR on a tie) with its loosened request."""
    known = [d for d in diagnoses if d is not None]
    if not known:
        return None
    rejected = {k: sum(d.rejected.get(k, 0) for d in known) for k in CONSTRAINTS}

    def total(d: NoMatch) -> float:
        # the nearest's figures are in the user's units; the limits are crank-normalised
        return total_excess(violations(request, scaled_figures(d.nearest.figures, 1.0 / request.crank)))

    near = [d for d in known if d.nearest is not None]
    best = min(near, key=total) if near else None
    reaches = [(d.reach, d.reach_among) for d in known if d.reach is not None]
    reach, among = (
        (best.reach, best.reach_among)
        if best is not None and best.reach is not None
        else next(iter(reaches), (None, "fitted"))
    )
    if reach is not None:  # the best figure of both types on that constraint, among the same kind of six-bars
        mine = [r[1] for r, a in reaches if r[0] == reach[0] and a == among]
        pick = {"transmission": max, "arm": max, "clearance": max, "link_ratio": min, "acceleration": min}.get(
            reach[0], lambda xs: min(xs, key=lambda x: abs(x - reach[2]))
        )
        reach = (reach[0], pick(mine), reach[2])
    return NoMatch(
        sum(d.fitted for d in known),
        rejected,
        None if best is None else best.nearest,
        None if best is None else dataclasses.replace(best.would_meet, output=request.output),
        reach,
        among,
    )
