"""``db.queries.select_segments`` reads its walks together (a UNION ALL per up to
``WALKS_CHUNK`` walks, the statements built once): its rows are still those of the walks read
one by one, in the same order — checked against the walks spelled out in Python on an atlas
whose dwell keys and distances tie, on SQLite and PostgreSQL (``atlas_url``)."""

from __future__ import annotations

import random

import pytest
from sqlalchemy import insert, select

from atlas.shard import ShardResult
from db import SCHEMA_VERSION, Build, open_atlas
from db.queries import WALKS_CHUNK, AtlasSource, segment_row, select_segments, tolerance_levels
from db.rows import SEGMENTS_PER_LINKAGE, TableColumns, length_ceil_milli, linkage_id, transmission_floor_cdeg
from db.schema import Dwell
from db.writes import finish_build, write_shard
from synth.kinds import SEGMENT_KINDS, SegmentKind
from synth.query.contract import ALL_ROWS, DwellWindow

KINDS = tuple(str(k) for k in SEGMENT_KINDS)
#: Dwell keys and window targets on a grid of sixteenths: keys and distances tie exactly.
GRID = [k / 16 for k in range(1, 40)]


def _shard(rng: random.Random) -> ShardResult:
    """Linkages with a segment of each kind, dwell rows at some of 3 levels, keys on :data:`GRID`."""
    linkages, segments, dwells = [], [], []
    for i in range(60):
        lid = linkage_id(i, 1)
        longest = rng.choice([2.0, 3.5, 6.0, 9.0])
        linkages.append(
            dict(
                id=lid,
                shard_index=0,
                sweep_index=i,
                b=longest,
                c=1.5,
                d=longest / 2,
                branch=1,
                grashof=1,
                transmission_min=0.6,
                transmission_max=1.5,
            )
        )
        for j, kind in enumerate(SEGMENT_KINDS):
            sid = lid * SEGMENTS_PER_LINKAGE + j
            segments.append(
                dict(
                    id=sid,
                    linkage_id=lid,
                    kind=str(kind),
                    phi_gen=1.0 + j,
                    phi_gen2=4.0 if kind == SegmentKind.DOUBLE_LINE else None,
                    u=0.5 + i / 100,
                    v=-0.25,
                )
            )
            for level in rng.sample(range(3), rng.randint(1, 3)):
                key = rng.choice(GRID)
                arc, double = kind == SegmentKind.ARC, kind == SegmentKind.DOUBLE_LINE
                dwells.append(
                    dict(
                        segment_id=sid,
                        kind=kind.code,
                        level=level,
                        dwell_key=key,
                        dwell_angle=key / 2 if arc else None,
                        phi_start=0.5 + level,
                        x=0.25 * j - i / 50,
                        y=0.75 if arc else None,
                        direction=None if arc else 0.3 + i / 30,
                        radius=rng.choice([0.3, 1.0, 2.5, 7.0]) if arc else None,
                        transmission_min_cdeg=rng.choice([2000, 2864, 3500, 4500]),
                        longest_link_milli=length_ceil_milli(longest),
                        dwell_angle2=key / 3 if double else None,
                        phi_start2=3.5 if double else None,
                        x2=-0.5 if double else None,
                        direction2=1.1 + i / 40 if double else None,
                    )
                )
    linkages, segments, dwells = (TableColumns.of_rows(None, rows) for rows in (linkages, segments, dwells))
    return ShardResult(shard_index=0, linkages=linkages, segments=segments, dwells=dwells, skipped={}, seconds=0.5)


def _passes(d, min_transmission: float, max_length: float, min_radius_ratio: float) -> bool:
    """``db.queries._filters`` spelled out on one dwell row."""
    ok = d.transmission_min_cdeg >= transmission_floor_cdeg(min_transmission)
    if max_length < 1e12:
        ok &= d.longest_link_milli <= length_ceil_milli(max_length) and (d.radius is None or d.radius <= max_length)
    if min_radius_ratio > 0:
        ok &= d.radius is None or (
            d.radius >= min_radius_ratio and d.radius * 1000 >= min_radius_ratio * (d.longest_link_milli - 2)
        )
    return ok


def _walked(dwells, kinds, windows, levels, limits) -> list[tuple[int, int]]:
    """(segment id, level) of what the walks, one by one, select: per window, per kind and
    level, up to ``limit`` rows up from the target (key, id order) and down (key descending,
    id), then the window's ``limit`` closest (then id, level, walk order), each segment once."""
    out, seen = [], set()
    for w in windows:
        found = []
        for kind in kinds:
            for lv in [lv for lv, _ in levels] if w.level is None else [w.level]:
                rows = [d for d in dwells if d.kind == SegmentKind(kind).code and d.level == lv and _passes(d, *limits)]
                up = sorted(
                    (d for d in rows if w.target <= d.dwell_key <= w.high), key=lambda d: (d.dwell_key, d.segment_id)
                )
                down = sorted(
                    (d for d in rows if w.low <= d.dwell_key < w.target), key=lambda d: (-d.dwell_key, d.segment_id)
                )
                found += up[: w.limit] + down[: w.limit]
        found.sort(key=lambda d: (abs(d.dwell_key - w.target), d.segment_id, d.level))
        for d in found[: w.limit]:
            if d.segment_id not in seen:
                seen.add(d.segment_id)
                out.append((d.segment_id, d.level))
    return out


@pytest.fixture
def atlas(atlas_url):
    engine = open_atlas(atlas_url, create=True)
    with engine.begin() as conn:
        build_id = conn.execute(
            insert(Build).values(
                spec_json='{"name": "test", "tolerances": [0.0001, 0.001, 0.01]}',
                spec_digest="a" * 64,
                code_version="0",
                schema_version=SCHEMA_VERSION,
                status="building",
                n_shards=1,
                created_at="t",
                lock_token="t",
            )
        ).inserted_primary_key[0]
    write_shard(engine, build_id, _shard(random.Random(7)))
    assert finish_build(engine, build_id, "t")
    yield engine
    engine.dispose()


def test_the_walks_read_together_select_what_the_walks_one_by_one_do(atlas):
    rng = random.Random(3)
    levels = tolerance_levels(atlas)
    with atlas.connect() as conn:
        dwells = conn.execute(select(Dwell)).all()
    source = AtlasSource(atlas)
    checked = 0
    for trial in range(40):
        kinds = tuple(rng.sample(KINDS, rng.randint(1, 3)))
        windows = []
        for _ in range(rng.choice([0, 1, 4, 2 * WALKS_CHUNK])):  # the last: more walks than one statement holds
            target, width = rng.choice(GRID) + rng.choice([0.0, 1 / 32]), rng.choice([1 / 8, 1 / 2, 3.0])
            windows.append(
                DwellWindow(
                    rng.choice([None, 0, 1, 2, 5]),
                    target - width,
                    target + width * rng.random(),
                    target,
                    rng.choice([1, 3, 8, ALL_ROWS]),
                )
            )
        limits = (rng.choice([0.0, 0.5, 0.7]), rng.choice([1e300, 1e12, 4.0, 7.0]), rng.choice([0.0, 0.1, 0.25]))
        want = _walked(dwells, kinds, windows, levels, limits)
        named = dict(zip(("min_transmission", "max_length", "min_radius_ratio"), limits))
        got = select_segments(atlas, kinds, windows, **named)
        assert [(r.segment_id, r.level) for r in got] == want, trial
        assert got == [segment_row(atlas, sid, lv) for sid, lv in want]  # every field, as read one by one
        assert source.select_segments(kinds, windows, **named) == got  # the source's cached levels
        checked += len(got)
    assert checked > 500
