"""Indexed candidate selection for the synthesis query.

One SELECT over ``ix_dwell_query`` (kind, level, dwell_angle): the dwell rows of the wanted
kinds whose dwell angle lies in a window around the request, joined to their segment and
linkage, closest dwell first. Units as stored: crank lengths, radians.
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import Engine, and_, func, or_, select
from sqlalchemy.orm import Session

from db.schema import Dwell, Linkage, Segment

__all__ = ["SegmentRow", "nearest_dwell_angles", "select_segments", "tolerance_levels"]


@dataclass(frozen=True, slots=True)
class SegmentRow:
    """A stored segment with the dwell row (one level; both parts for a double line) that
    matched the request. Angles in radians, lengths in crank lengths."""

    segment_id: int
    kind: str
    level: int
    tolerance: float
    b: float
    c: float
    d: float
    branch: int
    u: float
    v: float
    phi_gen: float
    #: per part: (phi_start, phi_end, x, y, direction or None, radius or None)
    parts: tuple[tuple[float, float, float, float, float | None, float | None], ...]
    fourbar_transmission_min: float


def select_segments(
    engine: Engine,
    kinds: tuple[str, ...],
    dwell_low: float,
    dwell_high: float,
    target: float,
    *,
    level: int | None = None,
    min_transmission: float = 0.0,
    max_length: float = 1e300,
    limit: int = 200,
) -> list[SegmentRow]:
    """Segments of ``kinds`` with a dwell angle (part 0; at tolerance ``level``, or any) in
    [dwell_low, dwell_high] rad, at most ``limit``, ordered by |dwell − target| (then id, for
    a stable order). Only linkages whose transmission angle stays ≥ ``min_transmission`` (rad)
    over the turn and whose links are all ≤ ``max_length`` (cranks) are considered."""
    closeness = func.abs(Dwell.dwell_angle - target)
    stmt = (
        select(Dwell.segment_id, Dwell.level, closeness.label("closeness"))
        .join(Segment, Segment.id == Dwell.segment_id)
        .join(Linkage, Linkage.id == Segment.linkage_id)
        .where(
            and_(
                Dwell.kind.in_(kinds),
                Dwell.part == 0,
                Dwell.dwell_angle >= dwell_low,
                Dwell.dwell_angle <= dwell_high,
                *(() if level is None else (Dwell.level == level,)),
                Linkage.transmission_min >= min_transmission,
                Linkage.b <= max_length,
                Linkage.c <= max_length,
                Linkage.d <= max_length,
                or_(Dwell.radius.is_(None), Dwell.radius <= max_length),  # an arc's radius is the rod
            )
        )
        .order_by(closeness, Dwell.segment_id, Dwell.level)
        .limit(limit)
    )
    with Session(engine) as s:
        hits = s.execute(stmt).all()
        if not hits:
            return []
        wanted = {(h.segment_id, h.level) for h in hits}
        ids = sorted({h.segment_id for h in hits})
        rows = s.execute(
            select(Segment, Linkage).join(Linkage, Segment.linkage_id == Linkage.id).where(Segment.id.in_(ids))
        ).all()
        segs = {seg.id: (seg, link) for seg, link in rows}
        dwells = s.execute(select(Dwell).where(Dwell.segment_id.in_(ids)).order_by(Dwell.id)).scalars().all()
    by_key: dict[tuple[int, int], list[Dwell]] = {}
    for dw in dwells:
        by_key.setdefault((dw.segment_id, dw.level), []).append(dw)
    out: list[SegmentRow] = []
    for h in hits:
        key = (h.segment_id, h.level)
        if key not in wanted or h.segment_id not in segs:
            continue
        seg, link = segs[h.segment_id]
        parts = tuple(
            (dw.phi_start, dw.phi_end, dw.x, dw.y, dw.direction, dw.radius) for dw in sorted(by_key[key], key=lambda r: r.part)
        )
        if seg.kind == "double_line" and len(parts) != 2:
            continue  # a double line needs both stretches at this level
        out.append(
            SegmentRow(
                segment_id=seg.id,
                kind=seg.kind,
                level=h.level,
                tolerance=by_key[key][0].tolerance,
                b=link.b,
                c=link.c,
                d=link.d,
                branch=link.branch,
                u=seg.u,
                v=seg.v,
                phi_gen=seg.phi_gen,
                parts=parts,
                fourbar_transmission_min=link.transmission_min,
            )
        )
    return out


def nearest_dwell_angles(engine: Engine, kinds: tuple[str, ...], target: float) -> tuple[float | None, float | None]:
    """The stored dwell angles (rad) of ``kinds`` just below and just above ``target``: what
    the atlas could offer instead when nothing matches."""
    with Session(engine) as s:
        below = s.execute(
            select(func.max(Dwell.dwell_angle)).where(and_(Dwell.kind.in_(kinds), Dwell.dwell_angle <= target))
        ).scalar()
        above = s.execute(
            select(func.min(Dwell.dwell_angle)).where(and_(Dwell.kind.in_(kinds), Dwell.dwell_angle >= target))
        ).scalar()
    return below, above


def tolerance_levels(engine: Engine) -> list[tuple[int, float]]:
    """The atlas's (level, tolerance) pairs, in level order."""
    with Session(engine) as s:
        return [(int(lv), float(t)) for lv, t in s.execute(select(Dwell.level, Dwell.tolerance).distinct().order_by(Dwell.level))]
