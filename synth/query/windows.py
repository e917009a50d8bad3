"""The sample the query fits (:func:`select`): per segment kind and tolerance level, the stored
rows whose dwell key lies nearest a target the request predicts (:func:`_line_windows`,
:func:`_arc_windows`).
"""

from __future__ import annotations

import itertools
import math

from synth.kinds import OutputTag, SegmentKind
from synth.query.candidates import Request
from synth.query.contract import DwellWindow, SegmentSource
from synth.query.segment_rows import SegmentRow
from synth.segment_search.dwell_key import arc_key_target

#: Segments taken from the atlas per kind and tolerance level, closest to that level's target first.
PER_LEVEL = 10

#: Output link lengths (crank lengths) tried in the band conversion of ``_select``.
REACHES = (0.8, 1.5, 3.0)

#: The slot reaches whose lines a sparse answer also refines as near misses (those within the
#: link ratio; synth.query.pipeline): a long rest lies along a long stretch of the coupler
#: path, so the slot's pivot sits far from it and the output's band is a wide path band there
#: — the stored dwell that predicts the rest is shorter than REACHES alone target (RPR 180° at
#: a 30° swing on ``standard``: its six-bars lie on stretches that store 180°–221° at 0.01
#: crank, below the targets of 252°–350° the short reaches set at that level).
LONG_REACHES = (*REACHES, 6.0, 10.0)


def kinds_for(request: Request) -> tuple[SegmentKind, ...]:
    """Segment kinds a request draws on."""
    if request.dwells == 2:
        return (SegmentKind.DOUBLE_LINE,)
    if request.output == OutputTag.RPR:
        return (SegmentKind.LINE,)
    if request.output == OutputTag.RRR:
        return (SegmentKind.ARC,)
    return (SegmentKind.LINE, SegmentKind.ARC)


def select(
    source: SegmentSource,
    request: Request,
    kinds: tuple[SegmentKind, ...],
    per_level: int = PER_LEVEL,
    reaches: tuple[float, ...] = REACHES,
) -> list[SegmentRow]:
    """Segments worth fitting, per kind and tolerance level (each kind's rows in the order of
    its windows, :func:`_line_windows` (for the slot ``reaches``) and :func:`_arc_windows`).
    Only constraints the four-bar alone decides are applied here (crank = 1, the shortest
    link); an arc's radius becomes the rod, which must not be the link that breaks the ratio."""
    rows = []
    for kind in kinds:
        windows = (
            _arc_windows(source, request, per_level)
            if kind == SegmentKind.ARC
            else _line_windows(source, request, per_level, reaches)
        )
        rows += source.select_segments(
            (kind,),
            windows,
            min_transmission=request.min_transmission,
            max_length=request.max_link_ratio,
            min_radius_ratio=1.0 / request.max_link_ratio,
        )
    return rows


def _line_windows(
    source: SegmentSource, request: Request, per_level: int, reaches: tuple[float, ...] = REACHES
) -> list[DwellWindow]:
    """Stored dwells of lines (and double lines) worth fitting.

    A six-bar's dwell is measured with an output band (an angle), a segment's with a path band
    ε (a length): the output stands still while the coupler point stays within about
    ε* = R·band/2 of the segment's line, R the slot's reach, a few cranks. Dwells grow like
    ε^¼ (four-point contact), so at level ε_ℓ the segment dwell that gives the requested
    six-bar dwell is about dwell·(ε_ℓ/ε*)^¼; each level is searched around its own target for
    each of ``reaches``, generously — the simulation decides. ``per_level`` segments are
    taken per level and target (twice that closest to the request itself)."""
    width = request.dwell_tol + math.radians(10.0)
    windows = [DwellWindow(None, request.dwell - width, request.dwell + width, request.dwell, 2 * per_level)]
    for (level, eps), reach in itertools.product(source.tolerance_levels(), reaches):
        target = request.dwell * (eps / (reach * request.band / 2)) ** 0.25
        width = request.dwell_tol + 0.2 * target
        windows.append(DwellWindow(level, target - width, target + width, target, per_level))
    return windows


def _arc_windows(source: SegmentSource, request: Request, per_level: int) -> list[DwellWindow]:
    """Dwell keys of arcs worth fitting: per level, the keys nearest the one that predicts the
    requested dwell at the requested swing and band (:func:`synth.segment_search.dwell_key.arc_key_target`;
    the rocker is implied by the swing, so no reaches are guessed), as many as
    :func:`_line_windows` takes per level, within a factor of 2 of it."""
    windows = []
    for level, eps in source.tolerance_levels():
        target = arc_key_target(request.dwell, request.swing, request.band, eps)
        windows.append(DwellWindow(level, target / 2, 2 * target, target, len(REACHES) * per_level))
    return windows
