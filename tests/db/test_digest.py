"""Content digest: canonical text, what it ignores, what it does not; the same on SQLite and
PostgreSQL, for hand-made shards and for real builds."""

from __future__ import annotations

import hashlib
from dataclasses import replace

import pytest
from shards import shard_rows
from sqlalchemy import insert, select, update

from atlas.build import build_atlas
from atlas.sweep import PRESETS
from db import SCHEMA_VERSION, Build, Dwell, Linkage, Segment, Shard, open_atlas
from db.digest import DIGEST_EXCLUDED, content_digest, format_value, shard_digest, shard_digests, stored_digest
from db.summary import atlas_summary
from db.writes import finish_build, write_shard
from synth.kinds import SegmentKind


def make(target, shards, *, spec_json='{"name": "demo"}', extra_builds=0):
    """An atlas at ``target`` holding ``shards``, its build complete; ``extra_builds`` empty
    build rows first shift the build id."""
    engine = open_atlas(target, create=True)
    with engine.begin() as conn:
        for k in range(extra_builds):
            conn.execute(insert(Build).values(spec_json="{}", spec_digest=str(k) * 64, code_version="0",
                                              schema_version=SCHEMA_VERSION, status="complete", n_shards=1,
                                              created_at="t"))
        build_id = conn.execute(insert(Build).values(spec_json=spec_json, spec_digest="a" * 64, code_version="0",
                                                     schema_version=SCHEMA_VERSION, status="building",
                                                     n_shards=len(shards), created_at="t",
                                                     lock_token="t")).inserted_primary_key[0]
    for rows in shards:
        write_shard(engine, build_id, rows)
    assert finish_build(engine, build_id, "t")  # the dwell rows into their table
    return engine


def test_canonical_text_of_a_known_atlas(atlas_url):
    rows = shard_rows(0)
    engine = make(atlas_url, [rows])
    lk, sg, dw = rows.linkages[0], rows.segments[0], rows.dwells[0]
    # written out by hand from the rules in db/digest.py
    text = (
        "#linkage\tid\tshard_index\tsweep_index\tb\tc\td\tbranch\tgrashof\ttransmission_min\ttransmission_max\n"
        "1\t0\t0\t3\t2.5\t3\t1\t1\t0.5\t1.5\n"
        "#segment\tid\tlinkage_id\tkind\tphi_gen\tphi_gen2\tu\tv\n"
        f"{sg['id']}\t1\t\"arc\"\t1\t~\t1.2\t0.8\n"
        "#dwell\tkind\tlevel\tdwell_key\tsegment_id\tdwell_angle\ttransmission_min_cdeg\tlongest_link_milli\tradius"
        "\tphi_start\tx\ty\tdirection\tdwell_angle2\tphi_start2\tx2\tdirection2\n"
        f"1\t0\t0.5\t{sg['id']}\t0.5\t2864\t3000\t2\t0.75\t0.5\t0.25\t~\t~\t~\t~\t~\n"
    )
    assert lk["id"] == 1
    shard = hashlib.sha256(text.encode()).hexdigest()
    assert shard_digest(rows.linkages, rows.segments, rows.dwells) == shard
    assert content_digest(engine) == hashlib.sha256(f"0\t{shard}\n".encode()).hexdigest()
    with engine.connect() as conn:
        assert stored_digest(conn, 1) == content_digest(engine)  # from the shard row's digest
    engine.dispose()


def test_order_build_id_and_volatile_columns_do_not_matter(atlas_url, tmp_path):
    """``one`` on each backend, ``two`` always SQLite: also SQLite against PostgreSQL."""
    shards = [shard_rows(i) for i in range(4)]
    one = make(atlas_url, shards)
    two = make(str(tmp_path / "two.sqlite"), [replace(s, seconds=9.0, skipped={}) for s in reversed(shards)],
               spec_json='{"name": "renamed"}', extra_builds=2)
    with two.connect() as conn:
        assert conn.execute(Build.__table__.select().where(Build.spec_digest == "a" * 64)).one().id == 3
    assert content_digest(one) == content_digest(two)
    assert content_digest(one, build_id=1) == content_digest(two, build_id=3) == content_digest(one)
    assert content_digest(one, build_id=99) != content_digest(one)  # a build that does not exist: empty
    one.dispose()
    two.dispose()


@pytest.mark.parametrize("table, column, value, same", [
    (Linkage, "b", 3.0 * (1 + 1e-15), True),     # below 12 significant digits: noise
    (Linkage, "b", 3.0 * (1 + 1e-10), False),    # above: content
    (Segment, "u", 1.2 + 1e-9, False),
    (Segment, "phi_gen2", 0.0, False),           # NULL is not 0
    (Dwell, "level", 1, False),
    (Segment, "kind", "line", False),
])
def test_digest_sees_content_changes_and_ignores_noise(atlas_url, table, column, value, same):
    engine = make(atlas_url, [shard_rows(0), shard_rows(1)])
    before = content_digest(engine)
    with engine.begin() as conn:
        first = conn.execute(table.__table__.select()).first()  # by primary key: a dwell row has no id
        conn.execute(update(table).where(*(c == getattr(first, c.name) for c in table.__table__.primary_key.columns))
                     .values({column: value}))
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


def test_format_value_rules():
    b = Linkage.__table__.c.b
    assert format_value(b, -0.0) == format_value(b, 0.0) == "0"
    assert format_value(b, 1 / 3) == "0.333333333333"
    assert format_value(b, -2.5e-300) == "-2.5e-300"
    assert format_value(b, None) == "~"
    assert format_value(Linkage.__table__.c.id, 2**40) == str(2**40)
    assert format_value(Segment.__table__.c.kind, "arc") == '"arc"'


def _text(model, rows) -> str:
    """The canonical text of ``rows`` (dicts) written out value by value with ``format_value``."""
    cols = [c for c in model.__table__.columns if c.name not in DIGEST_EXCLUDED[model.__tablename__]]
    key = [c.name for c in model.__table__.primary_key.columns]
    lines = ["#" + model.__tablename__ + "\t" + "\t".join(c.name for c in cols)]
    lines += ["\t".join(format_value(c, row[c.name]) for c in cols) for row in sorted(rows, key=lambda r: [r[n] for n in key])]
    return "\n".join(lines) + "\n"


def test_shard_digest_writes_what_format_value_writes():
    """``shard_digest`` writes a row at a time with one format string; its text is
    ``format_value``'s value by value: −0.0 (and only it) as 0, NULL as ~, 12 significant
    digits, a kind (a ``StrEnum`` member too) as JSON, rows in key order whatever their order
    here, NULLs in different columns row by row, and a NULL where the schema has none."""
    base = shard_rows(0)
    lk = dict(base.linkages[0], b=-0.0, c=1 / 3, d=-2.5e-300, transmission_min=-1e-300, transmission_max=float(2**60))
    sg = [dict(base.segments[0], phi_gen=-0.0, u=-0.5, v=1e21),
          dict(base.segments[0], id=base.segments[0]["id"] + 1, kind=SegmentKind.DOUBLE_LINE, phi_gen2=-0.0, v=-0.0)]
    arc = dict(base.dwells[0], x=-0.0, y=-1e-300, phi_start=0.0)
    line = dict(base.dwells[0], kind=0, level=2, dwell_angle=None, x=-0.0, y=None, radius=None, direction=-0.0)
    double = dict(line, kind=2, segment_id=sg[1]["id"], dwell_angle2=1 / 3, phi_start2=-0.0, x2=-0.0, direction2=2.5)
    dw = [double, line, arc]  # not in key order
    text = _text(Linkage, [lk]) + _text(Segment, sg) + _text(Dwell, dw)
    assert "1\t0\t0\t0\t0.333333333333\t-2.5e-300\t1\t1\t-1e-300\t1.15292150461e+18\n" in text
    assert f'{sg[1]["id"]}\t1\t"double_line"\t1\t0\t1.2\t0\n' in text
    fields = text.replace("\n", "\t").split("\t")
    assert "-0" not in fields and "-1e-300" in fields and "-0.5" in fields
    assert shard_digest([lk], sg, dw) == hashlib.sha256(text.encode()).hexdigest()
    # a NULL in a column the schema keeps NOT NULL is written ~ too (a digest of what was given)
    odd = [dict(line, phi_start=None, transmission_min_cdeg=None)]
    assert shard_digest([lk], sg, odd) == hashlib.sha256((text.split("#dwell")[0] + _text(Dwell, odd)).encode()).hexdigest()
    assert shard_digest([], [], []) == hashlib.sha256((_text(Linkage, []) + _text(Segment, []) + _text(Dwell, [])).encode()).hexdigest()


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
