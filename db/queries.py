"""Indexed candidate selection for the synthesis query: :class:`AtlasSource` is the
:class:`synth.query.SegmentSource` of an atlas.

Short walks of the ``dwell`` table's key (kind, level, dwell_key, segment_id) outwards from
each wanted key (a line's dwell angle, an arc's dwell key: :mod:`synth.dwell_key`), filtered
on the linkage's constraints inside the walk (the table is the index: every column the
query needs comes with the walked row), then one read of the chosen segments and their linkages by primary key; for the complete search, a keyset walk of
the same key through every row of one kind and level. Units as stored: crank lengths,
radians.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

from sqlalchemy import Engine, and_, bindparam, func, or_, select
from sqlalchemy.orm import Session

from db.engine import atlas_name, damaged
from db.rows import length_ceil_milli, line_point, transmission_floor_cdeg
from db.schema import Dwell, Linkage, Segment, stored_dwell_angle
from db.spec import last_spec, tolerances
from synth.kinds import SegmentKind
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
    """Segments of ``kinds`` whose dwell key (part 0) lies in one of ``windows``: window by window,
    each window's closest first (then id, for a stable order); a segment is returned once, at
    the level of its first match. Only linkages whose transmission angle stays ≥
    ``min_transmission`` (rad) over the turn and whose links are all ≤ ``max_length`` (cranks)
    are considered; an arc's radius (the RRR rod) must lie in [longest four-bar link ·
    ``min_radius_ratio``, ``max_length``].

    Each (kind, level, window) is read as two walks of the dwell table's key outwards from the
    target — key ≥ target upwards, key < target downwards, each stopping after ``limit``
    rows that pass or at the window's edge. The rows hold every filtered column, so a walked
    row costs one b-tree entry, not a join; one statement is compiled for all the walks."""
    tolerance = dict(tolerance_levels(engine))
    base = select(*_DWELL_COLUMNS).where(
        Dwell.kind == bindparam("kind"), Dwell.level == bindparam("level"),
        *_filters(min_transmission, max_length, min_radius_ratio))
    up = (base.where(Dwell.dwell_key >= bindparam("target"), Dwell.dwell_key <= bindparam("high"))
          .order_by(Dwell.dwell_key, Dwell.segment_id).limit(bindparam("n")))
    down = (base.where(Dwell.dwell_key < bindparam("target"), Dwell.dwell_key >= bindparam("low"))
            .order_by(Dwell.dwell_key.desc(), Dwell.segment_id).limit(bindparam("n")))
    hits: list[Any] = []
    seen: set[int] = set()
    with engine.connect() as conn:
        for w in windows:
            found = []
            for kind in kinds:
                for lv in tolerance if w.level is None else [w.level]:
                    args = {"kind": SegmentKind(kind).code, "level": lv, "target": w.target, "low": w.low,
                            "high": w.high, "n": w.limit}
                    found += conn.execute(up, args).all() + conn.execute(down, args).all()
            found.sort(key=lambda h: (abs(h.dwell_key - w.target), h.segment_id, h.level))
            for h in found[: w.limit]:
                if h.segment_id not in seen:
                    seen.add(h.segment_id)
                    hits.append(h)
        return _segment_rows(engine, conn, hits, tolerance)


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
    :func:`select_segments`, in batches of up to ``batch`` (in dwell-key order: a keyset walk
    of the dwell table's key, so each batch costs its own rows, not an offset)."""
    page = (select(*_DWELL_COLUMNS)
            .where(Dwell.kind == SegmentKind(kind).code, Dwell.level == level,
                   *_filters(min_transmission, max_length, min_radius_ratio),
                   or_(Dwell.dwell_key > bindparam("key"),
                       and_(Dwell.dwell_key == bindparam("key"), Dwell.segment_id > bindparam("sid"))))
            .order_by(Dwell.dwell_key, Dwell.segment_id).limit(batch))
    tolerance = dict(tolerance_levels(engine))
    key, sid = -1.0, -1
    while True:
        with engine.connect() as conn:
            hits = conn.execute(page, {"key": key, "sid": sid}).all()
            if not hits:
                return
            rows = _segment_rows(engine, conn, hits, tolerance)
        key, sid = hits[-1].dwell_key, hits[-1].segment_id
        yield rows


def count_segments(engine: Engine, kind: str, level: int, *, min_transmission: float = 0.0,
                   max_length: float = 1e300, min_radius_ratio: float = 0.0) -> int:
    """How many segments :func:`scan_segments` walks (one count over the index)."""
    with engine.connect() as conn:
        return int(conn.execute(select(func.count()).select_from(Dwell).where(
            Dwell.kind == SegmentKind(kind).code, Dwell.level == level,
            *_filters(min_transmission, max_length, min_radius_ratio))).scalar_one())


#: What the walks read of a dwell row: the key, then the stretch(es) it describes.
_DWELL_COLUMNS = (Dwell.segment_id, Dwell.level, Dwell.dwell_key, stored_dwell_angle(Dwell).label("dwell_angle"),
                  Dwell.phi_start, Dwell.x, Dwell.y, Dwell.direction,
                  Dwell.radius, Dwell.dwell_angle2, Dwell.phi_start2, Dwell.x2, Dwell.direction2)
#: What a query reads of a segment: its own columns and its linkage's (one join by primary key).
_SEGMENTS = (select(Segment.id, Segment.kind, Segment.u, Segment.v, Segment.phi_gen, Linkage.b, Linkage.c, Linkage.d,
                    Linkage.branch, Linkage.transmission_min).join(Linkage, Segment.linkage_id == Linkage.id))
#: Beyond this a length limit (cranks) filters nothing and would overflow a 64-bit integer.
_NO_LENGTH_LIMIT = 1e12


def _filters(min_transmission: float, max_length: float, min_radius_ratio: float) -> list:
    """The linkage's and arc's limits on a dwell row, on its own columns: a walk never leaves
    the table's b-tree. The linkage's figures are stored floored (transmission, 0.01°) and
    ceiled (longest link, 0.001 crank); comparing them with the limit rounded the same way
    keeps every linkage that meets the limit (rounding is monotone) and lets through a few
    within 0.01° or 0.001 crank of it, which the exact figures then reject."""
    out = [Dwell.transmission_min_cdeg >= transmission_floor_cdeg(min_transmission)]
    if max_length < _NO_LENGTH_LIMIT:
        out += [Dwell.longest_link_milli <= length_ceil_milli(max_length),
                or_(Dwell.radius.is_(None), Dwell.radius <= max_length)]  # an arc's radius is the rod
    if min_radius_ratio > 0:
        out.append(or_(Dwell.radius.is_(None), and_(
            # (milli − 2)/1000 is below the longest link whatever the rounding of its copy
            Dwell.radius >= min_radius_ratio, Dwell.radius * 1000 >= min_radius_ratio * (Dwell.longest_link_milli - 2))))
    return out


def _parts(dw) -> tuple[tuple, ...]:
    """A walked dwell row as :attr:`SegmentRow.parts`: per stretch (phi_start, phi_end, x, y,
    direction or None, radius or None); a line's point is its foot from A0."""
    if dw.radius is not None:
        return ((dw.phi_start, dw.phi_start + dw.dwell_angle, dw.x, dw.y, None, dw.radius),)
    parts = [_line_part(dw.phi_start, dw.dwell_angle, dw.x, dw.direction)]
    if dw.dwell_angle2 is not None:
        parts.append(_line_part(dw.phi_start2, dw.dwell_angle2, dw.x2, dw.direction2))
    return tuple(parts)


def _line_part(phi_start: float, dwell_angle: float, offset: float, direction: float) -> tuple:
    foot = line_point(offset, direction)
    return (phi_start, phi_start + dwell_angle, foot.real, foot.imag, direction, None)


def _segment_rows(engine: Engine, conn, hits: Sequence, tolerance: dict[int, float]) -> list[SegmentRow]:
    """The :class:`SegmentRow` of each walked dwell row of ``hits`` (:data:`_DWELL_COLUMNS`),
    in that order, with its segment and linkage read by primary key; ``tolerance``: level →
    path tolerance (crank lengths)."""
    if not hits:
        return []
    ids = list(dict.fromkeys(h.segment_id for h in hits))
    segs: dict[int, Any] = {}
    # the ids go to the server as bound parameters: a few thousand per statement (SQLite
    # takes at most 32 766 in one, PostgreSQL 65 535)
    for k in range(0, len(ids), IN_CHUNK):
        segs.update((r.id, r) for r in conn.execute(_SEGMENTS.where(Segment.id.in_(ids[k : k + IN_CHUNK]))))
    lost = [h.segment_id for h in hits if h.segment_id not in segs]
    if lost:  # dwell rows whose segment (or its linkage) was deleted: only a damaged atlas
        raise damaged(atlas_name(engine), f"dwell rows name segment {lost[0]}, which does not exist")
    return [_segment_row(segs[h.segment_id], h.level, tolerance.get(h.level, 0.0), h) for h in hits]


def _segment_row(seg, level: int, tolerance: float, dw) -> SegmentRow:
    """A segment (:data:`_SEGMENTS` row) at ``level`` with its dwell row ``dw`` (None: no
    dwell there, ``parts`` empty)."""
    return SegmentRow(
        segment_id=seg.id, kind=seg.kind, level=level, tolerance=tolerance, b=seg.b, c=seg.c, d=seg.d,
        branch=seg.branch, u=seg.u, v=seg.v, phi_gen=seg.phi_gen, parts=() if dw is None else _parts(dw),
        fourbar_transmission_min=seg.transmission_min,
    )


def nearest_dwell_angles(engine: Engine, kinds: tuple[str, ...], target: float) -> tuple[float | None, float | None]:
    """The stored dwell angles (rad) of ``kinds`` just below and just above ``target``: what
    the atlas could offer instead when nothing matches (one index probe per kind and level for
    lines; arcs are keyed otherwise, so their level's rows are scanned)."""
    below: list[float] = []
    above: list[float] = []
    with Session(engine) as s:
        for kind in kinds:
            for lv, _ in tolerance_levels(engine):
                here = and_(Dwell.kind == SegmentKind(kind).code, Dwell.level == lv)
                angle = Dwell.dwell_angle if kind == SegmentKind.ARC else Dwell.dwell_key
                b = s.execute(select(func.max(angle)).where(here, angle <= target)).scalar()
                a = s.execute(select(func.min(angle)).where(here, angle >= target)).scalar()
                below += [] if b is None else [b]
                above += [] if a is None else [a]
    return max(below, default=None), min(above, default=None)


def tolerance_levels(engine: Engine) -> list[tuple[int, float]]:
    """The atlas's (level, tolerance) pairs, in level order, from its build's sweep spec (the
    dwell table itself is too large to scan for them)."""
    spec = last_spec(engine)
    return [] if spec is None else list(enumerate(tolerances(spec)))


def segment_row(engine: Engine, segment_id: int, level: int) -> SegmentRow | None:
    """Segment ``segment_id`` with its dwell row at ``level`` (``parts`` empty if it has none
    there); None if the atlas has no such segment. A rare path (reports, rebuilt ids): the
    dwell row is found by a scan of its kind and level, which no index serves."""
    with engine.connect() as conn:
        seg = conn.execute(_SEGMENTS.where(Segment.id == segment_id)).first()
        if seg is None:
            return None
        dw = conn.execute(select(*_DWELL_COLUMNS).where(
            Dwell.kind == SegmentKind(seg.kind).code, Dwell.level == level, Dwell.segment_id == segment_id)).first()
    return _segment_row(seg, level, 0.0 if dw is None else dict(tolerance_levels(engine)).get(level, 0.0), dw)


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
