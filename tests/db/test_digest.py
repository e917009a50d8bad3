"""Content digest: its records written out by hand from the rules (floats rounded in exact
arithmetic), what it ignores, what it does not; the same on SQLite and PostgreSQL, for
hand-made shards and for real builds."""

from __future__ import annotations

import hashlib
import math
import struct
import sys
from dataclasses import replace
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from shards import shard_rows
from sqlalchemy import Float, String, insert, select, update

from atlas.build import build_atlas
from atlas.sweep import PRESETS
from db import SCHEMA_VERSION, Build, Dwell, Linkage, Segment, Shard, open_atlas
from db.digest import DIGEST_EXCLUDED, content_digest, rounded_bits, shard_digest, shard_digests, stored_digest
from db.rows import TableColumns
from db.summary import atlas_summary
from db.writes import finish_build, write_shard
from synth.kinds import SegmentKind


def make(target, shards, *, spec_json='{"name": "demo"}', extra_builds=0):
    """An atlas at ``target`` holding ``shards``, its build complete; ``extra_builds`` empty
    build rows first shift the build id."""
    engine = open_atlas(target, create=True)
    with engine.begin() as conn:
        for k in range(extra_builds):
            conn.execute(
                insert(Build).values(
                    spec_json="{}",
                    spec_digest=str(k) * 64,
                    code_version="0",
                    schema_version=SCHEMA_VERSION,
                    status="complete",
                    n_shards=1,
                    created_at="t",
                )
            )
        build_id = conn.execute(
            insert(Build).values(
                spec_json=spec_json,
                spec_digest="a" * 64,
                code_version="0",
                schema_version=SCHEMA_VERSION,
                status="building",
                n_shards=len(shards),
                created_at="t",
                lock_token="t",
            )
        ).inserted_primary_key[0]
    for rows in shards:
        write_shard(engine, build_id, rows)
    assert finish_build(engine, build_id, "t")  # the dwell rows into their table
    return engine


def _rounded(x: float) -> float:
    """``x`` rounded to 40 significant bits, half away from zero, in exact arithmetic (a normal
    float or 0; −0.0 gives +0.0)."""
    if x == 0:
        return 0.0
    m, e = math.frexp(abs(x))  # |x| = m·2^e, m in [0.5, 1)
    n = math.floor(Fraction(m) * 2**40 + Fraction(1, 2))  # 40 bits: n in [2^39, 2^40]
    return math.copysign(math.ldexp(n, e - 40), x)


def _record(model, row) -> bytes:
    """A row's record written out from the module docstring's rules, a value at a time."""
    out = b""
    for c in model.__table__.columns:
        if c.name in DIGEST_EXCLUDED[model.__tablename__]:
            continue
        v = row[c.name]
        out += b"\x01" if v is None else b"\x00"
        if isinstance(c.type, String):
            out += (b"" if v is None else str(v).encode()).ljust(c.type.length, b"\x00")
        elif isinstance(c.type, Float):
            out += struct.pack("<d", 0.0 if v is None else _rounded(v))
        else:
            out += struct.pack("<q", 0 if v is None else v)
    return out


def _by_hand(model, rows) -> bytes:
    """The header and the records of ``rows`` (dicts), in primary-key order."""
    cols = [c.name for c in model.__table__.columns if c.name not in DIGEST_EXCLUDED[model.__tablename__]]
    key = [c.name for c in model.__table__.primary_key.columns]
    head = ("#" + model.__tablename__ + "\t" + "\t".join(cols) + "\n").encode()
    return head + b"".join(_record(model, r) for r in sorted(rows, key=lambda r: [r[n] for n in key]))


def _digest_by_hand(linkages, segments, dwells) -> str:
    return hashlib.sha256(
        _by_hand(Linkage, linkages) + _by_hand(Segment, segments) + _by_hand(Dwell, dwells)
    ).hexdigest()


def test_records_of_a_known_atlas(atlas_url):
    rows = shard_rows(0)
    engine = make(atlas_url, [rows])
    lk, sg, dw = rows.linkages.rows(), rows.segments.rows(), rows.dwells.rows()
    assert lk[0]["id"] == 1 and sg[0]["kind"] == "arc" and dw[0]["direction"] is None
    shard = _digest_by_hand(lk, sg, dw)
    assert shard_digest(rows.linkages, rows.segments, rows.dwells) == shard == shard_digest(lk, sg, dw)
    assert content_digest(engine) == hashlib.sha256(f"0\t{shard}\n".encode()).hexdigest()
    with engine.connect() as conn:
        assert stored_digest(conn, 1) == content_digest(engine)  # from the shard row's digest
    engine.dispose()


def test_order_build_id_and_volatile_columns_do_not_matter(atlas_url, tmp_path):
    """``one`` on each backend, ``two`` always SQLite: also SQLite against PostgreSQL."""
    shards = [shard_rows(i) for i in range(4)]
    one = make(atlas_url, shards)
    two = make(
        str(tmp_path / "two.sqlite"),
        [replace(s, seconds=9.0, skipped={}) for s in reversed(shards)],
        spec_json='{"name": "renamed"}',
        extra_builds=2,
    )
    with two.connect() as conn:
        assert conn.execute(Build.__table__.select().where(Build.spec_digest == "a" * 64)).one().id == 3
    assert content_digest(one) == content_digest(two)
    assert content_digest(one, build_id=1) == content_digest(two, build_id=3) == content_digest(one)
    assert content_digest(one, build_id=99) != content_digest(one)  # a build that does not exist: empty
    one.dispose()
    two.dispose()


@pytest.mark.parametrize(
    "table, column, value, same",
    [
        (Linkage, "b", 3.0 * (1 + 1e-15), True),  # below 12 significant digits: noise
        (Linkage, "b", 3.0 * (1 + 1e-10), False),  # above: content
        (Segment, "u", 1.2 + 1e-9, False),
        (Segment, "phi_gen2", 0.0, False),  # NULL is not 0
        (Dwell, "level", 1, False),
        (Segment, "kind", "line", False),
    ],
)
def test_digest_sees_content_changes_and_ignores_noise(atlas_url, table, column, value, same):
    engine = make(atlas_url, [shard_rows(0), shard_rows(1)])
    before = content_digest(engine)
    with engine.begin() as conn:
        first = conn.execute(table.__table__.select()).first()  # by primary key: a dwell row has no id
        conn.execute(
            update(table)
            .where(*(c == getattr(first, c.name) for c in table.__table__.primary_key.columns))
            .values({column: value})
        )
    assert (content_digest(engine) == before) is same
    engine.dispose()


def test_a_build_stores_the_digest_its_rows_give(tmp_path):
    """The shard digests the workers computed (stored in the shard rows) are the digests of the
    rows as read back, shard by shard, and the build's digest combines them."""
    path = str(tmp_path / "small.sqlite")
    summary = build_atlas(path, PRESETS["demo"].replace(samples=96, shard_size=16), workers=1)
    assert summary.complete and summary.n_shards >= 3 and summary.dwells > 0
    engine = open_atlas(path, readonly=True)
    with engine.connect() as conn:
        kept = dict(conn.execute(select(Shard.shard_index, Shard.digest)).all())
        stored = conn.execute(select(Build.content_digest)).scalar_one()
    assert shard_digests(engine) == kept and len(kept) == summary.n_shards
    assert content_digest(engine) == stored == content_digest(engine, build_id=1)
    engine.dispose()


@given(st.floats(-1e300, 1e300).filter(lambda x: x == 0 or abs(x) >= sys.float_info.min))  # the schema's range
@example(1.0 + 2.0**-40)  # half an ulp of 40 bits: away from zero
@example(-(1.0 + 2.0**-40))
@example(2.0 - 2.0**-52)  # rounds up into the next binade
@example(-0.0)
@example(1e300)
def test_floats_are_rounded_to_40_bits_as_exact_arithmetic_rounds_them(x):
    assert rounded_bits(np.array([x])).tobytes() == struct.pack("<d", _rounded(x))


def test_rounding_edges():
    bits = lambda x: rounded_bits(np.array([x]))[0]  # noqa: E731
    assert bits(1.0 + 2.0**-40) == bits(1.0 + 2.0**-39) != bits(1.0)  # the half-way case: away from zero
    assert bits(1.0 + 2.0**-41) == bits(1.0)
    assert bits(2.0 - 2.0**-52) == bits(2.0)  # the carry moves to the next binade
    assert bits(-0.0) == bits(0.0) == 0
    assert bits(-3.0) != bits(3.0)


def test_shard_digest_is_the_records_written_by_hand():
    """``shard_digest`` from dicts and from columns is the records written out value by value:
    −0.0 as 0, NULL flagged, floats rounded to 40 bits, a kind (a ``StrEnum`` member too) as
    zero-padded UTF-8, rows in key order whatever their order here, NULLs in different columns
    row by row, and a NULL where the schema has none."""
    base = shard_rows(0)
    b_lk, b_sg, b_dw = base.linkages.rows()[0], base.segments.rows()[0], base.dwells.rows()[0]
    lk = dict(b_lk, b=-0.0, c=1 / 3, d=-2.5e-300, transmission_min=-1e-300, transmission_max=float(2**60))
    sg = [
        dict(b_sg, phi_gen=-0.0, u=-0.5, v=1e21),
        dict(b_sg, id=b_sg["id"] + 1, kind=SegmentKind.DOUBLE_LINE, phi_gen2=-0.0, v=-0.0),
    ]
    arc = dict(b_dw, x=-0.0, y=-1e-300, phi_start=0.0)
    line = dict(b_dw, kind=0, level=2, dwell_angle=None, x=-0.0, y=None, radius=None, direction=-0.0)
    double = dict(line, kind=2, segment_id=sg[1]["id"], dwell_angle2=1 / 3, phi_start2=-0.0, x2=-0.0, direction2=2.5)
    dw = [double, line, arc]  # not in key order
    want = _digest_by_hand([lk], sg, dw)
    assert shard_digest([lk], sg, dw) == want
    assert shard_digest(*(TableColumns.of_rows(None, rows) for rows in ([lk], sg, dw))) == want
    assert shard_digest([lk], sg, [arc, double, line]) == want
    # −0.0 and +0.0 are one value; a NULL is not 0
    assert shard_digest([dict(lk, b=0.0)], sg, dw) == want
    assert shard_digest([lk], sg, [double, dict(line, direction=0.0), arc]) == want
    assert shard_digest([lk], sg, [double, dict(line, y=0.0), arc]) != want
    # a NULL in a column the schema keeps NOT NULL is flagged too (a digest of what was given)
    odd = [dict(line, phi_start=None, transmission_min_cdeg=None)]
    assert shard_digest([lk], sg, odd) == _digest_by_hand([lk], sg, odd) != shard_digest([lk], sg, [line])
    assert shard_digest([], [], []) == _digest_by_hand([], [], [])
    with pytest.raises(ValueError, match="longer than its column"):
        shard_digest([lk], [dict(b_sg, kind="a kind too long")], [])


def _facts(target: str, *, recompute: bool = True) -> tuple[str | None, str | None, dict]:
    """(digest computed now — None without ``recompute`` —, digest stored by the build,
    ``info`` document without what differs between two builds: timestamps, compute time, ids,
    bytes on disk)."""
    engine = open_atlas(target, readonly=True)
    try:
        with engine.connect() as conn:
            stored = conn.execute(select(Build.content_digest)).scalar_one()
        doc = atlas_summary(engine).to_dict()
        for key in ("created_at", "finished_at", "compute_seconds", "id"):
            doc["build"].pop(key)
        # bytes on disk are the engine's own (pages, indexes), not content
        assert doc.pop("storage_bytes") > 0 and doc.pop("bytes_per_linkage") > 0
        return content_digest(engine) if recompute else None, stored, doc
    finally:
        engine.dispose()


@pytest.mark.postgres
def test_a_small_build_is_the_same_on_sqlite_and_postgresql(tmp_path, postgres_url):
    spec = PRESETS["demo"].replace(samples=64)
    path = str(tmp_path / "small.sqlite")
    for target in (path, postgres_url):
        summary = build_atlas(target, spec, workers=1)
        assert summary.complete and summary.linkages > 0 and sum(summary.segments.values()) > 0
    lite, pg = _facts(path), _facts(postgres_url)
    assert lite[0] == lite[1] and pg[0] == pg[1]  # the stored digest is that of the rows
    assert pg[0] == lite[0]
    assert pg[2] == lite[2]  # counts, histograms, skipped reasons, spec: the same atlas
    assert lite[2]["dwells"]["arc"] > 0


@pytest.mark.postgres
def test_the_demo_build_is_the_same_on_sqlite_and_postgresql(demo_atlases):
    # the stored digests (that they equal a fresh one is checked on the small build above)
    lite = _facts(demo_atlases["sqlite"], recompute=False)
    pg = _facts(demo_atlases["postgresql"], recompute=False)
    assert lite[2]["linkages"] > 1000 and lite[2]["build"]["spec"]["name"] == "demo"
    assert pg[1] == lite[1] and lite[1] == lite[2]["content_digest"]
    assert pg[2] == lite[2]
