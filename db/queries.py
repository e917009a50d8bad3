"""Indexed candidate selection for the synthesis query: :class:`AtlasSource` is the
:class:`synth.query.SegmentSource` of an atlas.

Short walks of the ``dwell`` table's key (kind, level, dwell_key, segment_id) outwards from
each wanted key (a line's dwell angle, an arc's dwell key: :mod:`synth.segment_search.dwell_key`), filtered
on the linkage's constraints inside the walk (the table is the index: every column the
query needs comes with the walked row), then one read of the chosen segments and their linkages by primary key; for the complete search, a keyset walk of
the same key through every row of one kind and level. Units as stored: crank lengths,
radians.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from sqlalchemy import (
    CompoundSelect,
    Engine,
    Float,
    Integer,
    and_,
    bindparam,
    func,
    literal_column,
    or_,
    select,
    union_all,
)
from sqlalchemy.orm import Session

from db.engine import atlas_name, damaged
from db.rows import length_ceil_milli, line_points, transmission_floor_cdeg
from db.schema import Dwell, Linkage, Segment, stored_dwell_angle
from db.spec import last_spec, tolerances
from synth.kinds import SegmentKind
from synth.linkage import CouplerFourBar
from synth.query.contract import DwellWindow
from synth.query.segment_rows import SegmentBatch, SegmentRow

#: Segment ids bound in one statement of :func:`select_segments`.
IN_CHUNK = 5000
#: Walks in one statement of :func:`select_segments` (two parts of a UNION ALL each: SQLite
#: allows 500).
WALKS_CHUNK = 32

__all__ = [
    "AtlasSource",
    "DwellWindow",
    "SegmentRow",
    "count_segments",
    "nearest_dwell_angles",
    "scan_segments",
    "select_segments",
    "tolerance_levels",
]


def select_segments(
    engine: Engine,
    kinds: tuple[str, ...],
    windows: Sequence[DwellWindow],
    *,
    min_transmission: float = 0.0,
    max_length: float = 1e300,
    min_radius_ratio: float = 0.0,
    levels: Sequence[tuple[int, float]] | None = None,
) -> list[SegmentRow]:
    """Segments of ``kinds`` whose dwell key (part 0) lies in one of ``windows``: window by window,
    each window's closest first (then id, for a stable order); a segment is returned once, at
    the level of its first match. Only linkages whose transmission angle stays ≥
    ``min_transmission`` (rad) over the turn and whose links are all ≤ ``max_length`` (cranks)
    are considered; an arc's radius (the RRR rod) must lie in [longest four-bar link ·
    ``min_radius_ratio``, ``max_length``]. ``levels``: the atlas's :func:`tolerance_levels`
    if the caller has them (:class:`AtlasSource` reads them once), else they are read here.

    Each (window, kind, level) is read as two walks of the dwell table's key outwards from the
    target — key ≥ target upwards, key < target downwards, each stopping after ``limit``
    rows that pass or at the window's edge. The rows hold every filtered column, so a walked
    row costs one b-tree entry, not a join. The walks go to the server together, as one
    statement (:func:`_walks`, built once per shape) for up to :data:`WALKS_CHUNK` of them: a
    query's dozens of walks cost one round trip, not one each."""
    levels = tolerance_levels(engine) if levels is None else levels
    tolerance = dict(levels)
    length, ratio, limits = _limits(min_transmission, max_length, min_radius_ratio)
    # (window, kind, level) in the order the walks' rows are taken on a tie
    walks = [
        (i, SegmentKind(kind).code, lv)
        for i, w in enumerate(windows)
        for kind in kinds
        for lv in (tolerance if w.level is None else [w.level])
    ]
    # per window: (distance from its target, segment id, level, walk number, dwell row)
    found: list[list[tuple]] = [[] for _ in windows]
    with engine.connect() as conn:
        for start in range(0, len(walks), WALKS_CHUNK):
            chunk = walks[start : start + WALKS_CHUNK]
            args = dict(limits)
            for k, (i, code, lv) in enumerate(chunk):
                w = windows[i]
                args |= {
                    f"kind_{k}": code,
                    f"level_{k}": lv,
                    f"target_{k}": w.target,
                    f"low_{k}": w.low,
                    f"high_{k}": w.high,
                    f"n_{k}": w.limit,
                }
            for h in conn.execute(_walks(len(chunk), length, ratio), args).all():
                sid, level, key, *_, walk = h  # unpacked: a row's attributes cost ~0.3 µs each
                i = chunk[walk // 2][0]
                found[i].append((abs(key - windows[i].target), sid, level, 2 * start + walk, h))
        hits: list[Any] = []
        seen: set[int] = set()
        for w, rows in zip(windows, found):
            # the walk's number breaks ties as the order of the walks did; it never ties itself
            # (a walk holds a segment once), so the rows themselves are never compared
            rows.sort()
            for *_, h in rows[: w.limit]:
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
) -> Iterator[SegmentBatch]:
    """Every segment of ``kind`` with a dwell at ``level``, filtered as in
    :func:`select_segments`, in batches of up to ``batch`` rows as columns (in dwell-key order: a
    keyset walk of the dwell table's key, so each batch costs its own rows, not an offset; each
    row's segment and linkage joined by primary key in the same statement)."""
    length, ratio, limits = _limits(min_transmission, max_length, min_radius_ratio)
    page = (
        select(*_DWELL_COLUMNS, Segment.id.label("segment"), *_SEGMENT_COLUMNS)
        .select_from(Dwell)
        .outerjoin(Segment, Segment.id == Dwell.segment_id)
        .outerjoin(Linkage, Linkage.id == Segment.linkage_id)
        .where(
            Dwell.kind == SegmentKind(kind).code,
            Dwell.level == level,
            *_filters(length, ratio),
            # the key's bound alone is what a b-tree seeks on (an OR of the two is read from
            # the start of the level on every page: quadratic in the pages); the OR then
            # breaks ties on the key by id
            Dwell.dwell_key >= bindparam("key"),
            or_(
                Dwell.dwell_key > bindparam("key"),
                and_(Dwell.dwell_key == bindparam("key"), Dwell.segment_id > bindparam("sid")),
            ),
        )
        .order_by(Dwell.dwell_key, Dwell.segment_id)
        .limit(batch)
    )
    tolerance = dict(tolerance_levels(engine))
    key, sid = -1.0, -1
    while True:
        with engine.connect() as conn:
            hits = conn.execute(page, {**limits, "key": key, "sid": sid}).all()
        if not hits:
            return
        key, sid = hits[-1].dwell_key, hits[-1].segment_id
        yield _segment_batch(engine, kind, hits, tolerance)


def _segment_batch(engine: Engine, kind: str, hits: Sequence, tolerance: dict[int, float]) -> SegmentBatch:
    """The :class:`SegmentBatch` of ``hits``, dwell rows of segments of ``kind`` read with their
    segment and linkage (:data:`_DWELL_COLUMNS`, the segment's id or None if it is missing,
    :data:`_SEGMENT_COLUMNS`); ``tolerance``: level → path tolerance (crank lengths). The one
    place where a stored dwell row becomes the query's stretches: the interval's end is its
    start plus the dwell angle, a line's point its foot from A0 (:func:`db.rows.line_points`)."""
    (
        segment_id,
        levels,
        _,
        angle,
        start,
        x,
        y,
        direction,
        radius,
        angle2,
        start2,
        x2,
        direction2,
        segment,
        u,
        v,
        phi_gen,
        b,
        c,
        d,
        branch,
        transmission_min,
    ) = zip(*hits)
    if None in segment or None in b:  # the outer join found no segment (or linkage) for a dwell row
        raise _lost_segment(engine, segment_id[list(segment).index(None) if None in segment else list(b).index(None)])
    n = len(hits)

    def column(values: Sequence, dtype=np.float64) -> np.ndarray:
        return np.array(values, dtype)

    def nullable(values: Sequence) -> np.ndarray:
        return np.array([np.nan if x is None else x for x in values], np.float64) if None in values else column(values)

    start = column(start)
    first = np.empty((n, 6))
    first[:, 0], first[:, 1] = start, start + column(angle)
    if kind == SegmentKind.ARC.value:
        first[:, 2], first[:, 3], first[:, 4], first[:, 5] = column(x), column(y), np.nan, column(radius)
    else:
        direction = column(direction)
        foot = line_points(column(x), direction)
        first[:, 2], first[:, 3], first[:, 4], first[:, 5] = foot.real, foot.imag, direction, np.nan
    parts: tuple[np.ndarray, ...] = (first,)
    has_parts = np.ones(n, np.int64)
    if kind == SegmentKind.DOUBLE_LINE.value:
        angle2, start2 = nullable(angle2), nullable(start2)
        direction2 = nullable(direction2)
        foot2 = line_points(nullable(x2), direction2)
        second = np.stack([start2, start2 + angle2, foot2.real, foot2.imag, direction2, np.full(n, np.nan)], axis=1)
        parts = (first, second)
        has_parts += ~np.isnan(angle2)
    return SegmentBatch(
        kind,
        column(segment_id, np.int64),
        column(levels, np.int64),
        column([tolerance.get(lv, 0.0) for lv in levels]),
        CouplerFourBar(
            b=column(b), c=column(c), d=column(d), branch=column(branch, np.int64), u=column(u), v=column(v)
        ),
        column(phi_gen),
        column(transmission_min),
        parts,
        has_parts,
    )


def count_segments(
    engine: Engine,
    kind: str,
    level: int,
    *,
    min_transmission: float = 0.0,
    max_length: float = 1e300,
    min_radius_ratio: float = 0.0,
) -> int:
    """How many segments :func:`scan_segments` walks (one count over the index)."""
    length, ratio, limits = _limits(min_transmission, max_length, min_radius_ratio)
    with engine.connect() as conn:
        return int(
            conn.execute(
                select(func.count())
                .select_from(Dwell)
                .where(Dwell.kind == SegmentKind(kind).code, Dwell.level == level, *_filters(length, ratio)),
                limits,
            ).scalar_one()
        )


#: What the walks read of a dwell row: the key, then the stretch(es) it describes.
_DWELL_COLUMNS = (
    Dwell.segment_id,
    Dwell.level,
    Dwell.dwell_key,
    stored_dwell_angle(Dwell).label("dwell_angle"),
    Dwell.phi_start,
    Dwell.x,
    Dwell.y,
    Dwell.direction,
    Dwell.radius,
    Dwell.dwell_angle2,
    Dwell.phi_start2,
    Dwell.x2,
    Dwell.direction2,
)
#: What a query reads of a dwell row's segment and linkage.
_SEGMENT_COLUMNS = (
    Segment.u,
    Segment.v,
    Segment.phi_gen,
    Linkage.b,
    Linkage.c,
    Linkage.d,
    Linkage.branch,
    Linkage.transmission_min,
)
#: A segment with :data:`_SEGMENT_COLUMNS`, after its id and kind (one join by primary key).
_SEGMENTS = select(Segment.id, Segment.kind, *_SEGMENT_COLUMNS).join(Linkage, Segment.linkage_id == Linkage.id)
#: :data:`_SEGMENTS` of the segment ids bound as ``ids`` (one statement object, so that its
#: compiled form and result columns are reused, not rebuilt, at every query).
_SEGMENTS_BY_ID = _SEGMENTS.where(Segment.id.in_(bindparam("ids", expanding=True)))
#: Beyond this a length limit (cranks) filters nothing and would overflow a 64-bit integer.
_NO_LENGTH_LIMIT = 1e12


def _limits(min_transmission: float, max_length: float, min_radius_ratio: float) -> tuple[bool, bool, dict]:
    """The request's limits for :func:`_filters`: whether a length limit and a radius ratio
    apply (a statement has their conditions only then), and the values of the bound
    parameters, rounded as the dwell rows store the linkage's figures (see :func:`_filters`)."""
    length, ratio = max_length < _NO_LENGTH_LIMIT, min_radius_ratio > 0
    values: dict[str, Any] = {"min_cdeg": transmission_floor_cdeg(min_transmission)}
    if length:
        values |= {"max_milli": length_ceil_milli(max_length), "max_length": max_length}
    if ratio:
        values["min_radius_ratio"] = min_radius_ratio
    return length, ratio, values


def _filters(length: bool, ratio: bool) -> list:
    """The linkage's and arc's limits on a dwell row, on its own columns: a walk never leaves
    the table's b-tree; with ``length`` a length limit, with ``ratio`` a radius ratio. The
    limits are bound parameters (their values: :func:`_limits`), so that a statement is built
    once for all requests. The linkage's figures are stored floored (transmission, 0.01°) and
    ceiled (longest link, 0.001 crank); comparing them with the limit rounded the same way
    keeps every linkage that meets the limit (rounding is monotone) and lets through a few
    within 0.01° or 0.001 crank of it, which the exact figures then reject."""
    out = [Dwell.transmission_min_cdeg >= bindparam("min_cdeg")]
    if length:
        out += [
            Dwell.longest_link_milli <= bindparam("max_milli"),
            or_(Dwell.radius.is_(None), Dwell.radius <= bindparam("max_length")),
        ]  # an arc's radius is the rod
    if ratio:
        min_ratio = bindparam("min_radius_ratio", type_=Float)
        out.append(
            or_(
                Dwell.radius.is_(None),
                and_(
                    # (milli − 2)/1000 is below the longest link whatever the rounding of its copy
                    Dwell.radius >= min_ratio,
                    Dwell.radius * 1000 >= min_ratio * (Dwell.longest_link_milli - 2),
                ),
            )
        )
    return out


@functools.cache
def _walks(n: int, length: bool, ratio: bool) -> CompoundSelect:
    """One statement for ``n`` (window, kind, level) walks of :func:`select_segments`, the
    limits as :func:`_filters` (``length``, ``ratio``): walk ``k`` reads ``kind_k``,
    ``level_k`` from ``target_k`` up to ``high_k`` and down to ``low_k``, ``n_k`` rows each
    way. A row's ``walk`` is 2k upwards, 2k + 1 downwards. Each walk is a subquery: its
    ORDER BY and LIMIT then hold inside the UNION ALL (SQLite allows them nowhere else)."""
    parts = []
    for k in range(n):
        base = select(*_DWELL_COLUMNS).where(
            Dwell.kind == bindparam(f"kind_{k}"), Dwell.level == bindparam(f"level_{k}"), *_filters(length, ratio)
        )
        target, limit = bindparam(f"target_{k}"), bindparam(f"n_{k}")
        up = (
            base.where(Dwell.dwell_key >= target, Dwell.dwell_key <= bindparam(f"high_{k}"))
            .order_by(Dwell.dwell_key, Dwell.segment_id)
            .limit(limit)
        )
        down = (
            base.where(Dwell.dwell_key < target, Dwell.dwell_key >= bindparam(f"low_{k}"))
            .order_by(Dwell.dwell_key.desc(), Dwell.segment_id)
            .limit(limit)
        )
        parts += [
            walk.subquery().select().add_columns(literal_column(str(2 * k + way), Integer).label("walk"))
            for way, walk in enumerate((up, down))
        ]
    return union_all(*parts)


def _lost_segment(engine: Engine, segment_id: int) -> Exception:
    """The error for dwell rows whose segment (or its linkage) was deleted: only a damaged atlas has them."""
    return damaged(atlas_name(engine), f"dwell rows name segment {segment_id}, which does not exist")


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
        segs.update((r[0], r) for r in conn.execute(_SEGMENTS_BY_ID, {"ids": ids[k : k + IN_CHUNK]}).all())
    lost = [h.segment_id for h in hits if h.segment_id not in segs]
    if lost:
        raise _lost_segment(engine, lost[0])
    width = len(_DWELL_COLUMNS)
    by_kind: dict[str, list[int]] = {}
    joined = []
    for i, h in enumerate(hits):
        seg = segs[h.segment_id]
        joined.append((*h[:width], seg[0], *seg[2:]))
        by_kind.setdefault(seg[1], []).append(i)
    out: list[SegmentRow] = [None] * len(hits)  # type: ignore[list-item]
    for kind, index in by_kind.items():
        for i, row in zip(index, _segment_batch(engine, kind, [joined[i] for i in index], tolerance)):
            out[i] = row
    return out


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
        dw = conn.execute(
            select(*_DWELL_COLUMNS).where(
                Dwell.kind == SegmentKind(seg.kind).code, Dwell.level == level, Dwell.segment_id == segment_id
            )
        ).first()
    if dw is None:
        segment_id, kind, u, v, phi_gen, b, c, d, branch, transmission_min = seg
        fourbar = CouplerFourBar(b=b, c=c, d=d, branch=branch, u=u, v=v)
        return SegmentRow(segment_id, kind, level, 0.0, fourbar, phi_gen, (), transmission_min)
    return _segment_batch(engine, seg.kind, [(*dw, seg[0], *seg[2:])], dict(tolerance_levels(engine)))[0]


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
        return select_segments(
            self.engine,
            kinds,
            windows,
            min_transmission=min_transmission,
            max_length=max_length,
            min_radius_ratio=min_radius_ratio,
            levels=self.tolerance_levels(),
        )

    def segment(self, segment_id: int, level: int) -> SegmentRow | None:
        return segment_row(self.engine, segment_id, level)

    def nearest_dwell_angles(self, kinds, target):
        return nearest_dwell_angles(self.engine, kinds, target)

    def scan_segments(self, kind, level, *, min_transmission, max_length, min_radius_ratio, batch):
        return scan_segments(
            self.engine,
            kind,
            level,
            min_transmission=min_transmission,
            max_length=max_length,
            min_radius_ratio=min_radius_ratio,
            batch=batch,
        )

    def count_segments(self, kind, level, *, min_transmission, max_length, min_radius_ratio):
        return count_segments(
            self.engine,
            kind,
            level,
            min_transmission=min_transmission,
            max_length=max_length,
            min_radius_ratio=min_radius_ratio,
        )
