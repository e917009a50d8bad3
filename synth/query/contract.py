"""What the query reads, and the one part of it ``db/`` needs: the :class:`SegmentSource`
protocol an atlas implements (``db.queries.AtlasSource``) and the :class:`DwellWindow` it is
asked for. The request itself is :class:`synth.query.candidates.Request`, re-exported here.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Protocol

from synth.kinds import SegmentKind
from synth.query.candidates import Request
from synth.query.segment_rows import SegmentBatch, SegmentRow

__all__ = ["ALL_ROWS", "BatchMap", "DwellWindow", "Request", "SegmentBatch", "SegmentRow", "SegmentSource"]


@dataclass(frozen=True, slots=True)
class DwellWindow:
    """Stored rows wanted: at tolerance ``level`` (None: any level), with a dwell key in [low,
    high], the ``limit`` closest to ``target``. A line's dwell key is its dwell angle (rad), an
    arc's the dwell angle × its excursion^¼ (:mod:`synth.segment_search.dwell_key`)."""

    level: int | None
    low: float
    high: float
    target: float
    limit: int


class SegmentSource(Protocol):
    """Where the query reads segments from (an atlas; ``db.queries.AtlasSource``)."""

    def tolerance_levels(self) -> list[tuple[int, float]]:
        """(level, path tolerance in crank lengths) pairs, in level order."""

    def select_segments(
        self,
        kinds: tuple[SegmentKind, ...],
        windows: Sequence[DwellWindow],
        *,
        min_transmission: float,
        max_length: float,
        min_radius_ratio: float,
    ) -> list[SegmentRow]:
        """Segments of ``kinds`` whose dwell key lies in one of ``windows`` (each window's
        closest first, a segment once, at the level of its first match), of linkages whose
        transmission angle stays ≥ ``min_transmission`` (rad) and whose links are ≤
        ``max_length`` (cranks); an arc's radius in [longest link · ``min_radius_ratio``,
        ``max_length``]."""

    def segment(self, segment_id: int, level: int) -> SegmentRow | None:
        """The segment with its dwell row(s) at ``level``; None if the atlas has no such
        segment; a row with empty ``parts`` if it has no dwell at that level."""

    def nearest_dwell_angles(self, kinds: tuple[SegmentKind, ...], target: float) -> tuple[float | None, float | None]:
        """The stored dwell angles (rad) of ``kinds`` just below and just above ``target``."""

    def scan_segments(
        self,
        kind: SegmentKind,
        level: int,
        *,
        min_transmission: float,
        max_length: float,
        min_radius_ratio: float,
        batch: int,
    ) -> Iterator[SegmentBatch]:
        """Every segment of ``kind`` with a dwell at ``level`` (filtered as in
        :meth:`select_segments`), in batches of up to ``batch`` rows as columns."""

    def count_segments(
        self, kind: SegmentKind, level: int, *, min_transmission: float, max_length: float, min_radius_ratio: float
    ) -> int:
        """How many segments :meth:`scan_segments` yields."""


#: No limit on the rows of a window (SQL LIMIT).
ALL_ROWS = 2**62

#: Runs a function over a stream of items and yields the results in any order
#: (the built-in :func:`map` in this process; ``atlas.pool.pool_map`` on worker processes).
BatchMap = Callable[[Callable[[tuple], tuple], Iterator[tuple]], Iterator[tuple]]
