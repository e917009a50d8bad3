"""The atlas's rows (``db.rows.segment_columns``): worked out for a whole shard at once, as
columns, they are the rows spelled out one at a time from their definitions — the same dicts,
keys in the same order, the same Python floats and ints to the last bit — on a real shard of
every kind; and columns made of any rows spell those rows out again (``TableColumns``)."""

from __future__ import annotations

import math
import struct
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

import atlas.shard
from atlas.sweep import PRESETS
from db.rows import (
    SEGMENTS_PER_LINKAGE,
    TableColumns,
    length_ceil_milli,
    line_offset,
    linkage_columns,
    segment_columns,
    transmission_floor_cdeg,
)
from synth.kinds import SEGMENT_KINDS, SegmentKind
from synth.linkage import FourBar
from synth.segment_search.dwell_key import arc_dwell_key
from synth.segment_search.segments import SegmentSearch, find_segments


@pytest.fixture(scope="module")
def shard():
    """(found segments, linkage rows, the shard's result) of a small demo shard, as
    ``atlas.shard.compute_shard`` passes them to :func:`segment_columns` (the linkages as rows)."""
    seen = {}

    def capture(found, links):
        seen["found"], seen["links"] = found, links
        return segment_columns(found, links)

    mp = pytest.MonkeyPatch()
    mp.setattr(atlas.shard, "segment_columns", capture)
    try:
        result = atlas.shard.compute_shard(PRESETS["demo"].replace(shard_size=16), 0)
    finally:
        mp.undo()
    return seen["found"], seen["links"].rows(), result


def _stretch(found, i, level, part, *, arc):
    """A stretch's dwell columns, one value at a time from the definitions."""
    p = found.fit_point[i, level, part]
    start, end = float(found.phi_start[i, level, part]), float(found.phi_end[i, level, part])
    if arc:
        key = float(arc_dwell_key(end - start, found.excursion[i, level], found.tolerances[level]))
        return {
            "dwell_key": key,
            "dwell_angle": end - start,
            "phi_start": start,
            "x": float(p.real),
            "y": float(p.imag),
            "direction": None,
            "radius": float(found.fit_radius[i, level, part]),
        }
    direction = float(np.angle(found.fit_direction[i, level, part]))
    return {
        "dwell_key": end - start,
        "dwell_angle": None,
        "phi_start": start,
        "x": line_offset(complex(p), direction),
        "y": None,
        "direction": direction,
        "radius": None,
    }


def _reference(found, linkages):
    """The rows as the module docstrings define them, a segment and a level at a time."""
    segments, dwells = [], []
    ordinal = {}
    for i in range(len(found)):
        kind = SEGMENT_KINDS[int(found.kind[i])]
        link = linkages[int(found.linkage[i])]
        ordinal[link["id"]] = n = ordinal.get(link["id"], -1) + 1
        sid = link["id"] * SEGMENTS_PER_LINKAGE + n
        double = kind is SegmentKind.DOUBLE_LINE
        segments.append(
            {
                "id": sid,
                "linkage_id": link["id"],
                "kind": kind.value,
                "phi_gen": float(found.phi_gen[i]),
                "phi_gen2": float(found.phi_gen2[i]) if double else None,
                "u": float(found.uv[i].real),
                "v": float(found.uv[i].imag),
            }
        )
        copies = {
            "transmission_min_cdeg": transmission_floor_cdeg(link["transmission_min"]),
            "longest_link_milli": length_ceil_milli(max(link["b"], link["c"], link["d"])),
        }
        for level in range(len(found.tolerances)):
            if not found.has_dwell[i, level, 0] or (double and not found.has_dwell[i, level, 1]):
                continue
            row = {
                "kind": kind.code,
                "level": level,
                "segment_id": sid,
                **copies,
                **_stretch(found, i, level, 0, arc=kind is SegmentKind.ARC),
            }
            second = (
                _stretch(found, i, level, 1, arc=False)
                if double
                else dict.fromkeys(("dwell_key", "phi_start", "x", "direction"))
            )
            row.update(
                dwell_angle2=second["dwell_key"],
                phi_start2=second["phi_start"],
                x2=second["x"],
                direction2=second["direction"],
            )
            dwells.append(row)
    return segments, dwells


def _same(rows, expected):
    assert len(rows) == len(expected)
    for row, want in zip(rows, expected):
        assert list(row) == list(want)  # keys, in order
        assert row == want
        # bit for bit, and plain Python: a float stays a float (no numpy scalar), an int an int
        assert [type(v) for v in row.values()] == [type(v) for v in want.values()]
        assert all(
            math.copysign(1, v) == math.copysign(1, w) for v, w in zip(row.values(), want.values()) if type(v) is float
        )


def test_segment_rows_are_the_rows_spelled_out_one_at_a_time(shard):
    found, links, result = shard
    segments, dwells = _reference(found, links)
    assert {d["kind"] for d in dwells} == {k.code for k in SegmentKind}  # every kind
    assert any(d["level"] > 0 for d in dwells)
    _same(result.segments.rows(), segments)
    _same(result.dwells.rows(), dwells)
    assert all(
        type(v) in (int, float, str, type(None))
        for row in result.dwells.rows() + result.segments.rows()
        for v in row.values()
    )


def test_a_double_line_needs_both_stretches_at_a_level(shard):
    found, links, _ = shard
    double = np.flatnonzero(found.kind == SegmentKind.DOUBLE_LINE.code)
    assert double.size
    has = found.has_dwell.copy()
    has[double, :, 1] = False  # the second stretch nowhere: no dwell row for a double line
    lone = replace(found, has_dwell=has)
    segments, dwells = (t.rows() for t in segment_columns(lone, TableColumns.of_rows(None, links)))
    assert len(segments) == len(found)
    assert not any(d["kind"] == SegmentKind.DOUBLE_LINE.code for d in dwells)
    _same(dwells, _reference(lone, links)[1])


def test_no_segments_no_rows():
    found = find_segments(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, int), SegmentSearch())
    links = linkage_columns(
        0,
        np.zeros(0),
        FourBar(b=np.zeros(0), c=np.zeros(0), d=np.zeros(0), branch=np.zeros(0, int)),
        np.zeros(0, int),
        np.zeros((0, 1)),
    )
    assert [t.rows() for t in segment_columns(found, links)] == [[], []]


_COLUMN = st.sampled_from(["float", "int", "str"])


@st.composite
def _table(draw):
    """Rows as dicts: a few columns, each of one type (floats with NaN and ±inf, 64-bit ints,
    short texts), any of them NULL (None) anywhere."""
    kinds = draw(st.lists(_COLUMN, min_size=1, max_size=5))
    value = {
        "float": st.floats(allow_nan=True, allow_infinity=True),
        "int": st.integers(-(2**63), 2**63 - 1),
        "str": st.text(max_size=4),
    }
    n = draw(st.integers(1, 6))
    columns = [draw(st.lists(st.none() | value[k], min_size=n, max_size=n)) for k in kinds]
    return [{f"c{j}": col[i] for j, col in enumerate(columns)} for i in range(n)], kinds


@given(_table())
@example(([{"c0": None, "c1": -0.0}, {"c0": 3, "c1": float("nan")}], ["int", "float"]))
@example(([{"c0": "a\x00"}, {"c0": None}], ["str"]))
def test_columns_spell_out_the_rows_they_were_made_of(table):
    """``TableColumns.of_rows`` then ``rows`` gives the same dicts back, values of the same
    type and bits (−0.0, NaN), None where NULL; ``first_nonfinite`` names the first NaN or
    ±inf row by row, as a scan of the dicts does."""
    rows, kinds = table
    cols = TableColumns.of_rows(None, rows)
    assert len(cols) == len(rows)
    back = cols.rows()
    for row, got in zip(rows, back):
        assert list(got) == list(row)
        for k, v in row.items():
            w = got[k]
            assert type(w) is type(v)
            if isinstance(v, float):
                assert struct.pack("<d", w) == struct.pack("<d", v)
            else:
                assert w == v
    first = next(
        (
            (i, k, v)
            for i, row in enumerate(rows)
            for k, v in row.items()
            if isinstance(v, float) and not math.isfinite(v)
        ),
        None,
    )
    found = cols.first_nonfinite()
    assert (found is None) == (first is None)
    if first is not None:
        assert found[:2] == first[:2] and struct.pack("<d", found[2]) == struct.pack("<d", first[2])
