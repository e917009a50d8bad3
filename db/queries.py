"""Indexed candidate selection for the synthesis query: :class:`AtlasSource` is the
:class:`synth.query.SegmentSource` of an atlas.

Short walks of ``ix_dwell_query`` (kind, level, dwell_angle) outwards from each wanted dwell
angle, joined to their segment and linkage and filtered on the linkage's constraints, then one
read of the chosen segments and their dwell rows; for the complete search, a keyset walk of
the same index through every row of one kind and level. Units as stored: crank lengths,
radians.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

from sqlalchemy import Engine, and_, bindparam, func, or_, select
from sqlalchemy.orm import Session

from db.engine import atlas_name, damaged
from db.schema import Dwell, Linkage, Segment
from db.spec import last_spec, tolerances
from synth.query import DwellWindow, SegmentRow

#: Segment ids bound in one statement of :func:`select_segments`.
IN_CHUNK = 5000

__all__ = ["AtlasSource", "DwellWindow", "SegmentRow", "count_segments", "nearest_dwell_angles", "scan_segments",
           "select_segments", "tolerance_levels"]


def select_segments(
    engine: Engine,
    kinds: tuple[str, ...],
    windows: Sequence[DwellWindow],
    *,
    min_transmission: float = 0.0,
    max_length: float = 1e300,
    min_radius_ratio: float = 0.0,
) -> list[SegmentRow]:
    """Segments of ``kinds`` whose dwell (part 0) lies in one of ``windows``: window by window,
    each window's closest first (then id, for a stable order); a segment is returned once, at
    the level of its first match. Only linkages whose transmission angle stays ≥
    ``min_transmission`` (rad) over the turn and whose links are all ≤ ``max_length`` (cranks)
    are considered; an arc's radius (the RRR rod) must lie in [longest four-bar link ·
    ``min_radius_ratio``, ``max_length``].

    Each (kind, level, window) is read as two walks of ``ix_dwell_query`` outwards from the
    target — dwell ≥ target upwards, dwell < target downwards, each stopping after ``limit``
    rows that pass or at the window's edge. The index covers every filter, so a walked row
    costs an index entry, not a join; one statement is compiled for all the walks."""
    levels = [lv for lv, _ in tolerance_levels(engine)]
    base = select(Dwell.segment_id, Dwell.level, Dwell.dwell_angle).where(
        Dwell.kind == bindparam("kind"), Dwell.level == bindparam("level"),
        *_filters(min_transmission, max_length, min_radius_ratio))
    up = (base.where(Dwell.dwell_angle >= bindparam("target"), Dwell.dwell_angle <= bindparam("high"))
          .order_by(Dwell.dwell_angle, Dwell.segment_id).limit(bindparam("n")))
    down = (base.where(Dwell.dwell_angle < bindparam("target"), Dwell.dwell_angle >= bindparam("low"))
            .order_by(Dwell.dwell_angle.desc(), Dwell.segment_id).limit(bindparam("n")))
    hits: list[tuple[int, int]] = []
    seen: set[int] = set()
    with engine.connect() as conn:
        for w in windows:
            found = []
            for kind in kinds:
                for lv in levels if w.level is None else [w.level]:
                    args = {"kind": kind, "level": lv, "target": w.target, "low": w.low, "high": w.high, "n": w.limit}
                    found += conn.execute(up, args).all() + conn.execute(down, args).all()
            found.sort(key=lambda h: (abs(h.dwell_angle - w.target), h.segment_id, h.level))
            for h in found[: w.limit]:
                if h.segment_id not in seen:
                    seen.add(h.segment_id)
                    hits.append((h.segment_id, h.level))
        return _segment_rows(engine, conn, hits)


def scan_segments(
    engine: Engine,
    kind: str,
    level: int,
    *,
    min_transmission: float = 0.0,
    max_length: float = 1e300,
    min_radius_ratio: float = 0.0,
    batch: int = 4000,
) -> Iterator[list[SegmentRow]]:
    """Every segment of ``kind`` with a dwell at ``level``, filtered as in
    :func:`select_segments`, in batches of up to ``batch`` (in stored-dwell order: a keyset walk
    of ``ix_dwell_query``, so each batch costs its own rows, not an offset)."""
    page = (select(Dwell.segment_id, Dwell.dwell_angle)
            .where(Dwell.kind == kind, Dwell.level == level, *_filters(min_transmission, max_length, min_radius_ratio),
                   or_(Dwell.dwell_angle > bindparam("angle"),
                       and_(Dwell.dwell_angle == bindparam("angle"), Dwell.segment_id > bindparam("sid"))))
            .order_by(Dwell.dwell_angle, Dwell.segment_id).limit(batch))
    angle, sid = -1.0, -1
    while True:
        with engine.connect() as conn:
            hits = conn.execute(page, {"angle": angle, "sid": sid}).all()
            if not hits:
                return
            rows = _segment_rows(engine, conn, [(h.segment_id, level) for h in hits])
        angle, sid = hits[-1].dwell_angle, hits[-1].segment_id
        yield rows


def count_segments(engine: Engine, kind: str, level: int, *, min_transmission: float = 0.0,
                   max_length: float = 1e300, min_radius_ratio: float = 0.0) -> int:
    """How many segments :func:`scan_segments` walks (one count over the index)."""
    with engine.connect() as conn:
        return int(conn.execute(select(func.count()).select_from(Dwell).where(
            Dwell.kind == kind, Dwell.level == level,
            *_filters(min_transmission, max_length, min_radius_ratio))).scalar_one())


def _filters(min_transmission: float, max_length: float, min_radius_ratio: float) -> list:
    """The linkage's and arc's limits on a dwell row (part 0). Every filter reads
    ix_dwell_query's own columns: a walk never leaves the index."""
    return [
        Dwell.part == 0,
        Dwell.linkage_transmission_min >= min_transmission,
        Dwell.longest_link <= max_length,
        or_(Dwell.radius.is_(None), Dwell.radius <= max_length),  # an arc's radius is the rod
        *(() if min_radius_ratio <= 0 else (or_(Dwell.radius.is_(None), and_(
            Dwell.radius >= min_radius_ratio, Dwell.radius >= min_radius_ratio * Dwell.longest_link)),)),
    ]


def _segment_rows(engine: Engine, conn, hits: Sequence[tuple[int, int]]) -> list[SegmentRow]:
    """The :class:`SegmentRow` of each (segment id, level) of ``hits``, in that order (a double
    line without both stretches at its level is left out)."""
    if not hits:
        return []
    ids = list(dict.fromkeys(sid for sid, _ in hits))
    by_level: dict[int, list[int]] = {}
    for sid, lv in hits:
        by_level.setdefault(lv, []).append(sid)
    segs: dict[int, Any] = {}
    parts: dict[tuple[int, int], list] = {}
    # the ids go to the server as bound parameters: a few thousand per statement (SQLite
    # takes at most 32 766 in one, PostgreSQL 65 535)
    for k in range(0, len(ids), IN_CHUNK):
        segs.update((r.id, r) for r in conn.execute(
            select(Segment.id, Segment.kind, Segment.u, Segment.v, Segment.phi_gen, Linkage.b, Linkage.c, Linkage.d,
                   Linkage.branch, Linkage.transmission_min)
            .join(Linkage, Segment.linkage_id == Linkage.id).where(Segment.id.in_(ids[k : k + IN_CHUNK]))
        ))
    # only the dwell rows of the wanted levels (a scan wants one of a segment's several)
    for lv, at_level in by_level.items():
        for k in range(0, len(at_level), IN_CHUNK):
            for dw in conn.execute(
                select(Dwell.segment_id, Dwell.part, Dwell.tolerance, Dwell.phi_start, Dwell.phi_end, Dwell.x,
                       Dwell.y, Dwell.direction, Dwell.radius)
                .where(Dwell.level == lv, Dwell.segment_id.in_(at_level[k : k + IN_CHUNK]))
                .order_by(Dwell.segment_id, Dwell.part)
            ):
                parts.setdefault((dw.segment_id, lv), []).append(dw)
    lost = [sid for sid, _ in hits if sid not in segs]
    if lost:  # dwell rows whose segment (or its linkage) was deleted: only a damaged atlas
        raise damaged(atlas_name(engine), f"dwell rows name segment {lost[0]}, which does not exist")
    out: list[SegmentRow] = []
    for sid, lv in hits:
        seg, dws = segs[sid], parts.get((sid, lv), [])
        if seg.kind == "double_line" and len(dws) != 2:
            continue  # a double line needs both stretches at this level
        out.append(
            SegmentRow(
                segment_id=sid,
                kind=seg.kind,
                level=lv,
                tolerance=dws[0].tolerance,
                b=seg.b,
                c=seg.c,
                d=seg.d,
                branch=seg.branch,
                u=seg.u,
                v=seg.v,
                phi_gen=seg.phi_gen,
                parts=tuple((dw.phi_start, dw.phi_end, dw.x, dw.y, dw.direction, dw.radius) for dw in dws),
                fourbar_transmission_min=seg.transmission_min,
            )
        )
    return out


def nearest_dwell_angles(engine: Engine, kinds: tuple[str, ...], target: float) -> tuple[float | None, float | None]:
    """The stored dwell angles (rad) of ``kinds`` just below and just above ``target``: what
    the atlas could offer instead when nothing matches (one index probe per kind and level)."""
    below: list[float] = []
    above: list[float] = []
    with Session(engine) as s:
        for kind in kinds:
            for lv, _ in tolerance_levels(engine):
                here = and_(Dwell.kind == kind, Dwell.level == lv)
                b = s.execute(select(func.max(Dwell.dwell_angle)).where(here, Dwell.dwell_angle <= target)).scalar()
                a = s.execute(select(func.min(Dwell.dwell_angle)).where(here, Dwell.dwell_angle >= target)).scalar()
                below += [] if b is None else [b]
                above += [] if a is None else [a]
    return max(below, default=None), min(above, default=None)


def tolerance_levels(engine: Engine) -> list[tuple[int, float]]:
    """The atlas's (level, tolerance) pairs, in level order, from its build's sweep spec (the
    dwell table itself is too large to scan for them)."""
    spec = last_spec(engine)
    return [] if spec is None else list(enumerate(tolerances(spec)))


def segment_row(engine: Engine, segment_id: int, level: int) -> SegmentRow | None:
    """Segment ``segment_id`` with its dwell row(s) at ``level`` (``parts`` empty if it has
    none there); None if the atlas has no such segment."""
    with engine.connect() as conn:
        seg = conn.execute(
            select(Segment.id, Segment.kind, Segment.u, Segment.v, Segment.phi_gen, Linkage.b, Linkage.c, Linkage.d,
                   Linkage.branch, Linkage.transmission_min)
            .join(Linkage, Segment.linkage_id == Linkage.id).where(Segment.id == segment_id)
        ).first()
        if seg is None:
            return None
        dws = conn.execute(
            select(Dwell.tolerance, Dwell.phi_start, Dwell.phi_end, Dwell.x, Dwell.y, Dwell.direction, Dwell.radius)
            .where(Dwell.segment_id == segment_id, Dwell.level == level).order_by(Dwell.part)
        ).all()
    return SegmentRow(
        segment_id=seg.id, kind=seg.kind, level=level, tolerance=dws[0].tolerance if dws else 0.0,
        b=seg.b, c=seg.c, d=seg.d, branch=seg.branch, u=seg.u, v=seg.v, phi_gen=seg.phi_gen,
        parts=tuple((dw.phi_start, dw.phi_end, dw.x, dw.y, dw.direction, dw.radius) for dw in dws),
        fourbar_transmission_min=seg.transmission_min,
    )


class AtlasSource:
    """The atlas behind ``engine`` as the query's :class:`synth.query.SegmentSource` (reads
    only; the tolerance levels are read once)."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self._levels: list[tuple[int, float]] | None = None

    def tolerance_levels(self) -> list[tuple[int, float]]:
        if self._levels is None:
            self._levels = tolerance_levels(self.engine)
        return self._levels

    def select_segments(self, kinds, windows, *, min_transmission, max_length, min_radius_ratio):
        return select_segments(self.engine, kinds, windows, min_transmission=min_transmission,
                               max_length=max_length, min_radius_ratio=min_radius_ratio)

    def segment(self, segment_id: int, level: int) -> SegmentRow | None:
        return segment_row(self.engine, segment_id, level)

    def nearest_dwell_angles(self, kinds, target):
        return nearest_dwell_angles(self.engine, kinds, target)

    def scan_segments(self, kind, level, *, min_transmission, max_length, min_radius_ratio, batch):
        return scan_segments(self.engine, kind, level, min_transmission=min_transmission, max_length=max_length,
                             min_radius_ratio=min_radius_ratio, batch=batch)

    def count_segments(self, kind, level, *, min_transmission, max_length, min_radius_ratio):
        return count_segments(self.engine, kind, level, min_transmission=min_transmission, max_length=max_length,
                              min_radius_ratio=min_radius_ratio)
