"""The tightest output band a request can be met at (``--band auto``; pure: no click, no ORM,
no I/O — the atlas is read through the query's :class:`~synth.query.SegmentSource`).

A six-bar's dwell is measured within an output band; the narrower the band, the stiller the
rest the dwell promises. At the default band (0.1°) the query answers with six-bars whose
output moves ≈ 0.09° during the rest, while the atlas often holds rests a hundred times
stiller for the same request. :func:`answer_tightest` finds the narrowest band, down to
:data:`FLOOR`, at which at least min(``request.top``, :data:`MEET`) six-bars meet the request
(its dwell ± ``dwell_tol`` *at that band*, its swing, every limit), then answers the request
at that band.

Each six-bar has its own bands: its dwell at a band grows with the band, so it meets the
request on the bands from the one at which its rest first holds ``dwell − dwell_tol`` up to
the one at which it holds more than ``dwell + dwell_tol``; every other constraint does not
depend on the band. The search therefore measures bands, it does not probe them:

1. **The pool** (:func:`pool`): the fits of the segments the query's sample takes at bands
   from the request's own down to :data:`FLOOR`, :data:`POOL_PER_DECADE` per decade (a
   stiller rest of the same length is predicted by other stored segments), each simulated
   once; per six-bar, the band its rest needs and the band past which it rests too long
   (:func:`~synth.mechanism.output_range.least_bands` on the query's crank grid), and its
   figures at its own band — those that meet every band-free constraint stay
   (:func:`~synth.query.evaluate.meets_but_dwells`).
2. **Stiller** (with refinement on; :func:`~synth.query.refine.stiller`): the :data:`STILLER`
   stillest distinct six-bars of the pool moved to the stillest rest a search finds near each
   (the deviation over the requested dwell minimised, every other constraint held); measured
   as in 1. A rest moved to its stillest meets the request on a narrow range of bands (its
   dwell grows past ``dwell + dwell_tol`` soon above the band it needs), and the stillest
   rests' ranges seldom overlap, so three seldom meet the request at one band. Each is therefore
   **detuned** (:func:`detuned`): moved back along the straight line of dimensions to the
   six-bar it came from, to the point whose rest is the request's length at a chosen band —
   for each band of a ladder from the one the third stillest rest needs upwards
   (:func:`detune_bands`). Along that line the rest's bands move from the stiller six-bar's
   to the fit's, so a band between them is met somewhere on it; a few dozen simulations find
   where, where a search toward each band would take thousands.
3. **The sweep** (:func:`sweep`): the candidate bands — every six-bar's own band, a ladder
   of :data:`LADDER` per decade and the detuning's bands, tightest first — at which enough six-bars' bands cover them
   (:func:`covered_bands`) are checked in turn with the exact figures of those six-bars
   (:func:`~synth.query.evaluate.meets`), until one holds enough: first the pool and the
   stiller rests, then, below the band they reach, with the detuned ones.

The request is then answered at the band reached as any request is (its sample, refinement
and ``complete`` setting), with the six-bars that met there joining its candidates
(:func:`synth.query.answer`'s ``seeded``). When no band holds enough, the request is answered
at its own band, as without ``auto``.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from synth.mechanism.figures import SixBarFigures, sixbar_figures
from synth.mechanism.output_range import least_bands
from synth.mechanism.sixbar import SixBar, SixBars, crank_grid, output_angle
from synth.query import QueryResult, SegmentSource, answer
from synth.query.candidate_ids import dimension_vector, round_dimensions, sixbar_like, with_dimensions
from synth.query.candidates import SAMPLES, Candidate, Request
from synth.query.evaluate import candidate_of, distinct, figures_of, meets, meets_but_dwells, rest_position
from synth.query.fitting import Fitted, fit
from synth.query.refine import stiller
from synth.query.windows import PER_LEVEL, kinds_for, select

__all__ = [
    "DETUNE_PER_DECADE",
    "DETUNE_POINTS",
    "DETUNE_SPAN",
    "FLOOR",
    "LADDER",
    "MEET",
    "POOL_PER_DECADE",
    "POOL_PER_LEVEL",
    "REFERENCE_BAND",
    "STILLER",
    "BandAnswer",
    "BandProbe",
    "StillSixBar",
    "answer_tightest",
    "covered_bands",
    "detune_bands",
    "detuned",
    "dwell_bands",
    "ladder",
    "needed",
    "pool",
    "probe",
    "reference_dwells",
    "still_six_bars",
    "sweep",
    "tighter_band",
]

#: The narrowest band searched (rad): 1e-4°, the ``--band`` option's own floor.
FLOOR = math.radians(1e-4)
#: Six-bars that must meet the request at a band for it to count (or ``--top``, if fewer).
MEET = 3
#: Bands per decade whose samples make the pool (0.1°, 0.032°, 0.01°, … down to the floor),
#: and segments per tolerance level and target each takes (the sample's wider read).
POOL_PER_DECADE = 2
POOL_PER_LEVEL = 3 * PER_LEVEL
#: Bands per decade the sweep checks besides the six-bars' own (two rests: a six-bar's own
#: band is that of its stillest rest alone, a lower bound).
LADDER = 6
#: The stillest distinct six-bars of the pool the search moves to stiller rests.
STILLER = 8
#: Bands the sweep checks with exact figures at most.
CHECKS = 40
#: The detuning (:func:`detuned`): points measured on each line from a fit to its stiller
#: six-bar (the ends left out: both are measured already), and the bands it detunes to,
#: :data:`DETUNE_PER_DECADE` per decade from the band the third stillest rest needs up to
#: :data:`DETUNE_SPAN` times it.
DETUNE_POINTS = 32
DETUNE_PER_DECADE = 12
DETUNE_SPAN = 10.0
#: The band every candidate's dwell is also reported at (rad): the query's default, 0.1°.
REFERENCE_BAND = math.radians(0.1)
#: A six-bar's own band is checked this much wider (a fraction) than measured on the grid: ψ
#: strays between the samples, and at a still rest's own band the exact dwell is far shorter
#: (RRR 60°/30° on ``standard``: 40–55° at the grid's band, 60.0–60.4° at 1 % more).
_OWN_BAND_MARGIN = 0.01


@dataclass(frozen=True, slots=True)
class BandProbe:
    """One check of a band: the ``band`` (rad) and how many distinct six-bars met the request
    there."""

    band: float
    met: int


@dataclass(frozen=True, slots=True)
class StillSixBar:
    """A six-bar of the search with the bands it can meet the request on.

    Attributes
    ----------
    fitted : Fitted
        The fit it is (or was moved from, ``moved``).
    sixbar : SixBar
        The six-bar, crank-normalised.
    lowest : float
        The band (rad) its rest needs to hold ``dwell − dwell_tol`` on the crank grid.
    highest : float
        The band (rad) from which it holds more than ``dwell + dwell_tol`` (inf: never).
    moved : bool
        Moved to a stiller rest by the search (:func:`~synth.query.refine.stiller`): its id
        carries its dimensions.
    """

    fitted: Fitted
    sixbar: SixBar
    lowest: float
    highest: float
    moved: bool = False

    @property
    def segment_id(self) -> int:
        """The stored segment it was fitted to (with :attr:`sixbar`, what
        :func:`~synth.query.evaluate.distinct` tells six-bars apart by)."""
        return self.fitted.row.segment_id

    def candidate(self, request: Request, figures: SixBarFigures) -> Candidate:
        """The candidate it is for ``request``, with its ``figures`` (crank-normalised) there."""
        c = candidate_of(request, self.fitted, figures)
        if not self.moved:
            return c
        rest = rest_position(self.sixbar, figures)
        return dataclasses.replace(
            c,
            id=with_dimensions(c.id, self.sixbar),
            sixbar=self.sixbar.scaled(request.crank),
            dwell_position=None if rest is None else rest * request.crank,
        )


@dataclass(frozen=True, slots=True)
class BandAnswer:
    """The request answered at the tightest band found.

    Attributes
    ----------
    result : QueryResult
        The answer at ``band`` (``result.request.band == band``).
    band : float
        The band reached (rad): the tightest checked that held enough six-bars, or the
        request's own band when none did (``settled`` False).
    settled : bool
        Some band held enough six-bars (else ``band`` is the request's band, unsearched).
    probes : tuple of BandProbe
        Every band checked, in the order checked.
    reference_dwells : tuple of tuple of float
        Per candidate of ``result``, its dwells (rad) measured at :data:`REFERENCE_BAND`
        (empty where its output does not rest within that band).
    pooled : int
        Six-bars the pool fitted.
    stiller : int
        Six-bars moved to a stiller rest, or detuned from one, that then met every band-free
        constraint.
    """

    result: QueryResult
    band: float
    settled: bool
    probes: tuple[BandProbe, ...]
    reference_dwells: tuple[tuple[float, ...], ...]
    pooled: int = 0
    stiller: int = 0


def needed(request: Request) -> int:
    """Six-bars that must meet ``request`` at a band: min(``top``, :data:`MEET`)."""
    return min(request.top, MEET)


def ladder(ceiling: float, floor: float, per_decade: int = LADDER) -> np.ndarray:
    """Bands from ``ceiling`` down to ``floor`` (rad), ``per_decade`` per decade, both ends in."""
    steps = max(1, math.ceil(per_decade * math.log10(ceiling / floor) - 1e-9))
    return np.geomspace(ceiling, floor, steps + 1)


def pool(request: Request, source: SegmentSource, floor: float = FLOOR) -> list[Fitted]:
    """The fits of every segment the query's sample (:func:`~synth.query.windows.select`, at
    :data:`POOL_PER_LEVEL`) takes at the bands of :func:`ladder` (``request.band`` down to
    ``floor``, :data:`POOL_PER_DECADE` per decade), each (segment, level) once."""
    kinds = kinds_for(request)
    rows, seen = [], set()
    for band in ladder(request.band, min(floor, request.band), POOL_PER_DECADE):
        for r in select(source, dataclasses.replace(request, band=float(band)), kinds, POOL_PER_LEVEL):
            if (r.segment_id, r.level) not in seen:
                seen.add((r.segment_id, r.level))
                rows.append(r)
    return [f for kind in kinds for f in fit(request, [r for r in rows if r.kind == kind], kind)]


def dwell_bands(request: Request, sixbars: Sequence[SixBar]) -> tuple[np.ndarray, np.ndarray]:
    """The bands (rad) on which each of ``sixbars`` (crank-normalised) can meet ``request``:
    (lowest, highest) of :class:`StillSixBar`, from ψ on the query's grid:
    a dwell of ``dwell − dwell_tol`` holds ⌈(dwell − tol)/h⌉ + 1 samples, one longer than
    ``dwell + dwell_tol`` holds ⌊(dwell + tol)/h⌋ + 2."""
    h = 2 * math.pi / SAMPLES
    shortest = math.ceil((request.dwell - request.dwell_tol) / h) + 1
    longest = math.floor((request.dwell + request.dwell_tol) / h) + 2
    psi = output_angle(SixBars.from_sixbars(list(sixbars)), crank_grid(SAMPLES))
    if longest > SAMPLES:
        return least_bands(psi, [shortest])[:, 0], np.full(len(sixbars), np.inf)
    bands = least_bands(psi, [shortest, longest])
    return bands[:, 0], bands[:, 1]


def still_six_bars(
    request: Request, fitted: Sequence[Fitted], sixbars: Sequence[SixBar] | None = None, *, moved: bool = False
) -> tuple[list[StillSixBar], list[SixBarFigures]]:
    """The six-bars of ``fitted`` (or ``sixbars``, one per fit, moved from it) whose own band
    is below ``request.band`` and which meet every band-free constraint there
    (:func:`~synth.query.evaluate.meets_but_dwells`), with their figures at that band."""
    if sixbars is None:
        sixbars = [f.sixbar() for f in fitted]
    if not len(sixbars):
        return [], []
    lowest, highest = dwell_bands(request, sixbars)
    near = np.flatnonzero(np.isfinite(lowest) & (lowest < request.band))
    if not len(near):
        return [], []
    figures = sixbar_figures(
        SixBars.from_sixbars([sixbars[i] for i in near]),
        band=lowest[near] * (1 + _OWN_BAND_MARGIN),
        dwell_length=request.dwell,
        dwells=request.dwells,
        samples=SAMPLES,
        footprint=False,
        leave=request.swing_tol,
    )
    kept = [
        (StillSixBar(fitted[i], sixbars[i], float(lowest[i]), float(highest[i]), moved), f)
        for i, f in zip(near.tolist(), figures)
        if meets_but_dwells(request, f)
    ]
    return [k for k, _ in kept], [f for _, f in kept]


def _stillest(still: Sequence[StillSixBar], n: int) -> list[int]:
    """Indices of the ``n`` stillest distinct six-bars of ``still`` (as
    :func:`~synth.query.evaluate.distinct` tells them apart), stillest first."""
    order = sorted(range(len(still)), key=lambda i: still[i].lowest)
    kept = {id(s) for s in distinct([still[i] for i in order])[:n]}
    return [i for i in order if id(still[i]) in kept]


def covered_bands(
    lowest: np.ndarray,
    highest: np.ndarray,
    need: int,
    ceiling: float,
    floor: float = FLOOR,
    extra: Sequence[float] = (),
) -> Iterator[tuple[float, np.ndarray]]:
    """The bands worth checking, tightest first, with the six-bars that may meet there: of the
    six-bars' own bands (``lowest`` widened by the margin), the :func:`ladder` from ``ceiling``
    to ``floor`` (rad) and the ``extra`` bands, clipped to [``floor``, ``ceiling``], those
    covered by ``need`` or more of the intervals [``lowest``, ``highest``) — (band, their
    indices)."""
    own = np.clip(lowest * (1 + _OWN_BAND_MARGIN), floor, ceiling)
    more = np.clip(np.asarray(extra, float), floor, ceiling)
    for band in np.unique(np.concatenate([own, ladder(ceiling, min(floor, ceiling)), more])).tolist():
        live = np.flatnonzero((lowest <= band) & (band < highest))
        if len(live) >= need:
            yield band, live


def sweep(
    request: Request,
    still: Sequence[StillSixBar],
    floor: float = FLOOR,
    extra: Sequence[float] = (),
    below: float = math.inf,
) -> tuple[float | None, list[Candidate], tuple[BandProbe, ...]]:
    """The tightest band (rad) in [``floor``, ``request.band``] and below ``below`` at which
    :func:`needed` distinct six-bars of ``still`` meet ``request`` (exact figures), the
    candidates that meet it there, and the bands checked: those of :func:`covered_bands` (with
    the ``extra`` bands), in turn, :data:`CHECKS` at most."""
    need = needed(request)
    lowest = np.array([s.lowest for s in still])
    highest = np.array([s.highest for s in still])
    probes: list[BandProbe] = []
    bands = covered_bands(lowest, highest, need, request.band, floor, extra)
    for band, live in itertools.islice(itertools.takewhile(lambda b: b[0] < below, bands), CHECKS):
        at = dataclasses.replace(request, band=band)
        figures = figures_of(at, [still[i].sixbar for i in live], footprint=True)
        met = distinct([still[i].candidate(at, f) for i, f in zip(live.tolist(), figures) if meets(at, f)])
        probes.append(BandProbe(band, len(met)))
        if len(met) >= need:
            return band, met, tuple(probes)
    return None, [], tuple(probes)


def answer_tightest(
    request: Request,
    source: SegmentSource,
    *,
    answer_at: Callable[..., QueryResult] | None = None,
    floor: float = FLOOR,
    on_stage: Callable[[str], None] | None = None,
) -> BandAnswer:
    """``request`` answered at the tightest band it can be met at (the module docstring),
    searched from ``request.band`` down to ``floor`` (rad), or at ``request.band`` if no band
    holds enough six-bars.

    ``answer_at(request, seeded=…)`` answers the final request (default
    :func:`synth.query.answer` on ``source``; a caller passes its own to add a progress bar or
    worker processes to a complete search). ``on_stage(text)`` is told each step as it starts.
    """
    tell = on_stage or (lambda text: None)
    tell("band auto: fitting the sample at bands down to 1e-4°")
    fitted = pool(request, source, floor)
    still, figures = still_six_bars(request, fitted)
    chosen = _stillest(still, STILLER) if request.refine else []
    pairs = []
    if chosen:
        tell("band auto: moving the stillest rests stiller")
        pairs = _made_stiller(request, [still[i] for i in chosen], [figures[i] for i in chosen])
    moved = [m for _, m in pairs]
    band, met, probes = sweep(request, [*still, *moved], floor)
    bands = detune_bands(request, [*still, *moved], floor) if pairs else np.empty(0)
    if len(bands):
        # a sweep of its own, below the band reached: the detuned rests add many bands to
        # check, and a double dwell's own bands (its stillest rest's) are only lower bounds
        tell("band auto: detuning the stiller rests to one band")
        found = detuned(request, pairs, bands)
        moved += found
        tighter, meeting, more = sweep(request, [*still, *moved], floor, bands, math.inf if band is None else band)
        probes += more
        if tighter is not None:
            band, met = tighter, meeting
    final = request if band is None else dataclasses.replace(request, band=band)
    tell(f"band auto: answering at {math.degrees(final.band):.3g}°")
    respond = answer_at or (lambda r, seeded=(): answer(r, source, seeded=seeded))
    result = respond(final, seeded=met)
    return BandAnswer(
        result, final.band, band is not None, probes, reference_dwells(final, result), len(fitted), len(moved)
    )


def _made_stiller(
    request: Request, chosen: Sequence[StillSixBar], figures: Sequence[SixBarFigures]
) -> list[tuple[StillSixBar, StillSixBar]]:
    """The six-bars ``chosen`` (with their ``figures`` at their own bands) moved to the stillest
    rests near them (:func:`~synth.query.refine.stiller`) that still meet every band-free
    constraint, measured (:func:`still_six_bars`): (the six-bar chosen, its stiller version)."""
    if not chosen:
        return []
    # the search's objective is in units of a band: the chosen six-bars' own, as measured
    at = dataclasses.replace(request, band=float(np.median([s.lowest for s in chosen])))
    found = stiller(at, [s.sixbar for s in chosen], figures)
    changed = [(s, sb) for s, sb in zip(chosen, found) if sb is not s.sixbar]
    if not changed:
        return []
    origin = {s.fitted.key: s for s, _ in changed}
    kept = still_six_bars(request, [s.fitted for s, _ in changed], [sb for _, sb in changed], moved=True)[0]
    return [(origin[m.fitted.key], m) for m in kept]


def detune_bands(request: Request, still: Sequence[StillSixBar], floor: float = FLOOR) -> np.ndarray:
    """The bands (rad) :func:`detuned` moves six-bars to: from the band the :func:`needed`-th
    stillest distinct six-bar of ``still`` needs (its own band and the margin) up to
    :data:`DETUNE_SPAN` times it, :data:`DETUNE_PER_DECADE` per decade, those below
    ``request.band``; none if ``still`` holds too few distinct six-bars."""
    chosen = _stillest(still, needed(request))
    if len(chosen) < needed(request):
        return np.empty(0)
    first = max(floor, max(still[i].lowest for i in chosen) * (1 + _OWN_BAND_MARGIN))
    bands = first * np.geomspace(1.0, DETUNE_SPAN, round(DETUNE_PER_DECADE * math.log10(DETUNE_SPAN)) + 1)
    return bands[bands < request.band]


def detuned(request: Request, pairs: Sequence[tuple[StillSixBar, StillSixBar]], bands: np.ndarray) -> list[StillSixBar]:
    """Per pair (a six-bar, its stiller version) and per band of ``bands`` (rad), the six-bar on
    the straight line of dimensions between the two whose rest meets ``request`` at that band
    with the most room — of :data:`DETUNE_POINTS` points inside the line, the one whose bands
    [lowest, highest) (:func:`dwell_bands`) hold the band with the largest
    min(ln(band / lowest), ln(highest / band)) — rounded as an id holds it and measured
    (:func:`still_six_bars`: those that meet every band-free constraint)."""
    t = np.linspace(0.0, 1.0, DETUNE_POINTS + 2)[1:-1]
    points, origin = [], []
    for k, (start, end) in enumerate(pairs):
        p0, p1 = np.array(dimension_vector(start.sixbar)), np.array(dimension_vector(end.sixbar))
        for p in p0 + t[:, None] * (p1 - p0):
            try:
                points.append(sixbar_like(p, end.sixbar))
            except ValueError:  # a point between two six-bars may not assemble: skipped
                continue
            origin.append(k)
    if not points:
        return []
    lowest, highest = dwell_bands(request, points)
    lowest, highest, origin = lowest[:, None], highest[:, None], np.array(origin)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):  # a band of 0 or inf: outside, below
        room = np.minimum(np.log(bands / lowest), np.log(highest / bands))  # (points, bands)
    room = np.where((lowest <= bands) & (bands < highest) & np.isfinite(lowest), room, -np.inf)
    chosen: dict[int, int] = {}  # point → its pair, once however many bands chose it
    for k in range(len(pairs)):
        best = np.argmax(np.where(origin == k, room, -np.inf), axis=0)
        for b, j in enumerate(best.tolist()):
            if np.isfinite(room[j, b]):
                chosen[j] = k
    if not chosen:
        return []
    fits = [pairs[k][1].fitted for k in chosen.values()]
    return still_six_bars(request, fits, [round_dimensions(points[j]) for j in chosen], moved=True)[0]


def probe(request: Request, source: SegmentSource, band: float) -> BandProbe:
    """How many six-bars meet ``request`` at ``band`` (rad) in the sampled query without
    refinement (``top`` cut to :func:`needed`: the count is all it is asked for; an empty
    answer's diagnosis skips the stored dwells, :class:`_Counting`)."""
    asked = dataclasses.replace(request, band=band, refine=False, complete=False, top=needed(request))
    return BandProbe(band, len(answer(asked, _Counting(source)).candidates))


@dataclass(frozen=True, slots=True)
class _Counting:
    """``source`` as a probe reads it: the same segments, but no stored dwells near the
    request (:meth:`nearest_dwell_angles` answers ``(None, None)``). A probe needs only a
    count; an empty sample otherwise makes the query look the nearest stored dwells up for
    its no-match message — 0.7–0.9 s of SQL per empty RRR probe on ``standard``."""

    source: SegmentSource

    def tolerance_levels(self):
        return self.source.tolerance_levels()

    def select_segments(self, kinds, windows, **limits):
        return self.source.select_segments(kinds, windows, **limits)

    def segment(self, segment_id, level):
        return self.source.segment(segment_id, level)

    def nearest_dwell_angles(self, kinds, target):
        return None, None

    def scan_segments(self, kind, level, **limits):
        return self.source.scan_segments(kind, level, **limits)

    def count_segments(self, kind, level, **limits):
        return self.source.count_segments(kind, level, **limits)


def reference_dwells(
    request: Request, result: QueryResult, band: float = REFERENCE_BAND
) -> tuple[tuple[float, ...], ...]:
    """Per candidate of ``result``, its dwells (rad, at most ``request.dwells``) at ``band``
    (rad) from the exact simulation (the query's 720 samples, refined ends)."""
    if not result.candidates:
        return ()
    figures = sixbar_figures(
        SixBars.from_sixbars([c.sixbar for c in result.candidates]),
        band=band,
        dwell_length=request.dwell,
        dwells=request.dwells,
        footprint=False,
        leave=request.swing_tol,
    )
    return tuple(tuple(d.angle for d in f.dwells[: request.dwells]) for f in figures)


def tighter_band(request: Request, source: SegmentSource, factor: float = 10.0) -> BandProbe | None:
    """One probe at ``request.band / factor`` (not below :data:`FLOOR`): the probe if enough
    six-bars (:func:`needed`) meet the request there, else None. What a query at a fixed band
    names as the stiller rest ``--band auto`` would look for."""
    band = max(request.band / factor, FLOOR)
    if band >= request.band:
        return None
    found = probe(request, source, band)
    return found if found.met >= needed(request) else None
