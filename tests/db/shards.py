"""A hand-made shard result for the database tests: one linkage, one arc segment, one dwell,
with ids from ``db.rows``'s scheme."""

from __future__ import annotations

from atlas.shard import ShardResult
from db.rows import DWELLS_PER_SEGMENT, SEGMENTS_PER_LINKAGE, linkage_id


def shard_rows(index: int, *, radius: float | None = 2.0, dwell_angle: float = 0.5) -> ShardResult:
    lid = linkage_id(index, 1)
    sid = lid * SEGMENTS_PER_LINKAGE
    return ShardResult(
        shard_index=index,
        linkages=[dict(id=lid, shard_index=index, sweep_index=index, b=3.0, c=2.5, d=3.0, branch=1, grashof=1,
                       transmission_min=0.5, transmission_max=1.5)],
        segments=[dict(id=sid, linkage_id=lid, kind="arc", phi_gen=1.0, phi_gen2=None, u=1.2, v=0.8)],
        dwells=[dict(id=sid * DWELLS_PER_SEGMENT, segment_id=sid, kind="arc", level=0, tolerance=1e-3, part=0,
                     phi_start=0.75, phi_end=0.75 + dwell_angle, dwell_angle=dwell_angle,
                     x=0.5, y=0.25, direction=None, radius=radius, linkage_transmission_min=0.5, longest_link=3.0)],
        skipped={"pole at infinity": index},
        seconds=0.25,
    )
