"""The tightest output band a request can be met at (``--band auto``; pure: no click, no ORM,
no I/O — the atlas is read through the query's :class:`~synth.query.SegmentSource`).

A six-bar's dwell is measured within an output band; the narrower the band, the stiller the
rest the dwell promises. At the default band (0.1°) the query answers with six-bars whose
output moves ≈ 0.09° during the rest, while the atlas often holds rests a hundred times
stiller for the same request. :func:`answer_tightest` finds the narrowest band, down to
:data:`FLOOR`, at which at least min(``request.top``, :data:`MEET`) six-bars meet the request
(its dwell ± ``dwell_tol`` *at that band*, its swing, every limit), then answers the request
at that band.

Search: each probe is the sampled query with refinement off (:func:`probe`: the cheap part of
the query, ~0.05–0.2 s on ``standard``), asked at one band. How many six-bars meet is not
monotonic in the band — each band samples the atlas around its own target (a rest measured at
a narrower band is shorter, so other stored segments predict it) and a six-bar meets only on a
narrow range of bands, about ±4·dwell_tol/dwell around the one its rest fills exactly — so a
plain bisection from the two ends could settle on a loose band with a tighter one left
unseen. The search first probes a ladder of :data:`LADDER` bands per decade from the
request's band (the loosest tried) down to :data:`FLOOR`, takes the tightest rung that meets,
then bisects on a log scale between it and the next tighter rung until the two are within a
factor :data:`RESOLUTION`. The request is then answered once at the band reached, with its own
refinement and ``complete`` setting: refinement runs only there.

When no probe meets (the unrefined sample is sparse at every band: long RRR rests on
``standard``), the request is answered at its own band, as without ``auto``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from synth.mechanism.figures import sixbar_figures
from synth.mechanism.sixbar import SixBars
from synth.query import QueryResult, SegmentSource, answer
from synth.query.candidates import Request

__all__ = [
    "FLOOR",
    "LADDER",
    "MEET",
    "REFERENCE_BAND",
    "RESOLUTION",
    "BandAnswer",
    "BandProbe",
    "answer_tightest",
    "ladder",
    "needed",
    "probe",
    "reference_dwells",
    "tighter_band",
    "tightest_band",
]

#: The narrowest band searched (rad): 1e-4°, the ``--band`` option's own floor.
FLOOR = math.radians(1e-4)
#: Six-bars that must meet the request at a band for it to count (or ``--top``, if fewer).
MEET = 3
#: Rungs of the first pass per decade of band (log-spaced): 6 → 0.1°, 0.068°, 0.046°, …
LADDER = 6
#: The bisection stops when the band that meets is within this factor of the one that fails.
RESOLUTION = 1.25
#: The band every candidate's dwell is also reported at (rad): the query's default, 0.1°.
REFERENCE_BAND = math.radians(0.1)


@dataclass(frozen=True, slots=True)
class BandProbe:
    """One probe of the search: the ``band`` asked (rad) and how many six-bars the sampled,
    unrefined query found meeting the request there (at most the count needed)."""

    band: float
    met: int


@dataclass(frozen=True, slots=True)
class BandAnswer:
    """The request answered at the tightest band found.

    Attributes
    ----------
    result : QueryResult
        The answer at ``band`` (``result.request.band == band``).
    band : float
        The band reached (rad): the tightest probe that met, or the request's own band when
        none did (``settled`` False).
    settled : bool
        Some probe met the request (else ``band`` is the request's band, unsearched).
    probes : tuple of BandProbe
        Every probe, in the order made.
    reference_dwells : tuple of tuple of float
        Per candidate of ``result``, its dwells (rad) measured at :data:`REFERENCE_BAND`
        (empty where its output does not rest within that band).
    """

    result: QueryResult
    band: float
    settled: bool
    probes: tuple[BandProbe, ...]
    reference_dwells: tuple[tuple[float, ...], ...]


def needed(request: Request) -> int:
    """Six-bars that must meet ``request`` at a band: min(``top``, :data:`MEET`)."""
    return min(request.top, MEET)


@dataclass(frozen=True, slots=True)
class _Counting:
    """``source`` as a probe reads it: the same segments, but no stored dwells near the
    request (:meth:`nearest_dwell_angles` answers ``(None, None)``). A probe needs only a
    count; an empty sample otherwise makes the query look the nearest stored dwells up for
    its no-match message — 0.7–0.9 s of SQL per empty RRR probe on ``standard``, most of a
    search whose tight bands sample nothing."""

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


def probe(request: Request, source: SegmentSource, band: float) -> BandProbe:
    """How many six-bars meet ``request`` at ``band`` (rad) in the sampled query without
    refinement (``top`` cut to :func:`needed`: the count is all the search uses; an empty
    answer's diagnosis skips the stored dwells, :class:`_Counting`)."""
    asked = dataclasses.replace(request, band=band, refine=False, complete=False, top=needed(request))
    return BandProbe(band, len(answer(asked, _Counting(source)).candidates))


def ladder(ceiling: float, floor: float) -> np.ndarray:
    """Bands from ``ceiling`` down to ``floor`` (rad), :data:`LADDER` per decade, both ends in."""
    steps = max(1, math.ceil(LADDER * math.log10(ceiling / floor) - 1e-9))
    return np.geomspace(ceiling, floor, steps + 1)


def tightest_band(
    request: Request, count: Callable[[float], BandProbe], *, floor: float = FLOOR
) -> tuple[float | None, tuple[BandProbe, ...]]:
    """The tightest band (rad) in [``floor``, ``request.band``] at which ``count(band).met``
    reaches :func:`needed`, within :data:`RESOLUTION` (None if no probe does), and the probes.

    The ladder (:func:`ladder`) is probed from the floor up and stops at the first rung that
    meets; a bisection on log(band) between that rung and the next tighter one follows.
    """
    need = needed(request)
    ceiling = request.band
    if ceiling <= floor:
        found = count(ceiling)
        return (ceiling if found.met >= need else None), (found,)
    probes: list[BandProbe] = []

    def meets(band: float) -> bool:
        probes.append(count(float(band)))
        return probes[-1].met >= need

    rungs = ladder(ceiling, floor)[::-1]  # tightest first
    hit = next((k for k, band in enumerate(rungs) if meets(band)), None)
    if hit is None:
        return None, tuple(probes)
    good = float(rungs[hit])
    if hit == 0:
        return good, tuple(probes)
    bad = float(rungs[hit - 1])
    while good / bad > RESOLUTION:
        middle = math.sqrt(good * bad)
        if meets(middle):
            good = middle
        else:
            bad = middle
    return good, tuple(probes)


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


def answer_tightest(
    request: Request,
    source: SegmentSource,
    *,
    answer_at: Callable[[Request], QueryResult] | None = None,
    floor: float = FLOOR,
) -> BandAnswer:
    """``request`` answered at the tightest band it can be met at (:func:`tightest_band`,
    searched from ``request.band`` down to ``floor``, rad), or at ``request.band`` if no
    probe meets it.

    ``answer_at`` answers the final request (default :func:`synth.query.answer` on
    ``source``; a caller passes its own to add a progress bar or worker processes to a
    complete search).
    """
    band, probes = tightest_band(request, lambda b: probe(request, source, b), floor=floor)
    final = request if band is None else dataclasses.replace(request, band=band)
    result = (answer_at or (lambda r: answer(r, source)))(final)
    return BandAnswer(result, final.band, band is not None, probes, reference_dwells(final, result))


def tighter_band(request: Request, source: SegmentSource, factor: float = 10.0) -> BandProbe | None:
    """One probe at ``request.band / factor`` (not below :data:`FLOOR`): the probe if enough
    six-bars (:func:`needed`) meet the request there, else None. What a query at a fixed band
    names as the stiller rest ``--band auto`` would look for."""
    band = max(request.band / factor, FLOOR)
    if band >= request.band:
        return None
    found = probe(request, source, band)
    return found if found.met >= needed(request) else None
