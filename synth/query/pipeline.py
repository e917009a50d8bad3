""":func:`answer`: a request through the steps of the package, over one :class:`Answering`
state (the rows read, the fits, the figures already computed, the clock): the sample, sampled
wider, the moved pivots and the deeper read while the answer is sparse, ranking, refinement,
the near misses and the diagnosis. ``--output any`` with one dwell is the best of both
output types (:func:`_best_of_both`, :func:`~synth.query.both_outputs.union_of`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from synth.kinds import OutputTag, SegmentKind
from synth.mechanism.figures import SixBarFigures
from synth.query.both_outputs import Answered, union_of
from synth.query.candidate_ids import REFINED_MARK
from synth.query.candidates import Candidate, Request, rank
from synth.query.complete import SearchCount, search
from synth.query.contract import BatchMap, SegmentSource
from synth.query.diagnosis import diagnose, diagnose_by_bounds, misses_of, reach_beyond, unfitted_reach
from synth.query.evaluate import candidate_of, distinct, meets, screened_figures, toleranced
from synth.query.fitting import Fitted, fit, fit_arrays, fits_of, prescreen, reseat
from synth.query.refinement import no_worse_than_fits, refined_candidates, refined_misses, with_origins
from synth.query.result import NoMatch, QueryResult
from synth.query.segment_rows import SegmentRow
from synth.query.support_fits import support_fits
from synth.query.windows import LONG_REACHES, PER_LEVEL, kinds_for, select

#: An answer with fewer candidates than this (or than ``--top``) is topped up from the
#: nearest misses, refined to meet the request (with refinement on).
FILL = 3

#: With refinement on, a sparse answer (fewer than FILL six-bars) samples again, this many
#: times wider (the no-refinement query keeps PER_LEVEL).
WIDER = 3

#: Last, if still sparse after the moved pivots, this many times PER_LEVEL segments per level
#: of the kinds in DEEPER_KINDS: arcs (RRR), whose dwell key ranks them (``synth.segment_search.dwell_key``)
#: — the longest rests (150° at swings of 20°–30° on ``standard``) lie a few hundred rows
#: deep —, and double lines, whose rests the stored dwell predicts less well (two rests of 90°
#: on ``standard``: 1 six-bar from the narrower samples, 3 with this read). Single lines are
#: not read deeper: their sparse answers (150° at a 90° swing) are filled from refined near
#: misses, which a deeper read would stop at 3 (FILL) where they reach 10.
DEEPER = 10

DEEPER_KINDS = (SegmentKind.ARC, SegmentKind.DOUBLE_LINE)

#: A creeping rest is shorter than the fitted one: the segments the sample would take for
#: these multiples of the requested dwell are moved too.
RESEAT_LONGER = (2.0, 4.0)

#: Moved six-bars simulated at a time; the reseat stops once --top segments are answered.
RESEAT_BATCH = 128


def answer(
    request: Request,
    source: SegmentSource,
    *,
    on_progress: Callable[[int, int], None] | None = None,
    map_batches: BatchMap | None = None,
    searched: tuple[list[Candidate], SearchCount] | None = None,
    seeded: Sequence[Candidate] = (),
) -> QueryResult:
    """Ranked candidates for ``request`` from ``source`` (a pure read): from the sample of
    segments :func:`select` takes, or with ``request.complete`` from every six-bar the atlas
    yields (:func:`search`, which reports ``on_progress`` and runs its batches through
    ``map_batches``; or ``searched``, its result for this request from :func:`search_many`),
    and ``seeded``: six-bars found otherwise that meet ``request`` (the band search's,
    :mod:`synth.query.band_search`), ranked, refined and counted with them.

    ``--output any`` with one dwell is the best of both output types: the request answered as
    RPR and as RRR, each through the whole pipeline (its sparse-answer steps and refinement
    sized for ``request.top``), then the union of the two answers ranked once
    (:func:`~synth.query.candidates.rank`) and cut to ``request.top`` (:func:`_best_of_both`)."""
    if request.output == "any" and request.dwells == 1:
        return _best_of_both(
            request, source, on_progress=on_progress, map_batches=map_batches, searched=searched, seeded=seeded
        )
    return _answer_one(
        request, source, on_progress=on_progress, map_batches=map_batches, searched=searched, seeded=seeded
    ).result


def _best_of_both(
    request: Request,
    source: SegmentSource,
    *,
    on_progress: Callable[[int, int], None] | None,
    map_batches: BatchMap | None,
    searched: tuple[list[Candidate], SearchCount] | None,
    seeded: Sequence[Candidate] = (),
) -> QueryResult:
    """``request`` (``output="any"``, one dwell) answered as RPR and as RRR, then the best
    ``request.top`` of the union of the two answers by :func:`~synth.query.candidates.rank` (Pareto
    layer, score, id, over the union: a six-bar's layer depends on what it is ranked with).
    The union: :func:`~synth.query.both_outputs.union_of`; each part is diagnosed only if both
    are empty (:meth:`~synth.query.both_outputs.Answered.diagnosed`). ``searched`` (a complete search
    of both kinds, :func:`search_many`) is split by output type; its counts go to the RPR
    part, so that the sums are the search's own."""
    parts = []
    for output in (OutputTag.RPR, OutputTag.RRR):
        mine = None
        if searched is not None:
            found, count = searched
            met = [c for c in found if c.sixbar.dyad.kind == output.dyad]
            mine = (
                met,
                dataclasses.replace(count, met=len(met)) if output == OutputTag.RPR else SearchCount(met=len(met)),
            )
        parts.append(
            _answer_one(
                dataclasses.replace(request, output=output.value),
                source,
                on_progress=on_progress,
                map_batches=map_batches,
                searched=mine,
                seeded=[c for c in seeded if c.sixbar.dyad.kind == output.dyad],
                diagnosed=False,  # one kind's no-match matters only if the other has none either
            )
        )
    if not any(p.result.candidates for p in parts):
        parts = [p.diagnosed() for p in parts]
    union = union_of(request, parts)
    if 0 < len(union.candidates) < min(FILL, request.top):  # each type's constraint in the way of more
        union = dataclasses.replace(union, short_of=tuple(s for p in parts for s in p.result.short_of))
    return union


@dataclass(slots=True)
class Answering:
    """What the steps of one output type's answer share while it runs (mutable; never returned).

    Attributes
    ----------
    request, source, kinds :
        The request, where its segments are read, and the segment kinds it draws on.
    clock : dict
        Seconds per stage (``select``, ``fit``, ``simulate``, ``reseat``, ``search``, ``rank``,
        ``refine``), summed over the steps.
    rows : list of SegmentRow
        Every row the sample read (narrow, wider and deeper), each (segment, level) once.
    fitted : list of Fitted
        Every fit of those rows, past the prescreen or not: a no-match is diagnosed and the near
        misses are refined from them.
    known : dict
        The full figures (no footprint) of every screened fit, by :attr:`Fitted.key`: a
        diagnosis reuses them.
    longer_fits : list of Fitted
        Fits to rests ``RESEAT_LONGER[0]`` times the requested dwell (:func:`_moved_pivots`),
        refined as near misses with the others.
    moved_ids : set of str
        Ids of the fits whose answer is a six-bar with a moved output pivot.
    simulated : int
        Six-bars simulated (screened).
    """

    request: Request
    source: SegmentSource
    kinds: tuple[SegmentKind, ...]
    clock: dict[str, float] = field(default_factory=dict)
    rows: list[SegmentRow] = field(default_factory=list)
    fitted: list[Fitted] = field(default_factory=list)
    known: dict[tuple, SixBarFigures] = field(default_factory=dict)
    longer_fits: list[Fitted] = field(default_factory=list)
    moved_ids: set[str] = field(default_factory=set)
    simulated: int = 0

    def add_time(self, stage: str, since: float) -> None:
        """Seconds from ``since`` (:func:`time.perf_counter`) to now added to ``stage``."""
        self.clock[stage] = self.clock.get(stage, 0.0) + time.perf_counter() - since

    def read(self) -> set[tuple[int, int]]:
        """(segment, level) of every row read so far."""
        return {(r.segment_id, r.level) for r in self.rows}


def _sampled(
    state: Answering, per_level: int = PER_LEVEL, kinds: tuple[SegmentKind, ...] | None = None
) -> list[Fitted]:
    """The sample's rows and fits added to ``state`` (all of them are what a no-match is
    diagnosed and refined from); a wider sample adds the rows the narrower one did not have.
    Returns the new fits past the prescreen."""
    request, kinds = state.request, state.kinds if kinds is None else kinds
    t = time.perf_counter()
    had = state.read()
    new = [r for r in select(state.source, request, kinds, per_level) if (r.segment_id, r.level) not in had]
    state.rows = [*state.rows, *new]
    state.add_time("select", t)
    t = time.perf_counter()
    passed = []
    for kind in kinds:
        of_kind = [r for r in new if r.kind == kind]
        found, paths = fit_arrays(request, of_kind, kind)
        fits = fits_of(of_kind, found)  # every fit: a no-match is diagnosed and refined from them
        state.fitted.extend(fits)
        passed += [f for f, k in zip(fits, prescreen(request, found, paths)) if k]
    state.add_time("fit", t)
    return passed


def _meeting(state: Answering, fits: list[Fitted]) -> list[Candidate]:
    """The candidates among ``fits`` (simulated), their figures kept in ``state.known`` for a
    diagnosis (without the footprint, as the misses' own figures)."""
    t = time.perf_counter()
    screened, n = screened_figures(state.request, fits)
    state.simulated += n
    state.known.update({f.key: dataclasses.replace(fig, footprint=0.0) for f, fig in screened})
    state.add_time("simulate", t)
    return [candidate_of(state.request, f, fig) for f, fig in screened if meets(state.request, fig)]


def _moved_pivots(state: Answering, answered: list[Candidate]) -> list[Candidate]:
    """The six-bars with the output pivot moved off the fitted one (:func:`reseat`) that meet
    the request: of the sample's fits, then of the segments whose fitted rests are longer than
    the request (``RESEAT_LONGER``), ``RESEAT_BATCH`` at a time, until --top segments
    (``answered`` and these) have one."""
    request = state.request
    found: list[Candidate] = []
    had = state.read()
    origins = list(state.fitted)
    for k in (1.0, *RESEAT_LONGER):
        t = time.perf_counter()
        if k > 1:
            if request.dwells * k * request.dwell >= 2 * math.pi:
                break
            longer = [
                r
                for r in select(
                    state.source, dataclasses.replace(request, dwell=k * request.dwell), state.kinds, WIDER * PER_LEVEL
                )
                if (r.segment_id, r.level) not in had
            ]
            had |= {(r.segment_id, r.level) for r in longer}
            origins = [f for kind in state.kinds for f in fit(request, [r for r in longer if r.kind == kind], kind)]
            if k == RESEAT_LONGER[0]:
                state.longer_fits.extend(origins)
        moved = reseat(request, origins)
        state.add_time("reseat", t)
        for b in range(0, len(moved), RESEAT_BATCH):  # the fits nearest the request first
            met = _meeting(state, moved[b : b + RESEAT_BATCH])
            t = time.perf_counter()
            found += with_origins(request, met, origins, state.known)
            state.add_time("reseat", t)
            if len(distinct([*answered, *found])) >= request.top:
                return found
    return found


def _from_sample(state: Answering, seeded: Sequence[Candidate] = ()) -> list[Candidate]:
    """The candidates of the sample and ``seeded`` (which count toward the answer's size): a
    sparse answer (fewer than FILL) samples wider, is filled towards --top with the fits'
    pivots moved (short rests), and if still sparse reads deeper along the arcs' keys (long
    rests) and the double lines' dwells."""
    request = state.request
    candidates = [*seeded, *_meeting(state, _sampled(state))]
    sparse = request.refine and len(distinct(candidates)) < min(FILL, request.top)
    if sparse:
        candidates += _meeting(state, _sampled(state, WIDER * PER_LEVEL))
    if sparse and len(distinct(candidates)) < request.top:
        found = no_worse_than_fits(request, _moved_pivots(state, candidates), candidates)
        state.moved_ids = {c.id.split(REFINED_MARK)[0] for c in found} - {c.id for c in candidates}
        candidates += found
    deep = tuple(k for k in state.kinds if k in DEEPER_KINDS)
    if sparse and deep and len(distinct(candidates)) < min(FILL, request.top):
        candidates += _meeting(state, _sampled(state, DEEPER * PER_LEVEL, deep))
    return candidates


def _far_slot_fits(state: Answering) -> list[Fitted]:
    """Fits of the lines (single or double) the sample did not read whose stored dwells predict
    the rest for a slot pivot far from the stretch (:data:`~synth.query.windows.LONG_REACHES`
    within the link ratio, WIDER × PER_LEVEL per window): near misses of a sparse answer,
    refined with the others. Not candidates themselves: a long rest's six-bars are refined
    from them (RPR 180° at a 20° or 30° swing on ``standard``: 0–1 six-bars without them, 3
    with), but more candidates would stop the fill from the near misses sooner (RPR 120° at
    20°: 10 six-bars from the near misses, 3 with these as candidates)."""
    kinds = tuple(k for k in state.kinds if k != SegmentKind.ARC)
    if not kinds:
        return []
    request, had = state.request, state.read()
    reaches = tuple(r for r in LONG_REACHES if r <= request.max_link_ratio)  # the slot is a link
    rows = [
        r
        for r in select(state.source, request, kinds, WIDER * PER_LEVEL, reaches)
        if (r.segment_id, r.level) not in had
    ]
    fits = [f for kind in kinds for f in fit(request, [r for r in rows if r.kind == kind], kind)]
    known = {f.key for f in state.longer_fits}
    return [f for f in fits if f.key not in known]


def _ranked(request: Request, candidates: list[Candidate]) -> list[Candidate]:
    """The best ``request.top`` distinct ``candidates``, numbered from 1."""
    ranked = distinct(rank(request, candidates))[: request.top]
    return [dataclasses.replace(c, rank=i + 1) for i, c in enumerate(ranked)]


@dataclass(frozen=True, slots=True)
class _Filled:
    """The top after the near misses were refined toward the request (:func:`_fill_from_misses`)."""

    top: list[Candidate]
    refined: tuple[int, int]
    miss_ids: frozenset[str]
    no_match: NoMatch | None
    short_of: tuple[tuple[str, str, float, float], ...] = ()


def _fill_from_misses(state: Answering, top: list[Candidate], refined: tuple[int, int]) -> _Filled:
    """An answer with fewer than FILL (or --top) candidates topped up from the nearest misses
    refined to meet the request; with nothing met, the diagnosis of the misses; still short,
    the constraint in the way of more (:func:`reach_beyond`)."""
    request = state.request
    no_match = None
    miss_ids: frozenset[str] = frozenset()
    if request.complete and not state.fitted:
        _sampled(state)  # too little in the whole atlas: the sample's near misses are refined
    t = time.perf_counter()
    misses = misses_of(request, state.fitted, state.known)  # all of the fits, nearest first
    if not top:
        no_match = diagnose(request, state.fitted, misses)
    # the diagnosis simulates the fits the screen dropped: simulation time of this answer
    state.add_time("simulate", t)
    t = time.perf_counter()
    # a short rest's own sample can hold no fit (RRR 10° on ``standard``: the arcs whose
    # stored rests predict it are all near-toggle four-bars, transmission < 10°, as the atlas
    # keeps rests ≥ 20° at its widest tolerance); the fits to rests twice as long miss it by a
    # few degrees, and a long rest's lie on the far slots' lines; a rest shorter than a harmonic
    # output's of the swing lies at a support point of a curve (RPR 10° at a 10° or 20° swing):
    # all are refined with the others
    more = [*state.longer_fits, *_far_slot_fits(state), *support_fits(request, state.source)]
    state.add_time("fit", t)
    if more:
        t = time.perf_counter()
        misses = sorted([*misses, *misses_of(request, more, state.known)], key=lambda m: m[0])
        state.add_time("simulate", t)
    t = time.perf_counter()
    found, tried, better = refined_misses(
        request, misses, {c.id.split(REFINED_MARK)[0] for c in top}, min(FILL, request.top) - len(top)
    )
    if found:
        top = _ranked(request, [*top, *toleranced(request, found)])
        miss_ids = frozenset(c.id for c in found) & {c.id for c in top}
        no_match = None
    state.add_time("refine", t)
    short_of: tuple[tuple[str, str, float, float], ...] = ()
    if len(top) < min(FILL, request.top):
        beyond = reach_beyond(request, misses, {c.id.split(REFINED_MARK)[0] for c in top})
        short_of = () if beyond is None else ((request.output, *beyond),)
    return _Filled(top, (refined[0] + tried, refined[1] + better), miss_ids, no_match, short_of)


def _answer_one(
    request: Request,
    source: SegmentSource,
    *,
    on_progress: Callable[[int, int], None] | None = None,
    map_batches: BatchMap | None = None,
    searched: tuple[list[Candidate], SearchCount] | None = None,
    seeded: Sequence[Candidate] = (),
    diagnosed: bool = True,
) -> Answered:
    """:func:`answer` for one output type (or a double dwell): candidates (the complete
    search's or the sample's), ranked, the top refined, filled from the near misses while
    sparse, and diagnosed when empty (not ``diagnosed``: left to :meth:`Answered.diagnosed`)."""
    t = time.perf_counter()
    state = Answering(request, source, kinds_for(request))
    if request.complete:
        candidates, count = (
            searched
            if searched is not None
            else search(request, source, on_progress=on_progress, map_batches=map_batches)
        )
        state.clock["search"] = time.perf_counter() - t
        considered, state.simulated = count.rows, count.simulated
        candidates = [*candidates, *seeded]
    else:
        candidates = _from_sample(state, seeded)
        considered = len({r.segment_id for r in state.rows})
    t = time.perf_counter()
    top = _ranked(request, toleranced(request, candidates))
    state.add_time("rank", t)
    met_in_atlas = bool(top)
    refined = (0, 0)
    if top and request.refine:
        t = time.perf_counter()
        top, better = refined_candidates(request, top)
        top = rank(request, toleranced(request, top))
        refined = (len(top), better)
        state.add_time("refine", t)
    filled = _Filled(top, refined, frozenset(), None)
    if request.refine and len(top) < min(FILL, request.top):
        filled = _fill_from_misses(state, top, refined)
    top, no_match = filled.top, filled.no_match
    nearest: tuple[float | None, float | None] = (None, None)
    later = None
    if not top and diagnosed:
        no_match, nearest = _no_match(state, no_match)
    elif not top:
        later = functools.partial(_no_match, state, no_match)
    reseated = frozenset(c.id for c in top if c.id.split(REFINED_MARK)[0] in state.moved_ids)
    return Answered(
        QueryResult(
            request,
            top,
            considered,
            state.simulated,
            nearest,
            state.clock,
            no_match,
            filled.refined,
            from_misses=bool(top) and not met_in_atlas,
            misses_met=len(filled.miss_ids),
            reseated=len(reseated),
            short_of=filled.short_of,
        ),
        filled.miss_ids,
        reseated,
        later,
    )


def _no_match(state: Answering, found: NoMatch | None) -> tuple[NoMatch, tuple[float | None, float | None]]:
    """Why nothing met the request (``found``: the near misses' diagnosis, if the fill made
    one) and, with no six-bar to show, the stored dwell angles nearest the request."""
    request, source = state.request, state.source
    nearest: tuple[float | None, float | None] = (None, None)
    if found is None:
        if request.complete and not state.fitted:
            _sampled(state)  # nothing in the whole atlas: diagnose the sample's near misses
        t = time.perf_counter()
        found = diagnose_by_bounds(request, state.fitted, state.known)
        state.add_time("simulate", t)
    if not found.fitted:  # no six-bar to show: the stored dwells the atlas has instead
        nearest = source.nearest_dwell_angles(state.kinds, request.dwell)
        reach, among = unfitted_reach(request, source, state.kinds, state.rows) or (None, "fitted")
        found = dataclasses.replace(found, reach=reach, reach_among=among)
    return found, nearest
