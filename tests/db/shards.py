"""A hand-made shard result for the database tests: one linkage, one arc segment, one dwell
(its dwell key equal to its angle: an excursion of 1 crank), with ids from ``db.rows``'s scheme;
and a shard's tables with rows changed or added (:func:`with_rows`)."""

from __future__ import annotations

from dataclasses import replace

from atlas.shard import ShardResult
from db.rows import SEGMENTS_PER_LINKAGE, TableColumns, linkage_id


def shard_rows(index: int, *, radius: float | None = 2.0, dwell_angle: float = 0.5) -> ShardResult:
    lid = linkage_id(index, 1)
    sid = lid * SEGMENTS_PER_LINKAGE
    return with_rows(
        ShardResult(
            shard_index=index,
            linkages=[
                dict(
                    id=lid,
                    shard_index=index,
                    sweep_index=index,
                    b=3.0,
                    c=2.5,
                    d=3.0,
                    branch=1,
                    grashof=1,
                    transmission_min=0.5,
                    transmission_max=1.5,
                )
            ],
            segments=[dict(id=sid, linkage_id=lid, kind="arc", phi_gen=1.0, phi_gen2=None, u=1.2, v=0.8)],
            dwells=[
                dict(
                    segment_id=sid,
                    kind=1,
                    level=0,
                    phi_start=0.75,
                    dwell_key=dwell_angle,
                    dwell_angle=dwell_angle,
                    x=0.5,
                    y=0.25,
                    direction=None,
                    radius=radius,
                    transmission_min_cdeg=2864,
                    longest_link_milli=3000,
                    dwell_angle2=None,
                    phi_start2=None,
                    x2=None,
                    direction2=None,
                )
            ],
            skipped={"pole at infinity": index},
            seconds=0.25,
        )
    )


def with_rows(result, **tables):
    """``result`` with each table given as rows (dicts: ``linkages=[...]``) in place of its own
    (every table of ``result`` that is still a list of dicts is made columns too)."""
    new = {}
    for name in ("linkages", "segments", "dwells"):
        rows = tables.get(name, getattr(result, name))
        new[name] = rows if isinstance(rows, TableColumns) else TableColumns.of_rows(None, rows)
    return replace(result, **new)
