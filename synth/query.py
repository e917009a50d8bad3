"""The synthesis query as a library stage: a :class:`~synth.candidates.Request` in, ranked
six-bars out (pure: no click, no ORM, no I/O — segments are read through a
:class:`SegmentSource`, which ``db.queries.AtlasSource`` implements over an engine).

Pipeline (:func:`answer`): the segments whose stored dwell (an arc's dwell key) lies near the
request (:meth:`SegmentSource.select_segments`) → output dyads fitted to every segment in one
batch per kind (``synth.dyad``: RPR on straight segments, RPR at the lines' intersection for
double Ball points, RRR on arcs) → a necessary screen on the crank grid
(:func:`~synth.candidates.screen`) → the full figures of the survivors from the exact
simulation (:func:`~synth.figures.sixbar_figures`) → the six-bars that meet the request →
ranked (:func:`~synth.candidates.rank`), one per segment and output type and one of a mirror
pair → with ``request.refine``, the top ones refined by a local optimisation with exact
simulation in the loop (:func:`synth.refine.refine`) and ranked again. Lengths are
crank-normalised until the end, then scaled to ``request.crank``. ``--output any`` (one dwell)
runs the pipeline once as RPR and once as RRR and ranks the union of the two answers.

That pipeline runs on a sample of the atlas (:func:`select`: per level, the stored rows
nearest a target — a line's dwell, an arc's dwell key, :mod:`synth.dwell_key` — a budget;
a sparse answer samples wider, moves the fits' pivots, then reads deeper along the arcs).
With ``request.complete`` it runs instead on every stored segment at every level
(:func:`search`), pruned only by conditions no meeting six-bar can fail, the prescreen (:func:`prescreen`) among them: the complete answer.

When fewer than ``FILL`` six-bars meet the request (and refinement is on), the nearest misses
(of the sample's fits and of the fits to rests twice as long the moved pivots were taken from;
``MISSES`` at a time, by the sum of their excesses over the limits, for at most
``MISS_ROUNDS`` rounds while fewer than ``FILL`` meet) are refined toward it
(the refinement's reach: a CMA-ES in a wider trust region), and those that then meet it join
the answer; if nothing meets it even so, the result carries a
:class:`NoMatch`: how many fitted six-bars each constraint
rejected, the nearest six-bar and the request that it would meet. Without refinement the same
:class:`NoMatch` comes cheaper (:func:`diagnose_by_bounds`): only the six-bars whose dwell
decides a count or the nearest get their dwell ends refined.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from synth.candidates import (
    REFINED_MARK,
    Candidate,
    Request,
    candidate_dimensions,
    candidate_id,
    dwell_runs,
    parse_candidate_id,
    rank,
    round_dimensions,
    screen,
    with_dimensions,
)
from synth.dwell_key import arc_key_target
from synth.figures import SixBarFigures, figures_with_dwell_bounds, footprints, sixbar_figures
from synth.output_range import Dwell
from synth.segment_rows import SegmentBatch, SegmentRow
from synth.sixbar import OutputDyad, SixBar, SixBars, crank_grid
from synth.sixbar import simulate as simulate_motion

__all__ = [
    "CONSTRAINTS",
    "DwellWindow",
    "NoMatch",
    "QueryResult",
    "RebuildError",
    "SearchCount",
    "SegmentRow",
    "SegmentSource",
    "answer",
    "fit_key",
    "rebuild",
    "search",
    "search_batch",
    "search_many",
]

#: Crank samples of the exact simulation (0.5°); the figures refine beyond it.
SAMPLES = 720
#: Crank samples of the path the dyads are fitted to (1°): a fitted swing is within ~0.01° of
#: the simulated one, which is what the request is checked against.
FIT_SAMPLES = 360
#: Segments taken from the atlas per kind and tolerance level, closest to that level's target first.
PER_LEVEL = 10
#: With refinement on, a sparse answer (fewer than FILL six-bars) samples again, this many
#: times wider (the no-refinement query keeps PER_LEVEL).
WIDER = 3
#: Last, if still sparse after the moved pivots, this many times PER_LEVEL segments per level
#: of the kinds in DEEPER_KINDS: arcs (RRR), whose dwell key ranks them (``synth.dwell_key``)
#: — the longest rests (150° at swings of 20°–30° on ``standard``) lie a few hundred rows
#: deep —, and double lines, whose rests the stored dwell predicts less well (two rests of 90°
#: on ``standard``: 1 six-bar from the narrower samples, 3 with this read). Single lines are
#: not read deeper: their sparse answers (150° at a 90° swing) are filled from refined near
#: misses, which a deeper read would stop at 3 (FILL) where they reach 10.
DEEPER = 10
DEEPER_KINDS = ("arc", "double_line")
#: Output link lengths (crank lengths) tried in the band conversion of ``_select``.
REACHES = (0.8, 1.5, 3.0)
#: Nearest misses refined toward a request that fewer than FILL six-bars met, this many at a
#: time (nearest first), for at most MISS_ROUNDS rounds while the answer still holds fewer.
MISSES = 16
MISS_ROUNDS = 2
#: An answer with fewer candidates than this (or than ``--top``) is topped up from the
#: nearest misses, refined to meet the request (with refinement on).
FILL = 3
#: After the wider sample, while it holds fewer than --top, each fit's output pivot moved off
#: the fitted one (:func:`reseat`): at most this many moved pivots per fit, nearest first.
RESEAT_PER_FIT = 1
#: Moved six-bars simulated at a time; the reseat stops once --top segments are answered.
RESEAT_BATCH = 128
#: A creeping rest is shorter than the fitted one: the segments the sample would take for
#: these multiples of the requested dwell are moved too.
RESEAT_LONGER = (2.0, 4.0)
#: The request's constraints, in the order a no-match names them (see :func:`violations`).
CONSTRAINTS = ("assembly", "dwell", "swing", "step", "transmission", "link_ratio", "arm", "clearance", "acceleration")


# --------------------------------------------------------------------------------------------
# What the query reads
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class DwellWindow:
    """Stored rows wanted: at tolerance ``level`` (None: any level), with a dwell key in [low,
    high], the ``limit`` closest to ``target``. A line's dwell key is its dwell angle (rad), an
    arc's the dwell angle × its excursion^¼ (:mod:`synth.dwell_key`)."""

    level: int | None
    low: float
    high: float
    target: float
    limit: int


class SegmentSource(Protocol):
    """Where the query reads segments from (an atlas; ``db.queries.AtlasSource``)."""

    def tolerance_levels(self) -> list[tuple[int, float]]:
        """(level, path tolerance in crank lengths) pairs, in level order."""

    def select_segments(self, kinds: tuple[str, ...], windows: Sequence[DwellWindow], *,
                        min_transmission: float, max_length: float, min_radius_ratio: float) -> list[SegmentRow]:
        """Segments of ``kinds`` whose dwell key lies in one of ``windows`` (each window's
        closest first, a segment once, at the level of its first match), of linkages whose
        transmission angle stays ≥ ``min_transmission`` (rad) and whose links are ≤
        ``max_length`` (cranks); an arc's radius in [longest link · ``min_radius_ratio``,
        ``max_length``]."""

    def segment(self, segment_id: int, level: int) -> SegmentRow | None:
        """The segment with its dwell row(s) at ``level``; None if the atlas has no such
        segment; a row with empty ``parts`` if it has no dwell at that level."""

    def nearest_dwell_angles(self, kinds: tuple[str, ...], target: float) -> tuple[float | None, float | None]:
        """The stored dwell angles (rad) of ``kinds`` just below and just above ``target``."""

    def scan_segments(self, kind: str, level: int, *, min_transmission: float, max_length: float,
                      min_radius_ratio: float, batch: int) -> Iterator[SegmentBatch]:
        """Every segment of ``kind`` with a dwell at ``level`` (filtered as in
        :meth:`select_segments`), in batches of up to ``batch`` rows as columns."""

    def count_segments(self, kind: str, level: int, *, min_transmission: float, max_length: float,
                       min_radius_ratio: float) -> int:
        """How many segments :meth:`scan_segments` yields."""


# --------------------------------------------------------------------------------------------
# What the query answers
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class NoMatch:
    """Why nothing met a request.

    Attributes
    ----------
    fitted : int
        Fitted six-bars examined (0: no stored segment was near the request).
    rejected : dict
        Per constraint of :data:`CONSTRAINTS`, how many of them it rejected (a six-bar can
        fail several; ``assembly`` counts those that do not assemble over the turn, toggle or
        revolve, which are not checked further).
    nearest : Candidate or None
        The six-bar closest to meeting the request (the smallest sum of its excesses over the
        limits, angles in degrees, the link ratio in percent of the limit), in the user's units.
    would_meet : Request or None
        The request loosened just enough for ``nearest`` to meet it.
    """

    fitted: int
    rejected: dict[str, int]
    nearest: Candidate | None
    would_meet: Request | None
    #: The one constraint in the way, with a figure: ``(constraint, best, limit)`` where
    #: ``constraint`` is the one the nearest six-bar that misses a single constraint misses,
    #: and ``best`` the best figure on it of every fitted six-bar that meets all the others —
    #: dwell, swing and step: the value nearest the request's (°); transmission: the largest
    #: (°); link ratio, acceleration: the smallest; arm, clearance: the largest (crank
    #: lengths) — against the request's ``limit`` (the requested value for dwell, swing and
    #: step). None when no fitted six-bar misses one constraint alone (or the diagnosis was
    #: made from bounds, :func:`diagnose_by_bounds`). With nothing fitted: the transmission
    #: angle, if the sample without its limit holds segments, and the best four-bar's among
    #: them (:func:`_unfitted_reach`).
    reach: tuple[str, float, float] | None = None

    @property
    def failed(self) -> str | None:
        """The constraint that rejected the most six-bars (None if nothing was fitted)."""
        if not self.fitted:
            return None
        return max(CONSTRAINTS, key=lambda k: (self.rejected.get(k, 0), -CONSTRAINTS.index(k)))


@dataclass(frozen=True, slots=True)
class QueryResult:
    request: Request
    candidates: list[Candidate]
    considered: int  #: segments fitted
    simulated: int  #: six-bars simulated
    #: stored dwell angles (rad) around the request when nothing was fitted (else None, None)
    nearest: tuple[float | None, float | None]
    seconds: dict[str, float]
    no_match: NoMatch | None = None
    #: six-bars refined (the returned ones, or the nearest misses when nothing met the
    #: request), and how many of them came out better (the others are kept unchanged)
    refined: tuple[int, int] = (0, 0)
    #: True when nothing in the atlas met the request and the candidates are refined near misses
    from_misses: bool = False
    #: how many of the candidates are near misses refined to meet the request (see FILL)
    misses_met: int = 0
    #: how many of the candidates are six-bars whose output pivot was moved off the fitted one
    #: (:func:`reseat`; their ids carry the dimensions)
    reseated: int = 0


class RebuildError(ValueError):
    """A candidate id that cannot be rebuilt from this atlas (message names the id)."""


# --------------------------------------------------------------------------------------------
# Stages
# --------------------------------------------------------------------------------------------


def kinds_for(request: Request) -> tuple[str, ...]:
    """Segment kinds a request draws on."""
    if request.dwells == 2:
        return ("double_line",)
    return {"rpr": ("line",), "rrr": ("arc",), "any": ("line", "arc")}[request.output]


def select(source: SegmentSource, request: Request, kinds: tuple[str, ...],
           per_level: int = PER_LEVEL) -> list[SegmentRow]:
    """Segments worth fitting, per kind and tolerance level (each kind's rows in the order of
    its windows, :func:`_line_windows` and :func:`_arc_windows`). Only constraints the four-bar
    alone decides are applied here (crank = 1, the shortest link); an arc's radius becomes the
    rod, which must not be the link that breaks the ratio."""
    rows = []
    for kind in kinds:
        windows = (_arc_windows if kind == "arc" else _line_windows)(source, request, per_level)
        rows += source.select_segments((kind,), windows, min_transmission=request.min_transmission,
                                       max_length=request.max_link_ratio,
                                       min_radius_ratio=1.0 / request.max_link_ratio)
    return rows


def _line_windows(source: SegmentSource, request: Request, per_level: int) -> list[DwellWindow]:
    """Stored dwells of lines (and double lines) worth fitting.

    A six-bar's dwell is measured with an output band (an angle), a segment's with a path band
    ε (a length): the output stands still while the coupler point stays within about
    ε* = R·band/2 of the segment's line, R the slot's reach, a few cranks. Dwells grow like
    ε^¼ (four-point contact), so at level ε_ℓ the segment dwell that gives the requested
    six-bar dwell is about dwell·(ε_ℓ/ε*)^¼; each level is searched around its own target for
    each of :data:`REACHES`, generously — the simulation decides. ``per_level`` segments are
    taken per level and target (twice that closest to the request itself)."""
    width = request.dwell_tol + math.radians(10.0)
    windows = [DwellWindow(None, request.dwell - width, request.dwell + width, request.dwell, 2 * per_level)]
    for (level, eps), reach in itertools.product(source.tolerance_levels(), REACHES):
        target = request.dwell * (eps / (reach * request.band / 2)) ** 0.25
        width = request.dwell_tol + 0.2 * target
        windows.append(DwellWindow(level, target - width, target + width, target, per_level))
    return windows


def _arc_windows(source: SegmentSource, request: Request, per_level: int) -> list[DwellWindow]:
    """Dwell keys of arcs worth fitting: per level, the keys nearest the one that predicts the
    requested dwell at the requested swing and band (:func:`synth.dwell_key.arc_key_target`;
    the rocker is implied by the swing, so no reaches are guessed), as many as
    :func:`_line_windows` takes per level, within a factor of 2 of it."""
    windows = []
    for level, eps in source.tolerance_levels():
        target = arc_key_target(request.dwell, request.swing, request.band, eps)
        windows.append(DwellWindow(level, target / 2, 2 * target, target, len(REACHES) * per_level))
    return windows


@dataclass(frozen=True, slots=True)
class Fitted:
    """One fitted output dyad: the segment row it came from, the output tag of its id
    (``rpr``, ``rrr``, ``dbl``), the fit's slot, the dyad (crank-normalised) and, for RRR,
    where the moving pivot rests during the dwell."""

    row: SegmentRow
    output: str
    slot: int
    dyad: OutputDyad
    rest: complex | None = None
    #: The dyad was moved off the fit's own (:func:`reseat`): the id carries the dimensions.
    moved: bool = False

    def sixbar(self) -> SixBar:
        r = self.row
        return SixBar(1.0, r.b, r.c, r.d, r.branch, r.u, r.v, self.dyad)


def _paths(rows: SegmentBatch | Sequence[SegmentRow], phi: np.ndarray) -> np.ndarray:
    """The coupler-point paths of ``rows`` (a batch, or rows of any kinds) on the crank grid ``phi``."""
    from kinematics.fourbar import fourbar_motion

    if isinstance(rows, SegmentBatch):
        b, c, d, branch, uv = rows.b, rows.c, rows.d, rows.branch, rows.coupler_point()
    else:
        b, c, d, branch = (np.array([getattr(r, name) for r in rows]) for name in ("b", "c", "d", "branch"))
        uv = np.array([complex(r.u, r.v) for r in rows])
    motion = fourbar_motion(1.0, b[:, None], c[:, None], d[:, None], phi, branch[:, None], order=0)
    return motion.A + motion.e_theta * uv[:, None]


def fit(request: Request, rows: Sequence[SegmentRow], kind: str) -> list[Fitted]:
    """Every dyad found for ``rows`` (all of segment kind ``kind``), in row and slot order."""
    return _fitted(rows, _fit_arrays(request, rows, kind)[0])


@dataclass(frozen=True, slots=True)
class _FitArrays:
    """The dyads :func:`fit` finds, one entry per dyad in row and slot order, before any
    object is made (most of a complete search's fits fail the prescreen): the id's output tag,
    each dyad's row (index into the rows fitted) and slot, its pivot, its stretch's line point
    or arc centre (part 0: where an RRR's Q rests; the prescreen measures angles from it) and
    (RRR) rocker, rod and branch."""

    output: str
    index: np.ndarray
    slot: np.ndarray
    pivot: np.ndarray
    point: np.ndarray
    rocker: np.ndarray | None = None
    rod: np.ndarray | None = None
    branch: np.ndarray | None = None


def _fit_arrays(request: Request, rows: Sequence[SegmentRow], kind: str) -> tuple[_FitArrays, np.ndarray]:
    """The dyads found for ``rows`` (all of kind ``kind``; a :class:`SegmentBatch` or a list of
    rows) and the rows' coupler-point paths on the fit's crank grid."""
    from synth.dyad import fit_rpr, fit_rrr, rpr_double

    phi = crank_grid(FIT_SAMPLES)
    none = np.zeros(0, np.int64)
    if not len(rows):
        empty = np.zeros(0, complex)
        return _FitArrays(_OUTPUT_OF[kind], none, none, empty, empty), np.zeros((0, FIT_SAMPLES), complex)
    batch = SegmentBatch.of_rows(rows, kind)
    paths = _paths(batch, phi)
    point = batch.point(0)
    if kind == "double_line":
        two = np.flatnonzero(batch.has_parts == 2)  # a double line holds both stretches at the level
        found = rpr_double((point[two], batch.part(0, "direction")[two]),
                           (batch.point(1)[two], batch.part(1, "direction")[two]))
        (hit,) = np.nonzero(found.found)
        index = two[hit]
        return _FitArrays("dbl", index, np.zeros_like(index), found.pivot[hit], point[index]), paths
    interval = (batch.part(0, "start"), batch.part(0, "end"))
    if kind == "line":
        found = fit_rpr(point, batch.part(0, "direction"), phi, paths, interval, request.swing)
        index, slot = np.nonzero(found.found)  # row-major: row, then slot order
        return _FitArrays("rpr", index, slot, found.pivot[index, slot], point[index]), paths
    found = fit_rrr(point, batch.part(0, "radius"), phi, paths, interval, request.swing, request.min_transmission,
                    keep=2)
    index, slot = np.nonzero(found.found)
    return _FitArrays("rrr", index, slot, found.pivot[index, slot], point[index], found.rocker[index, slot],
                      found.rod[index, slot], found.branch[index, slot]), paths


_OUTPUT_OF = {"line": "rpr", "arc": "rrr", "double_line": "dbl"}


def _fitted(rows: Sequence[SegmentRow], found: _FitArrays, keep: np.ndarray | None = None) -> list[Fitted]:
    """The :class:`Fitted` of ``found`` (of those ``keep`` marks)."""
    if not found.index.size:
        return []
    pick = slice(None) if keep is None else np.flatnonzero(keep)
    index, slot, pivot = (x[pick].tolist() for x in (found.index, found.slot, found.pivot))
    if found.output != "rrr":
        return [Fitted(rows[i], found.output, k, OutputDyad.rpr(D)) for i, k, D in zip(index, slot, pivot)]
    rocker, rod, branch, rest = (x[pick].tolist() for x in (found.rocker, found.rod, found.branch, found.point))
    return [Fitted(rows[i], "rrr", k, OutputDyad.rrr(D, L, rho, int(br)), Q)
            for i, k, D, L, rho, br, Q in zip(index, slot, pivot, rocker, rod, branch, rest)]


def prescreen(request: Request, found: _FitArrays, paths: np.ndarray) -> np.ndarray:
    """Which of the dyads ``found`` (:func:`_fit_arrays`, in its order) may meet
    ``request``, from the paths they were fitted to (``paths``, exact coupler-point positions on
    the fit's crank grid), before any simulation and before any object is made for them: the
    output angle on that grid in closed form (RPR: the slot's direction P − D; RRR: the
    rocker's, Q from the loop's circle intersection), then tests no six-bar meeting the
    request can fail: it assembles at every sample (RRR), and its sampled output angle passes
    :func:`synth.candidates.output_may_meet` (swing, and the dwell in runs of samples within
    the band). The angles are measured from the direction of the stretch's line point (RPR) or
    arc centre (RRR) seen from D, and unwrapped along the turn."""
    if not found.index.size:
        return np.zeros(0, bool)
    links = None if found.output != "rrr" else tuple(x[:, None] for x in (found.rod, found.rocker, found.branch))
    return _output_screen(request, paths[found.index], found.pivot[:, None], found.point[:, None], links)


def _reference(f: Fitted) -> complex:
    """Where the output angle is measured towards: an RRR's rest, else the stretch's line point."""
    return f.rest if f.rest is not None else complex(f.row.parts[0][2], f.row.parts[0][3])


def _rrr_links(fitted: Sequence[Fitted]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rod, rocker and branch of RRR fits, shaped (n, 1) to broadcast over the crank grid."""
    return tuple(np.array([getattr(f.dyad, k) for f in fitted])[:, None] for k in ("rod", "rocker", "branch"))


def _output_screen(request: Request, P: np.ndarray, D: np.ndarray, rest: np.ndarray,
                   rrr: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """:func:`prescreen`'s tests for coupler points ``P`` (n, M) on the fit's crank grid,
    output pivots ``D`` and references ``rest`` (n, 1): a slot's angle (``rrr`` None) or, with
    ``rrr`` = (rod, rocker, branch), the rocker's, Q from the loop's circle intersection, which
    must assemble at every sample; then :func:`synth.candidates.output_may_meet`'s tests.
    Compiled, one pass per dyad (:mod:`synth.prescreen_kernel`). Shape (n,)."""
    from synth.prescreen_kernel import screen_outputs  # numba: imported on first use

    shortest, longest = dwell_runs(request, P.shape[-1])
    return screen_outputs(P, D, rest, rrr, request.swing, request.swing_tol, request.band, shortest, longest)


def reseat(request: Request, fitted: Sequence[Fitted]) -> list[Fitted]:
    """Every fit's output pivot moved off the fitted one (:func:`synth.dyad.pivots_around`:
    an RPR's slot pivot off its line, a double line's off the lines' crossing, an RRR's rocker
    pivot with its rocker and rod kept), the moved six-bars that pass :func:`prescreen`, at
    most ``RESEAT_PER_FIT`` per fit (the nearest pivots first). The fit puts the pivot where the
    stretch is seen straight on (or the rest at the arc's centre); a shorter dwell than that
    gives wants another — the rest then creeps — and the atlas yields every pivot
    (docs/complete-query.md §1). Their ids carry the dimensions."""
    from synth.dyad import pivots_around

    if not fitted:
        return []
    paths = _paths([f.row for f in fitted], crank_grid(FIT_SAMPLES))
    rest = np.array([_reference(f) for f in fitted])
    reach = np.array([f.dyad.rocker if f.dyad.kind == "RRR" else
                      np.mean([abs(f.dyad.pivot - complex(p[2], p[3])) for p in f.row.parts]) for f in fitted])
    pivots = pivots_around(np.array([f.dyad.pivot for f in fitted]), reach)  # (n, K)
    rrr = np.array([f.dyad.kind == "RRR" for f in fitted])
    links = _rrr_links(fitted)  # every fit's (an RPR's are unused), read once

    def screen(i: np.ndarray, k: np.ndarray, every: int) -> np.ndarray:
        """The screen of the pivots (i, k) on every ``every``-th sample of the grid (a
        uniform grid too: the same necessary tests, weaker), in blocks of one kind."""
        ok = np.zeros(i.size, bool)
        for kind in (False, True):
            of_kind = np.flatnonzero(rrr[i] == kind)
            for b in (of_kind[s : s + _BLOCK] for s in range(0, of_kind.size, _BLOCK)):
                fits = i[b]
                ok[b] = _output_screen(request, paths[fits, ::every], pivots[fits, k[b]][:, None], rest[fits, None],
                                       tuple(x[fits] for x in links) if kind else None)
        return ok

    # first on a 4° grid, then the survivors on the fit's 1° grid
    i, k = (x.ravel() for x in np.indices(pivots.shape))
    coarse = screen(i, k, _COARSE)
    passed = np.zeros(pivots.shape, bool)
    passed[i[coarse], k[coarse]] = screen(i[coarse], k[coarse], 1)
    keep = passed & (np.cumsum(passed, axis=1) <= RESEAT_PER_FIT)  # the first passes of each fit
    # a search, not a bound: the screen ran on the dimensions before the rounding to the id's.
    # Where a moved RRR rests is not known before its simulation (its reference direction,
    # the arc's centre, stays the row's).
    return [_as_stored(dataclasses.replace(fitted[i], dyad=dataclasses.replace(fitted[i].dyad, pivot=complex(pivots[i, k])),
                                           rest=None, moved=True))
            for i, k in zip(*np.nonzero(keep))]


def _no_worse_than_fits(request: Request, moved: list[Candidate], answered: list[Candidate]) -> list[Candidate]:
    """The ``moved`` six-bars (:func:`reseat`) that may stand for their fit: a moved pivot is a
    change of the fit it was moved from (its ``refined_from``), kept only if no worse on every
    objective of the ranking (:func:`synth.refine.better_or_equal`) where that fit met the
    request itself (it is then among the ``answered``); beside a fit that missed, it is new."""
    from synth.refine import better_or_equal

    met = {c.id: c.figures for c in answered}
    return [c for c in moved
            if (fit_ := met.get(c.id.split(REFINED_MARK)[0])) is None or better_or_equal(request, c.figures, fit_)]


#: Pivots screened at a time by :func:`reseat` (n × samples temporaries), and its coarse
#: screen's sample step (every 4th of the fit's 1° grid).
_BLOCK = 8192
_COARSE = 4


def _with_origins(request: Request, found: list[Candidate], fitted: Sequence[Fitted],
                  known: dict[int, SixBarFigures]) -> list[Candidate]:
    """Reseated candidates (:func:`reseat`) with ``refined_from``: the figures of the fit they
    were moved from (``known`` by the fit's ``id``, or computed), in the user's units; and an
    RRR's ``dwell_position`` from its simulation."""
    if not found:
        return []
    base = {candidate_id(f.row.segment_id, f.output, f.slot, f.row.level, request.swing): f for f in fitted}
    origins = {c.id.split(REFINED_MARK)[0] for c in found}
    todo = [base[k] for k in origins if id(base[k]) not in known]
    if todo:
        known = {**known, **dict(zip(map(id, todo), _figures(request, [f.sixbar() for f in todo], footprint=False)))}
    return [dataclasses.replace(c, refined_from=_scaled_figures(known[id(base[c.id.split(REFINED_MARK)[0]])], request.crank),
                                dwell_position=_rest(c.sixbar, c.figures))
            for c in found]


def _as_stored(fitted: Fitted) -> Fitted:
    """``fitted`` with the dimensions its id will hold (:func:`~synth.candidates.round_dimensions`),
    so that its figures are the ones a rebuild from the id gives."""
    sb = round_dimensions(fitted.sixbar())
    row = dataclasses.replace(fitted.row, b=sb.b, c=sb.c, d=sb.d, u=sb.u, v=sb.v)
    return dataclasses.replace(fitted, row=row, dyad=sb.dyad)


def violations(request: Request, f: SixBarFigures) -> dict[str, float]:
    """How far the figures ``f`` (crank-normalised) miss each constraint of ``request``: 0 where
    met. ``assembly`` is 1 for a six-bar that does not assemble over the turn, toggles or
    revolves, or has fewer dwells than asked — two rests not separated by the swing tolerance
    are one (:func:`_missing_dwell`) — (then nothing else is measured); the angles'
    excesses in degrees; the link ratio's in percent of the limit."""
    out = dict.fromkeys(CONSTRAINTS, 0.0)
    if not f.acceptable or _missing_dwell(request, f):
        out["assembly"] = 1.0
        return out
    out["dwell"] = max(_dwell_excess(request, d.angle) for d in f.dwells[: request.dwells])
    if request.swing is not None:
        out["swing"] = max(0.0, math.degrees(abs(f.swing - request.swing) - request.swing_tol))
    if request.step is not None:
        out["step"] = max(0.0, math.degrees(abs(f.step - request.step) - request.swing_tol))
    out["transmission"] = max(0.0, math.degrees(request.min_transmission
                                                - min(f.transmission_fourbar, f.transmission_output)))
    out["link_ratio"] = max(0.0, 100.0 * (f.link_ratio / request.max_link_ratio - 1.0))
    b = f.build
    if b is not None:
        # shortfalls in crank lengths (the figures are crank-normalised), excess in rad/s²
        out["arm"] = 0.0 if b.arm is None else max(0.0, request.min_arm - b.arm)
        out["clearance"] = max(0.0, request.min_clearance - b.clearance)
        if request.max_accel is not None:
            out["acceleration"] = max(0.0, b.dynamics(request.rpm)[1] - request.max_accel)
    return out


def _missing_dwell(request: Request, f: SixBarFigures) -> bool:
    """Fewer dwells than ``request`` asks for, two rests counting as two only with motion
    between them (:meth:`~synth.figures.SixBarFigures.rests_apart` at the swing tolerance)."""
    if len(f.dwells) < request.dwells:
        return True
    return request.dwells == 2 and not f.rests_apart(request.swing_tol)


def _dwell_excess(request: Request, angle: float) -> float:
    """How far (°) a dwell of ``angle`` (rad) is outside the request's dwell ± tolerance."""
    return max(0.0, math.degrees(abs(angle - request.dwell) - request.dwell_tol))


def meets(request: Request, f: SixBarFigures) -> bool:
    """Whether the figures ``f`` (crank-normalised) meet ``request`` and its constraints."""
    if not f.acceptable or _missing_dwell(request, f):
        return False
    if any(abs(d.angle - request.dwell) > request.dwell_tol for d in f.dwells[: request.dwells]):
        return False
    if request.swing is not None and abs(f.swing - request.swing) > request.swing_tol:
        return False
    if request.step is not None and abs(f.step - request.step) > request.swing_tol:
        return False
    if min(f.transmission_fourbar, f.transmission_output) < request.min_transmission:
        return False
    b = f.build
    if b is not None:
        if (b.arm is not None and b.arm < request.min_arm) or b.clearance < request.min_clearance:
            return False
        if request.max_accel is not None and b.dynamics(request.rpm)[1] > request.max_accel:
            return False
    return f.link_ratio <= request.max_link_ratio


def _scaled_figures(f: SixBarFigures, scale: float) -> SixBarFigures:
    return dataclasses.replace(f, footprint=f.footprint * scale**2, bounds=tuple(x * scale for x in f.bounds),
                               build=None if f.build is None else f.build.scaled(scale))


def _candidate(request: Request, fitted: Fitted, f: SixBarFigures) -> Candidate:
    r = fitted.row
    return Candidate(
        id=candidate_id(r.segment_id, fitted.output, fitted.slot, r.level, request.swing,
                        fitted.sixbar() if fitted.moved else None),
        segment_id=r.segment_id,
        sixbar=fitted.sixbar().scaled(request.crank),
        figures=_scaled_figures(f, request.crank),
        dwell_position=None if fitted.rest is None else fitted.rest * request.crank,
    )


def _figures(request: Request, sixbars: list[SixBar], *, footprint: bool = True) -> list[SixBarFigures]:
    return sixbar_figures(SixBars.from_sixbars(sixbars), band=request.band, dwell_length=request.dwell,
                          dwells=request.dwells, samples=SAMPLES, footprint=footprint, leave=request.swing_tol)


def simulate(request: Request, fitted: Sequence[Fitted]) -> tuple[list[Candidate], int]:
    """The candidates among ``fitted`` that meet ``request`` (unranked), and how many six-bars
    were simulated."""
    screened, n = _screened_figures(request, fitted)
    return [_candidate(request, f, fig) for f, fig in screened if meets(request, fig)], n


def _screened_figures(request: Request, fitted: Sequence[Fitted]) -> tuple[list[tuple[Fitted, SixBarFigures]], int]:
    """The six-bars among ``fitted`` that pass the screen, with their full figures (the
    footprint, a ranking figure, only for those that meet ``request``; 0 for the others), and
    how many six-bars were simulated (screened)."""
    if not fitted:
        return [], 0
    sixbars = [f.sixbar() for f in fitted]
    # the full figures only for six-bars that pass the (necessary) test on the crank grid
    passed = screen(request, SixBars.from_sixbars(sixbars), SAMPLES)
    kept = [(f, sb) for f, sb, p in zip(fitted, sixbars, passed) if p]
    if not kept:
        return [], len(passed)
    figures = _figures(request, [sb for _, sb in kept], footprint=False)
    meeting = [k for k, fig in enumerate(figures) if meets(request, fig)]
    if meeting:  # the same positions as the figures' own simulation: the same areas
        areas = footprints(SixBars.from_sixbars([kept[k][1] for k in meeting]), SAMPLES)
        for k, area in zip(meeting, areas):
            figures[k] = dataclasses.replace(figures[k], footprint=float(area))
    return [(f, fig) for (f, _), fig in zip(kept, figures)], len(passed)


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


def _misses(request: Request, fitted: Sequence[Fitted], known: dict[int, SixBarFigures] | None = None
            ) -> list[tuple[float, Fitted, SixBarFigures, dict]]:
    """Every fitted six-bar with its figures (no footprint; ``known``: figures at hand by
    ``id`` of the fit) and excesses over the limits (:func:`violations`), nearest first by
    their sum (inf for one that does not assemble)."""
    if not fitted:
        return []
    known = known or {}
    rest = [f for f in fitted if id(f) not in known]
    computed = dict(zip(map(id, rest), _figures(request, [f.sixbar() for f in rest], footprint=False))) if rest else {}
    out = []
    for fit_ in fitted:
        fig = known[id(fit_)] if id(fit_) in known else computed[id(fit_)]
        excess = violations(request, fig)
        out.append((_total(excess), fit_, fig, excess))
    return sorted(out, key=lambda t: t[0])  # stable: ties keep the fit order


def _total(excess: dict[str, float]) -> float:
    """How far a six-bar is from meeting a request: the sum of its excesses (inf if it does not
    assemble)."""
    return math.inf if excess["assembly"] else sum(excess.values())


def diagnose(request: Request, fitted: Sequence[Fitted],
             misses: list[tuple[float, Fitted, SixBarFigures, dict]] | None = None) -> NoMatch:
    """Why none of ``fitted`` meets ``request`` (see :class:`NoMatch`); simulates them all
    unless their :func:`_misses` are given."""
    rejected = dict.fromkeys(CONSTRAINTS, 0)
    if not fitted:
        return NoMatch(0, rejected, None, None)
    misses = _misses(request, fitted) if misses is None else misses
    for _, _, _, excess in misses:
        for k, x in excess.items():
            rejected[k] += x > 0
    best_total, fit_, fig, _ = misses[0]
    found = _no_match(request, len(fitted), rejected, None if best_total == math.inf else (fit_, fig))
    return dataclasses.replace(found, reach=_reach(request, misses))


def _unfitted_reach(request: Request, source: SegmentSource, kinds: tuple[str, ...]) -> tuple[str, float, float] | None:
    """:attr:`NoMatch.reach` of a request whose sample held no segment: the four-bars'
    transmission angle, when the sample without that limit holds segments — with the largest
    smallest transmission angle (°) among their four-bars (RRR 10° at a 30° swing on
    ``standard``: the 49 arcs whose keys predict it all belong to four-bars below 10°)."""
    if request.min_transmission <= 0:
        return None
    rows = select(source, dataclasses.replace(request, min_transmission=0.0), kinds)
    if not rows:
        return None
    return ("transmission", math.degrees(max(r.fourbar_transmission_min for r in rows)),
            math.degrees(request.min_transmission))


def _reach(request: Request, misses: list[tuple[float, Fitted, SixBarFigures, dict]]
           ) -> tuple[str, float, float] | None:
    """:attr:`NoMatch.reach` of ``misses`` (:func:`_misses`, nearest first)."""
    alone = [(next(k for k, x in excess.items() if x > 0), fig) for total, _, fig, excess in misses
             if total < math.inf and sum(x > 0 for x in excess.values()) == 1]
    if not alone:
        return None
    key = alone[0][0]
    figs = [fig for k, fig in alone if k == key]
    deg = math.degrees

    def nearest(values: list[float], target: float) -> float:
        return deg(min(values, key=lambda v: abs(v - target)))

    if key == "dwell":
        return key, nearest([d.angle for f in figs for d in f.dwells[: request.dwells]], request.dwell), deg(request.dwell)
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


def _no_match(request: Request, fitted: int, rejected: dict[str, int],
              nearest: tuple[Fitted, SixBarFigures] | None) -> NoMatch:
    if nearest is None:
        return NoMatch(fitted, rejected, None, None)
    fit_, fig = nearest
    # the misses are simulated without the footprint: the one shown gets it
    fig = dataclasses.replace(fig, footprint=float(footprints(SixBars.from_sixbars([fit_.sixbar()]))[0]))
    loose = _loosened(request, fig)
    return NoMatch(fitted, rejected, dataclasses.replace(_candidate(loose, fit_, fig), rank=1), loose)


def diagnose_by_bounds(request: Request, fitted: Sequence[Fitted],
                       known: dict[int, SixBarFigures] | None = None) -> NoMatch:
    """:func:`diagnose`, the same :class:`NoMatch`, refining the dwell ends only of the
    six-bars whose dwell decides something (single dwells; a double dwell is diagnosed by
    :func:`diagnose`).

    Every figure but the dwell is computed as :func:`~synth.figures.sixbar_figures` does; the
    dwell's angle is bounded from the grid (:func:`~synth.figures.figures_with_dwell_bounds`),
    which bounds its excess (convex in the angle: least at the requested dwell). A six-bar
    gets its exact figures when the bounds leave open whether it misses the dwell, or when
    its least possible total excess is not above the smallest total known to be reachable —
    until no six-bar not simulated exactly can be nearer (or as near: ties go to the fit
    order, as in :func:`diagnose`). ``known``: figures at hand by ``id`` of the fit."""
    known = dict(known or {})
    if request.dwells != 1 or not fitted:
        return diagnose(request, fitted, _misses(request, fitted, known))
    rest = [k for k, f in enumerate(fitted) if id(f) not in known]
    excess: dict[int, dict[str, float]] = {k: violations(request, known[id(f)])
                                          for k, f in enumerate(fitted) if id(f) in known}
    figures = {k: known[id(f)] for k, f in enumerate(fitted) if id(f) in known}
    low_total: dict[int, float] = {}
    high_total: dict[int, float] = {}
    undecided: list[int] = []
    bound: dict[int, dict[str, float]] = {}  # excesses of the decided ones (dwell: its lower bound)
    if rest:
        rough, low, high = figures_with_dwell_bounds(SixBars.from_sixbars([fitted[k].sixbar() for k in rest]),
                                                     band=request.band, samples=SAMPLES)
        for j, k in enumerate(rest):
            nearest = min(max(request.dwell, low[j]), high[j])  # the excess is convex in the angle
            least = violations(request, dataclasses.replace(rough[j], dwells=(Dwell(0.0, nearest, nearest),)))
            most = max(_dwell_excess(request, low[j]), _dwell_excess(request, high[j]))
            low_total[k] = _total(least)
            high_total[k] = _total(dict(least, dwell=most))
            if (least["dwell"] > 0) != (most > 0):
                undecided.append(k)
            bound[k] = least

    def exact(ks: list[int]) -> None:
        if not ks:
            return
        for k, fig in zip(ks, _figures(request, [fitted[k].sixbar() for k in ks], footprint=False)):
            figures[k], excess[k] = fig, violations(request, fig)
            low_total[k] = high_total[k] = _total(excess[k])

    for k in excess:
        low_total[k] = high_total[k] = _total(excess[k])
    exact(undecided)
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
    return _no_match(request, len(fitted), rejected, None if best_total == math.inf else (fitted[best], figures[best]))


def _distinct(ranked: Sequence[Candidate]) -> list[Candidate]:
    """One six-bar per segment and output type (the best-ranked), and one of a mirror pair: the
    two assembly branches of a four-bar are mirror images with the same figures."""
    seen: set = set()
    unique = []
    for c in ranked:
        sb = c.sixbar
        mirror = (round(sb.b, 9), round(sb.c, 9), round(sb.d, 9), sb.dyad.kind, round(sb.u, 3), round(abs(sb.v), 3))
        key = (c.segment_id, c.id.split("-")[1][:3])
        if key not in seen and mirror not in seen:
            seen.update((key, mirror))
            unique.append(c)
    return unique


def _rest(sixbar: SixBar, f: SixBarFigures) -> complex | None:
    """RRR: the moving pivot Q at the middle of the first dwell (None for an RPR)."""
    if sixbar.dyad.kind != "RRR" or not f.dwells:
        return None
    d = f.dwells[0]
    return complex(simulate_motion(sixbar, np.array([0.5 * (d.start + d.end)]), order=0).moving_pivot[0])


def _refined(request: Request, candidates: Sequence[Candidate],
             before: Sequence[SixBarFigures] | None = None, *, reach: bool = False
             ) -> tuple[list[Candidate], int]:
    """``candidates`` (the user's units) refined toward ``request`` (:func:`synth.refine.refine`,
    its reach for near misses): the refined ones with their new id, six-bar and figures and
    ``refined_from``, the others as they were; and how many were refined. ``before``: their
    figures crank-normalised, if at hand."""
    from synth.refine import refine

    if not candidates:
        return [], 0
    s = request.crank
    sixbars = [c.sixbar.scaled(1.0 / s) for c in candidates]
    before = [_scaled_figures(c.figures, 1.0 / s) for c in candidates] if before is None else before
    out, count = [], 0
    for c, r in zip(candidates, refine(request, sixbars, before, reach=reach)):
        if not r.refined:
            out.append(c)
            continue
        count += 1
        rest = _rest(r.sixbar, r.figures)
        out.append(dataclasses.replace(
            c, id=with_dimensions(c.id, r.sixbar), sixbar=r.sixbar.scaled(s), figures=_scaled_figures(r.figures, s),
            # a reseated six-bar keeps the fit it was moved from as "before" (as a rebuild does)
            dwell_position=None if rest is None else rest * s, refined_from=c.refined_from or c.figures))
    return out, count


#: (segment, level) rows the complete search reads, fits and simulates at a time.
BATCH = 4000
#: No limit on the rows of a window (SQL LIMIT).
ALL_ROWS = 2**62


@dataclass(frozen=True, slots=True)
class SearchCount:
    """What the complete search went through: (segment, level) rows read and fitted, dyads
    fitted, six-bars past the prescreen (:func:`prescreen`) and simulated, six-bars that met
    the request."""

    rows: int = 0
    fitted: int = 0
    simulated: int = 0
    met: int = 0


#: Runs a function over a stream of items and yields the results in any order
#: (the built-in :func:`map` in this process; ``atlas.pool.pool_map`` on worker processes).
BatchMap = Callable[[Callable[[tuple], tuple], Iterator[tuple]], Iterator[tuple]]


def fit_key(request: Request) -> tuple:
    """What the rows a complete search reads and the dyads it fits depend on: requests with
    the same key share both (:func:`search_many`); the dwell, band and the other limits only
    decide which of the fitted six-bars meet a request."""
    return (kinds_for(request), request.swing, request.min_transmission, request.max_link_ratio)


def search_batch(job: tuple[Sequence[Request], str, Sequence[SegmentRow]]
                 ) -> tuple[list[list[Candidate]], int, int, list[int]]:
    """One batch of :func:`search_many`: ``job = (requests, kind, rows)`` → per request the
    six-bars that meet it, then the rows, the fitted dyads and per request the simulated
    six-bars. The dyads are fitted once for all the requests (they share :func:`fit_key`).
    Module-level, so that it runs on worker processes."""
    requests, kind, rows = job
    fits, paths = _fit_arrays(requests[0], rows, kind)
    met, simulated = [], []
    for request in requests:
        found, n = simulate(request, _fitted(rows, fits, prescreen(request, fits, paths)))
        met.append(found)
        simulated.append(n)
    return met, len(rows), fits.index.size, simulated


def search(request: Request, source: SegmentSource, *,
           on_progress: Callable[[int, int], None] | None = None,
           map_batches: BatchMap | None = None) -> tuple[list[Candidate], SearchCount]:
    """Every six-bar the atlas yields for ``request`` that meets it, unranked (in the
    crank-normalised fit's terms, scaled to ``request.crank``).

    The six-bars the atlas yields: for every stored segment of the request's kinds
    (:func:`kinds_for`) at every tolerance level, the output dyads :func:`fit` finds for it
    (RPR: a slot pivot on each side of a straight stretch; RRR: up to two rocker directions on
    an arc; double: the pivot at the two lines' intersection). Nothing is left out by a
    budget: the rows are only pruned by conditions no six-bar meeting the request can fail —
    the four-bar's transmission angle and link lengths (stored per linkage), the arc's radius
    as the rod, then :func:`prescreen` and :func:`synth.candidates.screen` on exact samples.
    The atlas is read in batches of ``BATCH`` rows per kind and level, each evaluated by
    :func:`search_batch` through ``map_batches`` (default: in this process, in order; the
    answer does not depend on the order); ``on_progress(rows done, rows in all)`` after each."""
    return search_many([request], source, on_progress=on_progress, map_batches=map_batches)[0]


def search_many(requests: Sequence[Request], source: SegmentSource, *,
                on_progress: Callable[[int, int], None] | None = None,
                map_batches: BatchMap | None = None) -> list[tuple[list[Candidate], SearchCount]]:
    """:func:`search` for several requests with one :func:`fit_key` (say, every dwell of one
    swing): one walk of the atlas, each row fitted once; per request the same answer as its
    own :func:`search`."""
    requests = list(requests)
    if not requests or any(fit_key(r) != fit_key(requests[0]) for r in requests):
        raise ValueError("search_many needs one or more requests with the same kinds, swing, transmission and link ratio")
    first = requests[0]
    limits = {"min_transmission": first.min_transmission, "max_length": first.max_link_ratio,
              "min_radius_ratio": 1.0 / first.max_link_ratio}
    jobs = [(kind, lv) for kind in kinds_for(first) for lv, _ in source.tolerance_levels()]
    total = sum(source.count_segments(kind, lv, **limits) for kind, lv in jobs)
    batches = ((tuple(requests), kind, rows) for kind, lv in jobs
               for rows in source.scan_segments(kind, lv, batch=BATCH, **limits))
    out: list[list[Candidate]] = [[] for _ in requests]
    simulated = [0] * len(requests)
    rows_n = fitted_n = 0
    for met, n_rows, n_fitted, n_simulated in (map_batches or map)(search_batch, batches):
        for k, (found, n) in enumerate(zip(met, n_simulated)):
            out[k] += found
            simulated[k] += n
        rows_n, fitted_n = rows_n + n_rows, fitted_n + n_fitted
        if on_progress is not None:
            on_progress(rows_n, total)
    if on_progress is not None:
        on_progress(total, total)  # a double line without both stretches at a level is read, not fitted
    return [(found, SearchCount(rows_n, fitted_n, n, len(found))) for found, n in zip(out, simulated)]


def _toleranced(request: Request, candidates: list[Candidate]) -> list[Candidate]:
    """With ``request.tolerance``: each candidate with its toleranced deviation
    (:func:`synth.tolerance.toleranced_deviation` over the middles of its dwells, the request's
    dwell length), worked out afresh (a refined six-bar is another six-bar); else as they are."""
    if request.tolerance <= 0:
        return candidates
    from synth.tolerance import toleranced_deviation

    out = []
    for c in candidates:
        centres = [0.5 * (d.start + d.end) for d in c.figures.dwells[: request.dwells]]
        value = toleranced_deviation(c.sixbar, request.tolerance, centres, request.dwell) if centres else None
        out.append(dataclasses.replace(c, toleranced_deviation=value))
    return out


def answer(request: Request, source: SegmentSource, *,
           on_progress: Callable[[int, int], None] | None = None,
           map_batches: BatchMap | None = None,
           searched: tuple[list[Candidate], SearchCount] | None = None) -> QueryResult:
    """Ranked candidates for ``request`` from ``source`` (a pure read): from the sample of
    segments :func:`select` takes, or with ``request.complete`` from every six-bar the atlas
    yields (:func:`search`, which reports ``on_progress`` and runs its batches through
    ``map_batches``; or ``searched``, its result for this request from :func:`search_many`).

    ``--output any`` with one dwell is the best of both output types: the request answered as
    RPR and as RRR, each through the whole pipeline (its sparse-answer steps and refinement
    sized for ``request.top``), then the union of the two answers ranked once
    (:func:`~synth.candidates.rank`) and cut to ``request.top`` (:func:`_best_of_both`)."""
    if request.output == "any" and request.dwells == 1:
        return _best_of_both(request, source, on_progress=on_progress, map_batches=map_batches, searched=searched)
    return _answer_one(request, source, on_progress=on_progress, map_batches=map_batches, searched=searched).result


@dataclass(frozen=True, slots=True)
class _Answered:
    """One output type's answer and which of its candidates are refined near misses (FILL)
    and six-bars with a moved output pivot (by id): what :func:`_best_of_both` recounts for
    the candidates that stay in the union's top."""

    result: QueryResult
    misses: frozenset[str]
    reseated: frozenset[str]


def _best_of_both(request: Request, source: SegmentSource, *,
                  on_progress: Callable[[int, int], None] | None,
                  map_batches: BatchMap | None,
                  searched: tuple[list[Candidate], SearchCount] | None) -> QueryResult:
    """``request`` (``output="any"``, one dwell) answered as RPR and as RRR, then the best
    ``request.top`` of the union of the two answers by :func:`~synth.candidates.rank` (Pareto
    layer, score, id, over the union: a six-bar's layer depends on what it is ranked with).
    The two answers share no six-bar (their dyads differ), so :func:`_distinct` keeps the
    union whole. Times, counts and refinements add up; with nothing in either, the no-match
    is the two diagnoses in one (:func:`_either_no_match`). ``searched`` (a complete search
    of both kinds, :func:`search_many`) is split by output type; its counts go to the RPR
    part, so that the sums are the search's own."""
    parts = []
    for output in ("rpr", "rrr"):
        mine = None
        if searched is not None:
            found, count = searched
            met = [c for c in found if c.sixbar.dyad.kind == output.upper()]
            mine = (met, dataclasses.replace(count, met=len(met)) if output == "rpr" else SearchCount(met=len(met)))
        parts.append(_answer_one(dataclasses.replace(request, output=output), source, on_progress=on_progress,
                                 map_batches=map_batches, searched=mine))
    t = time.perf_counter()
    top = rank(request, [c for p in parts for c in p.result.candidates])[: request.top]
    clock: dict[str, float] = {}
    for p in parts:
        for k, v in p.result.seconds.items():
            clock[k] = clock.get(k, 0.0) + v
    clock["rank"] = clock.get("rank", 0.0) + time.perf_counter() - t
    results = [p.result for p in parts]
    no_match = None if top else _either_no_match(request, [r.no_match for r in results])
    below = [r.nearest[0] for r in results if r.nearest[0] is not None]
    above = [r.nearest[1] for r in results if r.nearest[1] is not None]
    nearest = (None, None) if top else (max(below, default=None), min(above, default=None))
    ids = {c.id for c in top}
    return QueryResult(request, top, sum(r.considered for r in results), sum(r.simulated for r in results),
                       nearest, clock, no_match,
                       (sum(r.refined[0] for r in results), sum(r.refined[1] for r in results)),
                       from_misses=bool(top) and all(r.from_misses or not r.candidates for r in results),
                       misses_met=sum(len(p.misses & ids) for p in parts),
                       reseated=sum(len(p.reseated & ids) for p in parts))


def _either_no_match(request: Request, diagnoses: Sequence[NoMatch | None]) -> NoMatch | None:
    """The :class:`NoMatch` of an ``any`` request from those of its RPR and RRR answers: the
    six-bars fitted and the rejections summed, the nearest the nearer of the two (the smaller
    sum of excesses, :func:`violations`; RPR on a tie) with its loosened request."""
    known = [d for d in diagnoses if d is not None]
    if not known:
        return None
    rejected = {k: sum(d.rejected.get(k, 0) for d in known) for k in CONSTRAINTS}

    def total(d: NoMatch) -> float:
        # the nearest's figures are in the user's units; the limits are crank-normalised
        return _total(violations(request, _scaled_figures(d.nearest.figures, 1.0 / request.crank)))

    near = [d for d in known if d.nearest is not None]
    best = min(near, key=total) if near else None
    reaches = [d.reach for d in known if d.reach is not None]
    reach = (best.reach if best is not None and best.reach is not None else None) or next(iter(reaches), None)
    if reach is not None:  # the best figure of both types on that constraint
        mine = [r[1] for r in reaches if r[0] == reach[0]]
        pick = {"transmission": max, "arm": max, "clearance": max, "link_ratio": min, "acceleration": min}.get(
            reach[0], lambda xs: min(xs, key=lambda x: abs(x - reach[2])))
        reach = (reach[0], pick(mine), reach[2])
    return NoMatch(sum(d.fitted for d in known), rejected, None if best is None else best.nearest,
                   None if best is None else dataclasses.replace(best.would_meet, output=request.output), reach)


def _answer_one(request: Request, source: SegmentSource, *,
                on_progress: Callable[[int, int], None] | None = None,
                map_batches: BatchMap | None = None,
                searched: tuple[list[Candidate], SearchCount] | None = None) -> _Answered:
    """:func:`answer` for one output type (or a double dwell)."""
    clock: dict[str, float] = {}
    t0 = time.perf_counter()
    kinds = kinds_for(request)
    rows: list[SegmentRow] = []
    fitted: list[Fitted] = []
    known: dict[int, SixBarFigures] = {}  # full figures of the screened fits, by id
    held: list[Fitted] = []  # every fit in ``known``, kept alive: no id is reused while the answer runs

    def sampled(per_level: int = PER_LEVEL, kinds: tuple[str, ...] = kinds) -> list[Fitted]:
        """The sample's rows and fits (all of them are what a no-match is diagnosed and
        refined from); a wider sample adds the rows the narrower one did not have. Returns
        the new fits past the prescreen."""
        nonlocal rows
        t = time.perf_counter()
        had = {(r.segment_id, r.level) for r in rows}
        new = [r for r in select(source, request, kinds, per_level) if (r.segment_id, r.level) not in had]
        rows = [*rows, *new]
        clock["select"] = clock.get("select", 0.0) + time.perf_counter() - t
        t = time.perf_counter()
        passed = []
        for kind in kinds:
            of_kind = [r for r in new if r.kind == kind]
            found, paths = _fit_arrays(request, of_kind, kind)
            fits = _fitted(of_kind, found)  # every fit: a no-match is diagnosed and refined from them
            fitted.extend(fits)
            passed += [f for f, k in zip(fits, prescreen(request, found, paths)) if k]
        clock["fit"] = clock.get("fit", 0.0) + time.perf_counter() - t
        return passed

    def meeting(fits: list[Fitted]) -> list[Candidate]:
        """The candidates among ``fits`` (simulated), their figures kept for a diagnosis."""
        nonlocal simulated
        t = time.perf_counter()
        screened, n = _screened_figures(request, fits)
        simulated += n
        # reused by a no-match diagnosis, without the footprint as the misses' own figures.
        # ``known`` is keyed by id(): its fits are held, or a freed (moved) fit's id would be
        # reused by a later fit, which then read its figures
        known.update({id(f): dataclasses.replace(fig, footprint=0.0) for f, fig in screened})
        held.extend(f for f, _ in screened)
        clock["simulate"] = clock.get("simulate", 0.0) + time.perf_counter() - t
        return [_candidate(request, f, fig) for f, fig in screened if meets(request, fig)]

    def moved_pivots(answered: list[Candidate]) -> list[Candidate]:
        """The six-bars with the output pivot moved off the fitted one (:func:`reseat`) that
        meet the request: of the sample's fits, then of the segments whose fitted rests are
        longer than the request (``RESEAT_LONGER``), ``RESEAT_BATCH`` at a time, until --top
        segments (``answered`` and these) have one."""
        found: list[Candidate] = []
        had = {(r.segment_id, r.level) for r in rows}
        origins = list(fitted)
        for k in (1.0, *RESEAT_LONGER):
            t = time.perf_counter()
            if k > 1:
                if request.dwells * k * request.dwell >= 2 * math.pi:
                    break
                longer = [r for r in select(source, dataclasses.replace(request, dwell=k * request.dwell), kinds,
                                            WIDER * PER_LEVEL) if (r.segment_id, r.level) not in had]
                had |= {(r.segment_id, r.level) for r in longer}
                origins = [f for kind in kinds for f in fit(request, [r for r in longer if r.kind == kind], kind)]
                if k == RESEAT_LONGER[0]:
                    longer_fits.extend(origins)
            moved = reseat(request, origins)
            clock["reseat"] = clock.get("reseat", 0.0) + time.perf_counter() - t
            for b in range(0, len(moved), RESEAT_BATCH):  # the fits nearest the request first
                met = meeting(moved[b : b + RESEAT_BATCH])
                t = time.perf_counter()
                found += _with_origins(request, met, origins, known)
                clock["reseat"] += time.perf_counter() - t
                if len(_distinct([*answered, *found])) >= request.top:
                    return found
        return found

    moved_ids: set[str] = set()  # ids of the fits whose answer is a reseated six-bar
    longer_fits: list[Fitted] = []  # fits to rests of RESEAT_LONGER[0] × the dwell (moved_pivots)
    if request.complete:
        candidates, count = (searched if searched is not None else
                             search(request, source, on_progress=on_progress, map_batches=map_batches))
        clock["search"] = time.perf_counter() - t0
        considered, simulated = count.rows, count.simulated
    else:
        simulated = 0
        candidates = meeting(sampled())
        # a sparse answer (fewer than FILL) samples wider, is filled towards --top with the
        # fits' pivots moved (short rests), and if still sparse reads deeper along the arcs'
        # keys (long rests) and the double lines' dwells
        sparse = request.refine and len(_distinct(candidates)) < min(FILL, request.top)
        if sparse:
            candidates += meeting(sampled(WIDER * PER_LEVEL))
        if sparse and len(_distinct(candidates)) < request.top:
            found = _no_worse_than_fits(request, moved_pivots(candidates), candidates)
            moved_ids = {c.id.split(REFINED_MARK)[0] for c in found} - {c.id for c in candidates}
            candidates += found
        deep = tuple(k for k in kinds if k in DEEPER_KINDS)
        if sparse and deep and len(_distinct(candidates)) < min(FILL, request.top):
            candidates += meeting(sampled(DEEPER * PER_LEVEL, deep))
        considered = len({r.segment_id for r in rows})
    t3 = time.perf_counter()
    candidates = _toleranced(request, candidates)
    top = [dataclasses.replace(c, rank=i + 1) for i, c in enumerate(_distinct(rank(request, candidates))[: request.top])]
    clock["rank"] = time.perf_counter() - t3
    nearest: tuple[float | None, float | None] = (None, None)
    no_match = None
    refined = (0, 0)
    before_refine = bool(top)  # something in the atlas met the request
    if top and request.refine:
        t4 = time.perf_counter()
        top, better = _refined(request, top)
        top = rank(request, _toleranced(request, top))
        refined = (len(top), better)
        clock["refine"] = time.perf_counter() - t4
    misses_met = 0
    miss_ids: frozenset[str] = frozenset()
    if request.refine and len(top) < min(FILL, request.top):
        if request.complete and not fitted:
            sampled()  # too little in the whole atlas: the sample's near misses are refined
        t4 = time.perf_counter()
        misses = _misses(request, fitted, known)  # all of the fits, nearest first
        if not top:
            no_match = diagnose(request, fitted, misses)
        # the diagnosis simulates the fits the screen dropped: simulation time of this answer
        clock["simulate"] = clock.get("simulate", 0.0) + time.perf_counter() - t4
        if longer_fits:
            # a short rest's own sample can hold no fit (RRR 10° on ``standard``: the arcs
            # whose stored rests predict it are all near-toggle four-bars, transmission < 10°,
            # as the atlas keeps rests ≥ 20° at its widest tolerance); the fits to rests twice
            # as long miss it by a few degrees and are refined toward it with the others
            misses = sorted([*misses, *_misses(request, longer_fits, known)], key=lambda m: m[0])
        t5 = time.perf_counter()
        found, tried, better = _refined_misses(request, misses, {c.id.split("~")[0] for c in top},
                                               min(FILL, request.top) - len(top))
        if found:
            top = [dataclasses.replace(c, rank=i + 1)
                   for i, c in enumerate(_distinct(rank(request, [*top, *_toleranced(request, found)]))[: request.top])]
            miss_ids = frozenset(c.id for c in found) & {c.id for c in top}
            misses_met = len(miss_ids)
            no_match = None
        refined = (refined[0] + tried, refined[1] + better)
        clock["refine"] = clock.get("refine", 0.0) + time.perf_counter() - t5
    if not top:
        if no_match is None:
            if request.complete and not fitted:
                sampled()  # nothing in the whole atlas: diagnose the sample's near misses
            t4 = time.perf_counter()
            no_match = diagnose_by_bounds(request, fitted, known)
            clock["simulate"] = clock.get("simulate", 0.0) + time.perf_counter() - t4
        if not no_match.fitted:  # no six-bar to show: the stored dwells the atlas has instead
            nearest = source.nearest_dwell_angles(kinds, request.dwell)
            no_match = dataclasses.replace(no_match, reach=_unfitted_reach(request, source, kinds))
    reseated = frozenset(c.id for c in top if c.id.split(REFINED_MARK)[0] in moved_ids)
    return _Answered(QueryResult(request, top, considered, simulated, nearest, clock, no_match, refined,
                                 from_misses=bool(top) and not before_refine, misses_met=misses_met,
                                 reseated=len(reseated)), miss_ids, reseated)


def _refined_misses(request: Request, misses: list[tuple[float, Fitted, SixBarFigures, dict]],
                    taken: set[str], wanted: int) -> tuple[list[Candidate], int, int]:
    """The nearest distinct misses (:func:`miss_pool`, not one of the ``taken`` ids) refined
    toward ``request``, ``MISSES`` at a time, nearest first, until ``wanted`` distinct six-bars
    meet it or ``MISS_ROUNDS`` rounds are done: (those that now meet it, how many were tried,
    how many came out refined). The first round is what one round always was."""
    pool, figures = miss_pool(request, misses, taken, MISSES * MISS_ROUNDS)
    met: list[Candidate] = []
    better = tried = 0
    for start in range(0, len(pool), MISSES):
        part = pool[start:start + MISSES]
        refined, improved = _refined(request, part, figures[start:start + MISSES], reach=True)
        met += [c for c in refined if c.refined_from is not None]
        tried, better = tried + len(part), better + improved
        if len(_distinct(met)) >= wanted:
            break
    return met, tried, better


def miss_pool(request: Request, misses: list[tuple[float, Fitted, SixBarFigures, dict]], taken: set[str],
              n: int) -> tuple[list[Candidate], list[SixBarFigures]]:
    """The ``n`` nearest distinct ``misses`` (:func:`_misses`' order; one per segment and
    output type, one of a mirror pair; none that does not assemble, none of the ``taken``
    ids) as candidates, with their figures crank-normalised (the candidates' own are in the
    user's units)."""
    near = [(_candidate(request, fit_, fig), fig) for total, fit_, fig, _ in misses if total < math.inf]
    figures: dict[str, SixBarFigures] = {}
    for c, fig in near:
        figures.setdefault(c.id, fig)
    pool = [c for c in _distinct([c for c, _ in near]) if c.id not in taken][:n]
    return pool, [figures[c.id] for c in pool]


def rebuild(ids: Sequence[str], source: SegmentSource, request: Request) -> list[Candidate]:
    """The candidates named by ``ids`` (from an earlier query), re-fitted and re-simulated.

    ``request`` gives the output band, the deviation window (its dwell), the crank length and
    the minimum transmission the RRR fit used; its other limits are ignored — the figures of a
    rebuilt six-bar are shown whatever they are. A refined id's six-bar is the one its
    dimensions give (its figures are the query's for the same band and dwell); its
    ``refined_from`` holds the figures of the six-bar it was refined from. Raises
    :class:`RebuildError` naming the id."""
    out = []
    for text in ids:
        try:
            seg_id, output, slot, level, swing = parse_candidate_id(text)
            dims = candidate_dimensions(text)
        except ValueError as exc:
            raise RebuildError(str(exc)) from None
        if dims is not None:
            out.append(dataclasses.replace(_rebuild_refined(text, dims, source, request), rank=len(out) + 1))
            continue
        # a double dwell's id from before --swing was required holds no swing ("@free"): its
        # fit does not use one
        req = dataclasses.replace(request, swing=request.swing if swing is None else swing,
                                  dwells=2 if output == "dbl" else 1, output="rpr" if output in ("rpr", "dbl") else "rrr")
        row = source.segment(seg_id, level)
        if row is None:
            raise RebuildError(f"no segment {seg_id} in this atlas (candidate {text!r})")
        found = None
        if row.parts:
            fitted = [f for f in fit(req, [row], row.kind) if f.output == output and f.slot == slot]
            # whatever its figures — a fit a six-bar was moved or refined from may revolve, or
            # have one rest where two were asked —, but a six-bar that assembles and rests
            cands = [_candidate(req, f, fig) for f, fig in zip(fitted, _figures(req, [f.sixbar() for f in fitted]))
                     if fig.assembled and fig.dwells] if fitted else []
            found = dataclasses.replace(cands[0], id=text.strip()) if cands else None
        if found is None:
            raise RebuildError(f"candidate {text!r} cannot be rebuilt from this atlas (no fit for that slot and level)")
        out.append(dataclasses.replace(found, rank=len(out) + 1))
    return out


def _rebuild_refined(text: str, dims: SixBar, source: SegmentSource, request: Request) -> Candidate:
    """The refined six-bar ``dims`` (crank-normalised) an id carries, simulated as the query
    simulated it; the six-bar it was refined from is rebuilt for ``refined_from`` (None if it
    cannot be)."""
    seg_id, output, _, level, _ = parse_candidate_id(text)
    if source.segment(seg_id, level) is None:
        raise RebuildError(f"no segment {seg_id} in this atlas (candidate {text!r})")
    req = dataclasses.replace(request, dwells=2 if output == "dbl" else 1)
    fig = _figures(req, [dims])[0]
    try:
        base = rebuild([text.strip().split("~")[0]], source, request)[0].figures
    except RebuildError:
        base = None
    rest = _rest(dims, fig)
    s = request.crank
    return Candidate(id=text.strip(), segment_id=seg_id, sixbar=dims.scaled(s), figures=_scaled_figures(fig, s),
                     dwell_position=None if rest is None else rest * s, refined_from=base)
