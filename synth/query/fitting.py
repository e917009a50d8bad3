"""Output dyads fitted to stored segments (:func:`fit`; as arrays before any object is made,
:func:`fit_arrays`), the prescreen on the fit's crank grid that needs no simulation
(:func:`prescreen`), and the fits' output pivots moved off the fitted ones (:func:`reseat`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from synth.kinds import OutputKind, OutputTag, SegmentKind
from synth.mechanism.sixbar import OutputDyad, SixBar, crank_grid
from synth.query.candidate_ids import candidate_id, round_dimensions
from synth.query.candidates import Request, dwell_runs
from synth.query.segment_rows import SegmentBatch, SegmentRow

#: Crank samples of the path the dyads are fitted to (1°): a fitted swing is within ~0.01° of
#: the simulated one, which is what the request is checked against.
FIT_SAMPLES = 360

#: After the wider sample, while it holds fewer than --top, each fit's output pivot moved off
#: the fitted one (:func:`reseat`): at most this many moved pivots per fit, nearest first.
RESEAT_PER_FIT = 1

#: Pivots screened at a time by :func:`reseat` (n × samples temporaries), and its coarse
#: screen's sample step (every 4th of the fit's 1° grid).
_BLOCK = 8192
_COARSE = 4


@dataclass(frozen=True, slots=True)
class Fitted:
    """One fitted output dyad: the segment row it came from, the output tag of its id
    (``rpr``, ``rrr``, ``dbl``), the fit's slot, the dyad (crank-normalised) and, for RRR,
    where the moving pivot rests during the dwell."""

    row: SegmentRow
    output: OutputTag
    slot: int
    dyad: OutputDyad
    rest: complex | None = None
    #: The dyad was moved off the fit's own (:func:`reseat`): the id carries the dimensions.
    moved: bool = False

    def sixbar(self) -> SixBar:
        return SixBar.of(self.row.fourbar, self.dyad)

    def candidate_id(self, swing: float | None, *, dimensions: bool = True) -> str:
        """Its candidate id for a request of ``swing`` (rad), with a moved dyad's dimensions
        unless not ``dimensions`` (the id of the fit it was moved from)."""
        r = self.row
        moved = self.sixbar() if self.moved and dimensions else None
        return candidate_id(r.segment_id, self.output, self.slot, r.level, swing, moved)

    @property
    def key(self) -> tuple:
        """The fit told from every other by its fields (segment, level, output, slot, moved or
        not, dyad): two fits with one key are one six-bar. The figures an answer has computed
        are kept by it."""
        return (self.row.segment_id, self.row.level, self.output, self.slot, self.moved, self.dyad)


def coupler_paths(rows: SegmentBatch | Sequence[SegmentRow], phi: np.ndarray) -> np.ndarray:
    """The coupler-point paths of ``rows`` (a batch, or rows of any kinds) on the crank grid ``phi``."""
    if isinstance(rows, SegmentBatch):
        fb = rows.fourbar
        return paths_of(fb.b, fb.c, fb.d, fb.branch, rows.coupler_point(), phi)
    b, c, d, branch = (np.array([getattr(r.fourbar, name) for r in rows]) for name in ("b", "c", "d", "branch"))
    return paths_of(b, c, d, branch, np.array([complex(r.fourbar.u, r.fourbar.v) for r in rows]), phi)


def paths_of(
    b: np.ndarray, c: np.ndarray, d: np.ndarray, branch: np.ndarray, points: np.ndarray, phi: np.ndarray
) -> np.ndarray:
    """(len(b), len(phi)) complex: the path of coupler point ``points[k]`` (u + iv, coupler
    frame) of the crank-normalised four-bar ``k`` (b, c, d, branch) on the crank grid ``phi``
    (:meth:`~kinematics.fourbar.FourBarMotion.coupler_point`, the formula's one home)."""
    from kinematics.fourbar import fourbar_motion

    motion = fourbar_motion(1.0, b[:, None], c[:, None], d[:, None], phi, branch[:, None], order=0)
    return motion.coupler_point(points.real[:, None], points.imag[:, None])[0]


def fit(request: Request, rows: Sequence[SegmentRow], kind: SegmentKind | str) -> list[Fitted]:
    """Every dyad found for ``rows`` (all of segment kind ``kind``), in row and slot order."""
    return fits_of(rows, fit_arrays(request, rows, kind)[0])


@dataclass(frozen=True, slots=True)
class FitArrays:
    """The dyads :func:`fit` finds, one entry per dyad in row and slot order, before any
    object is made (most of a complete search's fits fail the prescreen): the id's output tag,
    each dyad's row (index into the rows fitted) and slot, its pivot, its stretch's line point
    or arc centre (part 0: where an RRR's Q rests; the prescreen measures angles from it) and
    (RRR) rocker, rod and branch."""

    output: OutputTag
    index: np.ndarray
    slot: np.ndarray
    pivot: np.ndarray
    point: np.ndarray
    rocker: np.ndarray | None = None
    rod: np.ndarray | None = None
    branch: np.ndarray | None = None


def fit_arrays(request: Request, rows: Sequence[SegmentRow], kind: SegmentKind | str) -> tuple[FitArrays, np.ndarray]:
    """The dyads found for ``rows`` (all of kind ``kind``; a :class:`SegmentBatch` or a list of
    rows) and the rows' coupler-point paths on the fit's crank grid."""
    from synth.mechanism.dyad import fit_rpr, fit_rrr, rpr_double

    kind = SegmentKind(kind)  # a stored row's kind is its string
    phi = crank_grid(FIT_SAMPLES)
    none = np.zeros(0, np.int64)
    if not len(rows):
        empty = np.zeros(0, complex)
        return FitArrays(kind.output, none, none, empty, empty), np.zeros((0, FIT_SAMPLES), complex)
    batch = SegmentBatch.of_rows(rows, kind)
    paths = coupler_paths(batch, phi)
    point = batch.point(0)
    if kind == SegmentKind.DOUBLE_LINE:
        two = np.flatnonzero(batch.has_parts == 2)  # a double line holds both stretches at the level
        found = rpr_double(
            (point[two], batch.part(0, "direction")[two]), (batch.point(1)[two], batch.part(1, "direction")[two])
        )
        (hit,) = np.nonzero(found.found)
        index = two[hit]
        return FitArrays(OutputTag.DOUBLE_RPR, index, np.zeros_like(index), found.pivot[hit], point[index]), paths
    interval = (batch.part(0, "start"), batch.part(0, "end"))
    if kind == SegmentKind.LINE:
        found = fit_rpr(point, batch.part(0, "direction"), phi, paths, interval, request.swing)
        index, slot = np.nonzero(found.found)  # row-major: row, then slot order
        return FitArrays(OutputTag.RPR, index, slot, found.pivot[index, slot], point[index]), paths
    found = fit_rrr(
        point, batch.part(0, "radius"), phi, paths, interval, request.swing, request.min_transmission, keep=2
    )
    index, slot = np.nonzero(found.found)
    return FitArrays(
        OutputTag.RRR,
        index,
        slot,
        found.pivot[index, slot],
        point[index],
        found.rocker[index, slot],
        found.rod[index, slot],
        found.branch[index, slot],
    ), paths


def fits_of(rows: Sequence[SegmentRow], found: FitArrays, keep: np.ndarray | None = None) -> list[Fitted]:
    """The :class:`Fitted` of ``found`` (of those ``keep`` marks)."""
    if not found.index.size:
        return []
    pick = slice(None) if keep is None else np.flatnonzero(keep)
    index, slot, pivot = (x[pick].tolist() for x in (found.index, found.slot, found.pivot))
    if found.output != OutputTag.RRR:
        return [Fitted(rows[i], found.output, k, OutputDyad.rpr(D)) for i, k, D in zip(index, slot, pivot)]
    rocker, rod, branch, rest = (x[pick].tolist() for x in (found.rocker, found.rod, found.branch, found.point))
    return [
        Fitted(rows[i], OutputTag.RRR, k, OutputDyad.rrr(D, L, rho, int(br)), Q)
        for i, k, D, L, rho, br, Q in zip(index, slot, pivot, rocker, rod, branch, rest)
    ]


def prescreen(request: Request, found: FitArrays, paths: np.ndarray) -> np.ndarray:
    """Which of the dyads ``found`` (:func:`fit_arrays`, in its order) may meet
    ``request``, from the paths they were fitted to (``paths``, exact coupler-point positions on
    the fit's crank grid), before any simulation and before any object is made for them: the
    output angle on that grid in closed form (RPR: the slot's direction P − D; RRR: the
    rocker's, Q from the loop's circle intersection), then tests no six-bar meeting the
    request can fail: it assembles at every sample (RRR), and its sampled output angle passes
    :func:`synth.query.candidates.output_may_meet` (swing, and the dwell in runs of samples within
    the band). The angles are measured from the direction of the stretch's line point (RPR) or
    arc centre (RRR) seen from D, and unwrapped along the turn."""
    if not found.index.size:
        return np.zeros(0, bool)
    links = (
        None if found.output != OutputTag.RRR else tuple(x[:, None] for x in (found.rod, found.rocker, found.branch))
    )
    return _output_screen(request, paths[found.index], found.pivot[:, None], found.point[:, None], links)


def _reference(f: Fitted) -> complex:
    """Where the output angle is measured towards: an RRR's rest, else the stretch's line point."""
    return f.rest if f.rest is not None else f.row.parts[0].point


def _rrr_links(fitted: Sequence[Fitted]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rod, rocker and branch of RRR fits, shaped (n, 1) to broadcast over the crank grid."""
    return tuple(np.array([getattr(f.dyad, k) for f in fitted])[:, None] for k in ("rod", "rocker", "branch"))


def _output_screen(
    request: Request,
    P: np.ndarray,
    D: np.ndarray,
    rest: np.ndarray,
    rrr: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """:func:`prescreen`'s tests for coupler points ``P`` (n, M) on the fit's crank grid,
    output pivots ``D`` and references ``rest`` (n, 1): a slot's angle (``rrr`` None) or, with
    ``rrr`` = (rod, rocker, branch), the rocker's, Q from the loop's circle intersection, which
    must assemble at every sample; then :func:`synth.query.candidates.output_may_meet`'s tests.
    Compiled, one pass per dyad (:mod:`synth.query.prescreen_kernel`). Shape (n,)."""
    from synth.query.prescreen_kernel import screen_outputs  # numba: imported on first use

    shortest, longest = dwell_runs(request, P.shape[-1])
    return screen_outputs(P, D, rest, rrr, request.swing, request.swing_tol, request.band, shortest, longest)


def reseat(request: Request, fitted: Sequence[Fitted]) -> list[Fitted]:
    """Every fit's output pivot moved off the fitted one (:func:`synth.mechanism.dyad.pivots_around`:
    an RPR's slot pivot off its line, a double line's off the lines' crossing, an RRR's rocker
    pivot with its rocker and rod kept), the moved six-bars that pass :func:`prescreen`, at
    most ``RESEAT_PER_FIT`` per fit (the nearest pivots first). The fit puts the pivot where the
    stretch is seen straight on (or the rest at the arc's centre); a shorter dwell than that
    gives wants another — the rest then creeps — and the atlas yields every pivot
    (docs/complete-query.md §1). Their ids carry the dimensions."""
    from synth.mechanism.dyad import pivots_around

    if not fitted:
        return []
    paths = coupler_paths([f.row for f in fitted], crank_grid(FIT_SAMPLES))
    rest = np.array([_reference(f) for f in fitted])
    reach = np.array(
        [
            f.dyad.rocker
            if f.dyad.kind == OutputKind.RRR
            else np.mean([abs(f.dyad.pivot - p.point) for p in f.row.parts])
            for f in fitted
        ]
    )
    pivots = pivots_around(np.array([f.dyad.pivot for f in fitted]), reach)  # (n, K)
    rrr = np.array([f.dyad.kind == OutputKind.RRR for f in fitted])
    links = _rrr_links(fitted)  # every fit's (an RPR's are unused), read once

    def screen(i: np.ndarray, k: np.ndarray, every: int) -> np.ndarray:
        """The screen of the pivots (i, k) on every ``every``-th sample of the grid (a
        uniform grid too: the same necessary tests, weaker), in blocks of one kind."""
        ok = np.zeros(i.size, bool)
        for kind in (False, True):
            of_kind = np.flatnonzero(rrr[i] == kind)
            for b in (of_kind[s : s + _BLOCK] for s in range(0, of_kind.size, _BLOCK)):
                fits = i[b]
                ok[b] = _output_screen(
                    request,
                    paths[fits, ::every],
                    pivots[fits, k[b]][:, None],
                    rest[fits, None],
                    tuple(x[fits] for x in links) if kind else None,
                )
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
    return [
        _as_stored(
            dataclasses.replace(
                fitted[i], dyad=dataclasses.replace(fitted[i].dyad, pivot=complex(pivots[i, k])), rest=None, moved=True
            )
        )
        for i, k in zip(*np.nonzero(keep))
    ]


def _as_stored(fitted: Fitted) -> Fitted:
    """``fitted`` with the dimensions its id will hold (:func:`~synth.query.candidate_ids.round_dimensions`),
    so that its figures are the ones a rebuild from the id gives."""
    sb = round_dimensions(fitted.sixbar())
    row = dataclasses.replace(fitted.row, fourbar=sb.fourbar)  # a = 1: the id's dimensions are crank-normalised
    return dataclasses.replace(fitted, row=row, dyad=sb.dyad)
