"""Slotted rockers resting at a coupler curve's support point: the near misses of a sparse
answer for a rest shorter than a harmonic output of the requested swing would give
(:func:`support_fits`).

A short rest at a small swing (RPR 10° at a 10° or 20° swing) lies at no stored straight
stretch: the output must turn sharply at its extremes and move evenly between them
(:mod:`synth.mechanism.support_rest`). The paths tested are those of a grid of coupler points
on every eighth four-bar of the atlas's lines (within the request's transmission and link
limits); an even spread of the pairs of a path and a slot direction that pass the far-field
test get a slot pivot on the support tangent each way (its longest reach within the link
ratio, its swing within 10 % of the request's). They are returned as fits on the row of a
line of their four-bar, moved: their ids carry their dimensions, the coupler point with
them, and the near-miss refinement moves them onto the request.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from synth.kinds import OutputTag, SegmentKind
from synth.mechanism.sixbar import OutputDyad, crank_grid
from synth.mechanism.support_rest import DIRECTIONS, harmonic_rest, slot_pivots, support_points
from synth.query.candidates import Request
from synth.query.contract import SegmentSource
from synth.query.fitting import Fitted, paths_of
from synth.query.segment_rows import SegmentBatch, SegmentRow

__all__ = ["GRID_POINTS", "GRID_STRIDE", "PAIRS", "support_fits", "wants_support_fits"]

#: Passing (path, direction) pairs taken at most: each gives two fits (a slot pivot each way),
#: which the near misses' order sorts.
PAIRS = 512
#: How far (a fraction of the request's) a fit's swing may stay from it: the refinement moves
#: a near miss a little, and near the curve the reach may find no pivot that swings as asked.
SWING_SLACK = 0.1
#: Crank samples of the far-field test (1°: a 10° rest is ten of them).
SAMPLES = 360
#: Rows of the atlas read per batch.
BATCH = 8000
#: Paths given to the far-field test at a time (~6 kB a path and its motion).
PATHS = 4096
#: Coupler points tried on every GRID_STRIDE-th four-bar (cranks, the coupler's frame), not
#: the lines' own: a line's point has a straight stretch, where the output is slow. On
#: ``standard``, 64 near misses refined from each: RPR 10°/10° 1 meets from the lines' points,
#: 7 from the grid's; 10°/20° 10 and 17; the two pooled by their excess, 7 and 2.
GRID_POINTS = (np.linspace(-1.0, 2.5, 6)[None, :] + 1j * np.linspace(-2.0, 2.0, 6)[:, None]).ravel()
GRID_STRIDE = 8


def wants_support_fits(request: Request) -> bool:
    """A single RPR rest no longer than a harmonic output of the requested swing rests
    (:func:`~synth.mechanism.support_rest.harmonic_rest`, 23.0° at a 10° swing and 0.1° band):
    what the stored stretches do not predict."""
    return (
        request.output == OutputTag.RPR
        and request.dwells == 1
        and request.swing is not None
        and request.dwell <= harmonic_rest(request.band, request.swing)
    )


def support_fits(request: Request, source: SegmentSource) -> list[Fitted]:
    """RPR fits with the slot pivot on a support tangent of a coupler curve (module docstring):
    of :data:`GRID_POINTS` on every :data:`GRID_STRIDE`-th four-bar of the atlas's lines, up
    to :data:`PAIRS` passing (path, direction) pairs, an even spread in the atlas's scan
    order; [] unless :func:`wants_support_fits`."""
    if not wants_support_fits(request):
        return []
    level = source.tolerance_levels()[0][0]  # every line has a row at every level
    phi = crank_grid(SAMPLES)
    found: list[_Passing] = []
    seen: set[tuple[float, float, float, int]] = set()
    for batch in source.scan_segments(
        SegmentKind.LINE,
        level,
        min_transmission=request.min_transmission,
        max_length=request.max_link_ratio,
        min_radius_ratio=1.0 / request.max_link_ratio,
        batch=BATCH,
    ):
        fb = batch.fourbar
        first = []  # the first row of each four-bar not met before, every GRID_STRIDE-th of them
        for i, key in enumerate(zip(fb.b.tolist(), fb.c.tolist(), fb.d.tolist(), fb.branch.tolist())):
            if key not in seen:
                if len(seen) % GRID_STRIDE == 0:
                    first.append(i)
                seen.add(key)
        rows = np.repeat(np.array(first, np.int64), GRID_POINTS.size)
        found.append(_passing(request, batch, rows, np.tile(GRID_POINTS, len(first)), phi))
    return _pivot_fits(request, found, PAIRS, phi)


@dataclass(frozen=True, slots=True)
class _Passing:
    """The passing (path, direction) pairs of one batch: the path's row and coupler point,
    the slot normal's index and the support point's sample."""

    batch: SegmentBatch
    rows: np.ndarray
    points: np.ndarray
    direction: np.ndarray
    sample: np.ndarray


def _paths(batch: SegmentBatch, rows: np.ndarray, points: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """The paths of the coupler ``points`` (u + iv) of the four-bars of ``batch``'s ``rows``."""
    fb = batch.fourbar
    return paths_of(*(np.asarray(x)[rows] for x in (fb.b, fb.c, fb.d, fb.branch)), points, phi)


def _passing(request: Request, batch: SegmentBatch, rows: np.ndarray, points: np.ndarray, phi: np.ndarray) -> _Passing:
    """The pairs of the paths of ``rows`` and ``points`` that pass, :data:`PATHS` paths at a time
    (a batch's new four-bars can be thousands, 36 paths each: ~6 kB a path and its motion)."""
    support = np.empty((len(rows), DIRECTIONS), np.int64)
    for lo in range(0, len(rows), PATHS):
        support[lo : lo + PATHS] = support_points(
            _paths(batch, rows[lo : lo + PATHS], points[lo : lo + PATHS], phi),
            dwell=request.dwell,
            dwell_tol=request.dwell_tol,
            swing=request.swing,
            band=request.band,
        )
    path, k = np.nonzero(support >= 0)
    return _Passing(batch, rows[path], points[path], k, support[path, k])


def _pivot_fits(request: Request, found: list[_Passing], n: int, phi: np.ndarray) -> list[Fitted]:
    """Slot pivots (each way) of an even spread of ``n`` of the ``found`` pairs, those within
    the link ratio and :data:`SWING_SLACK` of the swing, as fits on their line's row with the
    pair's coupler point (the id carries it: the fits are moved)."""
    total = sum(len(f.rows) for f in found)
    # a small swing passes up to ~10⁵ pairs: an even spread of them, in scan order
    chosen = np.unique(np.linspace(0, total - 1, min(total, n)).round().astype(np.int64))
    picked: list[SegmentRow] = []
    paths, direction, sample = [], [], []
    start = 0
    for f in found:
        mine = chosen[(chosen >= start) & (chosen < start + len(f.rows))] - start
        start += len(f.rows)
        if not mine.size:
            continue
        picked += [_with_point(f.batch[int(r)], p) for r, p in zip(f.rows[mine], f.points[mine])]
        paths.append(_paths(f.batch, f.rows[mine], f.points[mine], phi))
        direction.append(f.direction[mine])
        sample.append(f.sample[mine])
    if not picked:
        return []
    path = np.concatenate(paths)
    hits, pivots, swung = slot_pivots(path, np.concatenate(direction), np.concatenate(sample), swing=request.swing)
    reach = np.abs(path[hits] - pivots[:, None]).max(axis=1)
    keep = (
        np.isfinite(pivots)
        & (reach <= request.max_link_ratio)  # the slot is a link (crank = 1)
        & (np.abs(swung - request.swing) <= SWING_SLACK * request.swing)
    )
    return [
        Fitted(picked[h], OutputTag.RPR, 0, OutputDyad.rpr(complex(p)), moved=True)
        for h, p in zip(hits[keep], pivots[keep])
    ]


def _with_point(row: SegmentRow, point: complex) -> SegmentRow:
    """``row`` (a line of the four-bar) with the grid's coupler point ``point``."""
    fourbar = dataclasses.replace(row.fourbar, u=float(point.real), v=float(point.imag))
    return dataclasses.replace(row, fourbar=fourbar)
