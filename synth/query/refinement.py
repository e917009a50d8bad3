"""The query's hand-off to :mod:`synth.query.refine`: the top candidates refined toward the request
(:func:`refined_candidates`), the nearest misses refined to meet it (:func:`miss_pool`,
:func:`refined_misses`), and the reseated six-bars kept only where no worse than their fit
(:func:`no_worse_than_fits`, :func:`with_origins`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

from synth.kinds import OutputTag
from synth.mechanism.figures import SixBarFigures
from synth.query.candidate_ids import REFINED_MARK, with_dimensions
from synth.query.candidates import Candidate, Request
from synth.query.evaluate import candidate_of, distinct, figures_of, rest_position, scaled_figures
from synth.query.fitting import Fitted
from synth.query.refine import refine
from synth.query.refine_objective import better_or_equal

#: Nearest misses refined toward a request that fewer than FILL six-bars met, this many at a
#: time (nearest first), for at most MISS_ROUNDS rounds while the answer still holds fewer.
MISSES = 16

#: Four rounds for lines (RPR, one dwell or two): the misses nearest by their excess are not
#: the ones that refine best — on ``standard`` RPR 180° at a 90° swing meets its first
#: six-bars in the 3rd and 4th rounds, two 20° ± 5° rests at a 45° swing in the 4th — at ~3 s
#: more for a request nothing meets.
MISS_ROUNDS = 4

#: Two for arcs (RRR): on ``standard``'s coverage grid the 3rd and 4th rounds met no
#: RRR request the first two had not (its eight cells short of 3 stayed empty, ~3 s more each).
ARC_MISS_ROUNDS = 2


def no_worse_than_fits(request: Request, moved: list[Candidate], answered: list[Candidate]) -> list[Candidate]:
    """The ``moved`` six-bars (:func:`reseat`) that may stand for their fit: a moved pivot is a
    change of the fit it was moved from (its ``refined_from``), kept only if no worse on every
    objective of the ranking (:func:`synth.query.refine_objective.better_or_equal`) where that fit met the
    request itself (it is then among the ``answered``); beside a fit that missed, it is new."""
    met = {c.id: c.figures for c in answered}
    return [
        c
        for c in moved
        if (fit_ := met.get(c.id.split(REFINED_MARK)[0])) is None or better_or_equal(request, c.figures, fit_)
    ]


def with_origins(
    request: Request, found: list[Candidate], fitted: Sequence[Fitted], known: dict[tuple, SixBarFigures]
) -> list[Candidate]:
    """Reseated candidates (:func:`reseat`) with ``refined_from``: the figures of the fit they
    were moved from (``known`` by the fit's :attr:`~synth.query.fitting.Fitted.key`, or
    computed), in the user's units; and an
    RRR's ``dwell_position`` from its simulation."""
    if not found:
        return []
    base = {f.candidate_id(request.swing, dimensions=False): f for f in fitted}
    origins = {c.id.split(REFINED_MARK)[0] for c in found}
    todo = [base[k] for k in origins if base[k].key not in known]
    if todo:
        computed = figures_of(request, [f.sixbar() for f in todo], footprint=False)
        known = {**known, **dict(zip((f.key for f in todo), computed))}
    return [
        dataclasses.replace(
            c,
            refined_from=scaled_figures(known[base[c.id.split(REFINED_MARK)[0]].key], request.crank),
            dwell_position=rest_position(c.sixbar, c.figures),
        )
        for c in found
    ]


def refined_candidates(
    request: Request,
    candidates: Sequence[Candidate],
    before: Sequence[SixBarFigures] | None = None,
    *,
    reach: bool = False,
) -> tuple[list[Candidate], int]:
    """``candidates`` (the user's units) refined toward ``request`` (:func:`synth.query.refine.refine`,
    its reach for near misses): the refined ones with their new id, six-bar and figures and
    ``refined_from``, the others as they were; and how many were refined. ``before``: their
    figures crank-normalised, if at hand."""
    if not candidates:
        return [], 0
    s = request.crank
    sixbars = [c.sixbar.scaled(1.0 / s) for c in candidates]
    before = [scaled_figures(c.figures, 1.0 / s) for c in candidates] if before is None else before
    out, count = [], 0
    for c, r in zip(candidates, refine(request, sixbars, before, reach=reach)):
        if not r.refined:
            out.append(c)
            continue
        count += 1
        rest = rest_position(r.sixbar, r.figures)
        out.append(
            dataclasses.replace(
                c,
                id=with_dimensions(c.id, r.sixbar),
                sixbar=r.sixbar.scaled(s),
                figures=scaled_figures(r.figures, s),
                # a reseated six-bar keeps the fit it was moved from as "before" (as a rebuild does)
                dwell_position=None if rest is None else rest * s,
                refined_from=c.refined_from or c.figures,
            )
        )
    return out, count


def refined_misses(
    request: Request, misses: list[tuple[float, Fitted, SixBarFigures, dict]], taken: set[str], wanted: int
) -> tuple[list[Candidate], int, int]:
    """The nearest distinct misses (:func:`miss_pool`, not one of the ``taken`` ids) refined
    toward ``request``, ``MISSES`` at a time, nearest first, until ``wanted`` distinct six-bars
    meet it or ``MISS_ROUNDS`` rounds are done (``ARC_MISS_ROUNDS`` for an RRR output): (those
    that now meet it, how many were tried, how many came out refined). The first round is what
    one round always was."""
    rounds = ARC_MISS_ROUNDS if request.output == OutputTag.RRR else MISS_ROUNDS  # two dwells are RPR
    pool, figures = miss_pool(request, misses, taken, MISSES * rounds)
    met: list[Candidate] = []
    better = tried = 0
    for start in range(0, len(pool), MISSES):
        part = pool[start : start + MISSES]
        refined, improved = refined_candidates(request, part, figures[start : start + MISSES], reach=True)
        met += [c for c in refined if c.refined_from is not None]
        tried, better = tried + len(part), better + improved
        if len(distinct(met)) >= wanted:
            break
    return met, tried, better


def miss_pool(
    request: Request, misses: list[tuple[float, Fitted, SixBarFigures, dict]], taken: set[str], n: int
) -> tuple[list[Candidate], list[SixBarFigures]]:
    """The ``n`` nearest distinct ``misses`` (:func:`misses_of`' order; one per segment and
    output type, one of a mirror pair; none that does not assemble, none of the ``taken``
    ids) as candidates, with their figures crank-normalised (the candidates' own are in the
    user's units)."""
    near = [(candidate_of(request, fit_, fig), fig) for total, fit_, fig, _ in misses if total < math.inf]
    figures: dict[str, SixBarFigures] = {}
    for c, fig in near:
        figures.setdefault(c.id, fig)
    pool = [c for c in distinct([c for c, _ in near]) if c.id not in taken][:n]
    return pool, [figures[c.id] for c in pool]
