"""Content digest: canonical text, what it ignores, what it does not."""

from __future__ import annotations

import hashlib
from dataclasses import replace

import pytest
from shards import shard_rows
from sqlalchemy import insert, update

from db import Build, Dwell, Linkage, Segment, open_atlas
from db.digest import content_digest, format_value
from db.writes import write_shard


def make(tmp_path, name, shards, *, spec_json='{"name": "demo"}', extra_builds=0):
    """An atlas holding ``shards``; ``extra_builds`` empty build rows first shift the build id."""
    engine = open_atlas(str(tmp_path / name), create=True)
    with engine.begin() as conn:
        for k in range(extra_builds):
            conn.execute(insert(Build).values(spec_json="{}", spec_digest=str(k) * 64, code_version="0", schema_version=1,
                                              status="complete", n_shards=1, created_at="t"))
        build_id = conn.execute(insert(Build).values(spec_json=spec_json, spec_digest="a" * 64, code_version="0",
                                                     schema_version=1, status="building", n_shards=len(shards),
                                                     created_at="t")).inserted_primary_key[0]
    for rows in shards:
        write_shard(engine, build_id, rows)
    return engine


def test_canonical_text_of_a_known_atlas(tmp_path):
    rows = shard_rows(0)
    engine = make(tmp_path, "a.sqlite", [rows])
    lk, sg, dw = rows.linkages[0], rows.segments[0], rows.dwells[0]
    # written out by hand from the rules in db/digest.py
    text = (
        "#linkage\tid\tshard_index\tsweep_index\tb\tc\td\tbranch\tgrashof\ttransmission_min\ttransmission_max\n"
        "1\t0\t0\t3\t2.5\t3\t1\t1\t0.5\t1.5\n"
        "#segment\tid\tlinkage_id\tkind\tphi_gen\tphi_gen2\tray\tu\tv\tpx\tpy\tdirection\tp2x\tp2y\tdirection2\tix\tiy"
        "\tcx\tcy\tradius\ttransmission_min\ttransmission_max\n"
        f"{sg['id']}\t1\t\"arc\"\t1\t~\t0.3\t1.2\t0.8\t~\t~\t~\t~\t~\t~\t~\t~\t0.5\t0.25\t2\t0.6\t1.4\n"
        "#dwell\tid\tsegment_id\tkind\tlevel\ttolerance\tpart\tphi_start\tphi_end\tdwell_angle\tmax_deviation\tx\ty"
        "\tdirection\tradius\n"
        f"{dw['id']}\t{sg['id']}\t\"arc\"\t0\t0.001\t0\t0.75\t1.25\t0.5\t0.0009\t0.5\t0.25\t~\t2\n"
    )
    assert lk["id"] == 1
    assert content_digest(engine) == hashlib.sha256(text.encode()).hexdigest()
    engine.dispose()


def test_order_build_id_and_volatile_columns_do_not_matter(tmp_path):
    shards = [shard_rows(i) for i in range(4)]
    one = make(tmp_path, "one.sqlite", shards)
    two = make(tmp_path, "two.sqlite", [replace(s, seconds=9.0, skipped={}) for s in reversed(shards)],
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
    (Segment, "px", 0.0, False),                 # NULL is not 0
    (Dwell, "level", 1, False),
    (Segment, "kind", "line", False),
])
def test_digest_sees_content_changes_and_ignores_noise(tmp_path, table, column, value, same):
    engine = make(tmp_path, "a.sqlite", [shard_rows(0), shard_rows(1)])
    before = content_digest(engine)
    with engine.begin() as conn:
        conn.execute(update(table).where(table.id == conn.execute(table.__table__.select()).first().id).values({column: value}))
    assert (content_digest(engine) == before) is same
    engine.dispose()


def test_format_value_rules():
    b = Linkage.__table__.c.b
    assert format_value(b, -0.0) == format_value(b, 0.0) == "0"
    assert format_value(b, 1 / 3) == "0.333333333333"
    assert format_value(b, -2.5e-300) == "-2.5e-300"
    assert format_value(b, None) == "~"
    assert format_value(Linkage.__table__.c.id, 2**40) == str(2**40)
    assert format_value(Segment.__table__.c.kind, "arc") == '"arc"'
