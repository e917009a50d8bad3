"""The query's reads of the atlas (``db.queries``): the dwell table's conservative integer
filters never hold back a linkage that meets a limit, a stored line is the fitted line, and the
rows read back are the rows written — on SQLite and PostgreSQL (``atlas_url``)."""

from __future__ import annotations

import cmath
import math

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from shards import shard_rows, with_rows
from sqlalchemy import event, insert, inspect

from db import SCHEMA_VERSION, Build, open_atlas
from db.engine import AtlasError
from db.queries import AtlasSource, scan_segments, segment_row, select_segments
from db.rows import length_ceil_milli, line_offset, line_point, line_points, transmission_floor_cdeg
from db.writes import finish_build, write_shard
from synth.query.contract import DwellWindow

angles = st.floats(0.0, math.pi / 2, allow_nan=False)
lengths = st.floats(1e-3, 1e3, allow_nan=False)


@given(angles, angles)
@example(math.radians(30.0), math.radians(30.0))
@example(math.nextafter(math.radians(30.0), 1.0), math.radians(30.0))
def test_the_transmission_floor_keeps_every_linkage_that_meets_the_limit(angle, limit):
    if angle >= limit:
        assert transmission_floor_cdeg(angle) >= transmission_floor_cdeg(limit)
    # and it lets through at most 0.01° more
    assert math.degrees(angle) * 100 - 1 < transmission_floor_cdeg(angle) <= math.degrees(angle) * 100


@given(lengths, lengths)
@example(3.0, 3.0)
@example(2.9999999999999996, 3.0)
@example(0.1 + 0.2, 0.30000000000000004)
def test_the_length_ceiling_keeps_every_linkage_that_meets_the_limit(length, limit):
    if length <= limit:
        assert length_ceil_milli(length) <= length_ceil_milli(limit)
    assert (length_ceil_milli(length) - 2) / 1000 < length <= length_ceil_milli(length) / 1000 + 1e-12 * length


@given(st.complex_numbers(max_magnitude=1e3, allow_nan=False, allow_infinity=False), st.floats(-math.pi, math.pi))
def test_a_stored_line_is_the_fitted_line(point, direction):
    """The foot rebuilt from (offset, direction) lies on the line through ``point``: the
    across-line coordinate of their difference vanishes (to rounding of the largest term)."""
    foot = line_point(line_offset(point, direction), direction)
    across = ((point - foot) * cmath.exp(-1j * direction)).imag
    assert abs(across) <= 1e-12 * max(1.0, abs(point))
    assert abs(foot) <= abs(point) * (1 + 1e-12) + 1e-12  # the foot is the nearest point to A0


def _atlas(target: str, shard):
    engine = open_atlas(target, create=True)
    with engine.begin() as conn:
        build_id = conn.execute(
            insert(Build).values(
                spec_json='{"name": "test", "tolerances": [0.001]}',
                spec_digest="a" * 64,
                code_version="0",
                schema_version=SCHEMA_VERSION,
                status="building",
                n_shards=1,
                created_at="t",
                lock_token="t",
            )
        ).inserted_primary_key[0]
    write_shard(engine, build_id, shard)
    assert finish_build(engine, build_id, "t")
    return engine


def _boundary_shard(transmission: float, longest: float, radius: float):
    """One linkage whose smallest transmission angle and longest link, and one arc whose radius,
    are the given values, with the integer copies computed as the build computes them."""
    rows = shard_rows(0, radius=radius)
    link = {
        **rows.linkages.rows()[0],
        "transmission_min": transmission,
        "b": longest,
        "c": longest / 2,
        "d": longest / 2,
    }
    dwell = {
        **rows.dwells.rows()[0],
        "transmission_min_cdeg": transmission_floor_cdeg(transmission),
        "longest_link_milli": length_ceil_milli(longest),
    }
    return with_rows(rows, linkages=[link], dwells=[dwell])


def test_a_linkage_exactly_at_every_limit_is_walked(atlas_url):
    """Transmission angle = the limit, longest link = the link ratio, rod = longest / ratio: it
    meets every limit, so every walk finds it; 0.02° less transmission and it is left out."""
    ratio = 7.3
    longest = 3.1234567
    engine = _atlas(atlas_url, _boundary_shard(math.radians(33.333333), longest, longest / ratio * (1 + 1e-15)))
    limits = dict(min_transmission=math.radians(33.333333), max_length=ratio, min_radius_ratio=1 / ratio)
    window = [DwellWindow(0, 0.0, 7.0, 0.5, 10)]
    found = select_segments(engine, ("arc",), window, **limits)
    assert [r.segment_id for r in found] == [shard_rows(0).segments.rows()[0]["id"]]
    assert [r.segment_id for rows in scan_segments(engine, "arc", 0, **limits) for r in rows] == [
        shard_rows(0).segments.rows()[0]["id"]
    ]
    assert AtlasSource(engine).count_segments("arc", 0, **limits) == 1
    stricter = {**limits, "min_transmission": math.radians(33.333333 + 0.02)}
    assert select_segments(engine, ("arc",), window, **stricter) == []
    engine.dispose()


def test_the_complete_walk_pages_through_ties_once_each_and_seeks_its_key(atlas_url):
    """Segments sharing dwell keys, read 3 rows a page: every row once, in (key, id) order, so
    a page starts where the last ended; on SQLite the page's plan seeks the b-tree on the key
    (an OR of the keyset's two conditions alone is read from the start of the level on every
    page, so the walk was quadratic in its pages)."""
    rows = shard_rows(0)
    segment, dwell = rows.segments.rows()[0], rows.dwells.rows()[0]
    keys = [0.5, 0.25, 0.5, 0.75, 0.5, 0.25, 1.0, 0.5]
    sids = [segment["id"] + k for k in range(len(keys))]
    engine = _atlas(
        atlas_url,
        with_rows(
            rows,
            segments=[{**segment, "id": sid} for sid in sids],
            dwells=[{**dwell, "segment_id": sid, "dwell_key": key} for sid, key in zip(sids, keys)],
        ),
    )
    pages = [[r.segment_id for r in batch] for batch in scan_segments(engine, "arc", 0, batch=3)]
    assert [len(p) for p in pages] == [3, 3, 2]
    assert sum(pages, []) == [sid for _, sid in sorted(zip(keys, sids))]
    if engine.dialect.name == "sqlite":
        plans: list[str] = []

        @event.listens_for(engine, "before_cursor_execute")
        def plan(conn, cursor, statement, parameters, context, executemany):
            if statement.lstrip().startswith("SELECT dwell.segment_id"):
                plans.extend(r[-1] for r in cursor.execute("EXPLAIN QUERY PLAN " + statement, parameters).fetchall())

        list(scan_segments(engine, "arc", 0, batch=3))
        dwell = [p for p in plans if p.startswith(("SEARCH dwell", "SCAN dwell"))]
        assert dwell and all(p.startswith("SEARCH dwell") and "dwell_key>?" in p for p in dwell), dwell
    engine.dispose()


def test_rows_read_back_as_written(atlas_url):
    """An arc and a double line: the query's rows hold the stored interval, geometry and the
    level's tolerance (from the sweep spec), the line as a point on it and its direction."""
    rows = shard_rows(0)
    segment, dwell = rows.segments.rows()[0], rows.dwells.rows()[0]
    sid = segment["id"]
    point, direction = 0.4 - 1.3j, 0.7
    offset = line_offset(point, direction)
    double = {**segment, "id": sid + 1, "kind": "double_line", "phi_gen2": 4.0}
    line_row = {
        **dwell,
        "segment_id": sid + 1,
        "kind": 2,
        "x": offset,
        "y": None,
        "direction": direction,
        "radius": None,
        "dwell_angle2": 0.25,
        "phi_start2": 3.5,
        "x2": -offset,
        "direction2": direction + 1,
    }
    engine = _atlas(atlas_url, with_rows(rows, segments=[segment, double], dwells=[dwell, line_row]))
    arc = segment_row(engine, sid, 0)
    assert arc.kind == "arc" and arc.tolerance == 0.001 and arc.parts == ((0.75, 1.25, 0.5, 0.25, None, 2.0),)
    dbl = segment_row(engine, sid + 1, 0)
    assert dbl.kind == "double_line" and len(dbl.parts) == 2
    (s1, e1, x1, y1, d1, r1), (s2, e2, x2, y2, d2, r2) = dbl.parts
    assert (s1, e1, d1, r1) == (0.75, 1.25, direction, None) and (s2, e2, d2, r2) == (3.5, 3.75, direction + 1, None)
    assert abs(((complex(x1, y1) - point) * cmath.exp(-1j * direction)).imag) < 1e-15
    assert abs(line_offset(complex(x2, y2), direction + 1) + offset) < 1e-15
    assert segment_row(engine, sid, 1).parts == ()  # no row at that level
    assert segment_row(engine, sid + 7, 0) is None
    engine.dispose()


def test_scanned_batches_spell_out_the_rows_read_one_by_one(atlas_url):
    """The complete search's batches (columns, one joined statement) hold every value that
    :func:`segment_row` reads for the same segment and level, bit for bit: an arc, a line and a
    double line."""
    rows = shard_rows(0)
    segment, dwell = rows.segments.rows()[0], rows.dwells.rows()[0]
    sid = segment["id"]
    direction = 0.7
    offset = line_offset(0.4 - 1.3j, direction)
    line = {**segment, "id": sid + 1, "kind": "line"}
    double = {**segment, "id": sid + 2, "kind": "double_line", "phi_gen2": 4.0, "u": -0.3, "v": 1e-17}
    line_row = {
        **dwell,
        "segment_id": sid + 1,
        "kind": 0,
        "dwell_key": 0.5,
        "dwell_angle": None,
        "x": offset,
        "y": None,
        "direction": direction,
        "radius": None,
    }
    double_row = {
        **line_row,
        "segment_id": sid + 2,
        "kind": 2,
        "dwell_angle2": 0.25,
        "phi_start2": 3.5,
        "x2": -offset,
        "direction2": -2.9,
    }
    engine = _atlas(atlas_url, with_rows(rows, segments=[segment, line, double], dwells=[dwell, line_row, double_row]))
    for kind, want in (("arc", sid), ("line", sid + 1), ("double_line", sid + 2)):
        (batch,) = scan_segments(engine, kind, 0)
        assert len(batch) == 1 and batch.kind == kind
        one = segment_row(engine, want, 0)
        assert list(batch) == [one] and batch[0].parts and batch[-1] == one
        assert [x.hex() for p in batch[0].parts for x in p if x is not None] == [
            x.hex() for p in one.parts for x in p if x is not None
        ]
    engine.dispose()


def test_a_read_names_a_dwell_row_without_its_segment(atlas_url):
    """Only a damaged atlas has one: one line naming the segment, not a row with holes."""
    engine = _atlas(atlas_url, shard_rows(0))
    sid = shard_rows(0).segments.rows()[0]["id"]
    with engine.begin() as conn:
        if engine.dialect.name == "sqlite":
            conn.exec_driver_sql("PRAGMA foreign_keys=OFF")  # the pooled connection's; restored below
        else:  # the tests' role owns the tables, but is no superuser to switch the key checks off
            for fk in inspect(conn).get_foreign_keys("dwell"):
                conn.exec_driver_sql(f'ALTER TABLE dwell DROP CONSTRAINT "{fk["name"]}"')
        conn.exec_driver_sql(f"DELETE FROM segment WHERE id = {sid}")
    if engine.dialect.name == "sqlite":
        with engine.begin() as conn:
            conn.exec_driver_sql("PRAGMA foreign_keys=ON")
    with pytest.raises(AtlasError, match=f"is damaged: dwell rows name segment {sid}, which does not exist"):
        list(scan_segments(engine, "arc", 0))
    with pytest.raises(AtlasError, match=f"is damaged: dwell rows name segment {sid}, which does not exist"):
        select_segments(engine, ("arc",), [DwellWindow(0, 0.0, 7.0, 0.5, 10)])  # the sample's read too
    engine.dispose()


@given(st.lists(st.tuples(st.floats(-1e3, 1e3), st.floats(-10.0, 10.0)), min_size=1, max_size=20))
@example([(0.0, 0.0), (-0.0, math.pi), (1.5, -0.0)])
def test_line_points_are_each_line_point(lines):
    """A line's foot is the same float alone or in an array (the scan reads arrays, a report one row)."""
    offset, direction = (np.array(x, float) for x in zip(*lines))
    feet = line_points(offset, direction)
    for foot, o, d in zip(feet.tolist(), offset.tolist(), direction.tolist()):
        one = line_point(o, d)
        assert (foot.real.hex(), foot.imag.hex()) == (one.real.hex(), one.imag.hex())
