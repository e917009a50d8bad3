"""Build writes: one transaction per shard, resume, one build per atlas, the builder lock —
on SQLite and PostgreSQL (``atlas_url``)."""

from __future__ import annotations

import json
import math
import os
import socket
import subprocess
import sys
import threading
import time

import pytest
from shards import shard_rows, with_rows
from sqlalchemy import delete, func, insert, inspect, select, text, update
from sqlalchemy.exc import IntegrityError

import db.writes
from db import SCHEMA_VERSION, AtlasError, Build, Dwell, Linkage, Segment, Shard, open_atlas
from db.engine import SQLITE_PAGE_SIZE
from db.packed import PackedShard, pack
from db.schema import dwell_staging
from db.writes import (
    STALE_SECONDS,
    BuildLock,
    LockLostError,
    ShardWriteError,
    code_version,
    finish_build,
    open_build,
    release_lock,
    write_shard,
)

SPEC_A = json.dumps({"name": "demo", "samples": 8})
SPEC_B = json.dumps({"name": "other", "samples": 9})
DIGEST_A = "a" * 64
DIGEST_B = "b" * 64


def plain(rows):
    return rows


def packed(rows):
    """``rows`` as a worker hands them over (:func:`db.packed.pack`)."""
    return pack(rows, None)


#: The two forms a shard reaches the writer in.
FORMS = [pytest.param(plain, id="plain"), pytest.param(packed, id="packed")]


def count(engine, model) -> int:
    with engine.connect() as conn:
        return conn.execute(select(func.count()).select_from(model)).scalar_one()


@pytest.fixture
def engine(atlas_url):
    e = open_atlas(atlas_url, create=True)
    yield e
    e.dispose()


def start(engine, *, digest=DIGEST_A, spec=SPEC_A, n_shards=3, lock=None, replace=False, target="a.sqlite"):
    lock = lock or BuildLock.mine()
    return open_build(
        engine, target=target, spec_json=spec, spec_digest=digest, n_shards=n_shards, lock=lock, replace=replace
    ), lock


def test_new_build_row_and_shard_rows(engine):
    h, lock = start(engine)
    assert (h.done, h.resumed, h.complete, h.replaced) == (frozenset(), False, False, None)
    write_shard(engine, h.build_id, shard_rows(0), lock_token=lock.token)
    with engine.connect() as conn:
        b = conn.execute(select(Build)).one()
        shard = conn.execute(select(Shard)).one()
    assert (b.status, b.n_shards, b.spec_json, b.spec_digest) == ("building", 3, SPEC_A, DIGEST_A)
    assert b.code_version == code_version() != "" and b.schema_version == SCHEMA_VERSION
    assert (b.lock_token, b.lock_pid, b.lock_host) == (lock.token, os.getpid(), socket.gethostname())
    assert (shard.shard_index, shard.n_linkages, shard.n_segments, shard.seconds) == (0, 1, 1, 0.25)
    assert json.loads(shard.skipped_json) == {"pole at infinity": 0}
    # a shard's dwell rows wait in the staging table until the build completes
    assert [count(engine, m) for m in (Linkage, Segment, dwell_staging, Dwell)] == [1, 1, 1, 0]
    if engine.dialect.name == "sqlite":  # a new atlas's pages: 16 KiB (db.engine.SQLITE_PAGE_SIZE)
        with engine.connect() as conn:
            assert conn.exec_driver_sql("PRAGMA page_size").scalar() == SQLITE_PAGE_SIZE == 16384


@pytest.mark.parametrize(
    "bad",
    [
        dict(radius=float("nan")),  # a nullable column: SQLite would store NaN as NULL silently
        dict(radius=float("inf")),
        dict(dwell_angle=-0.1),  # CHECK dwell_key > 0 (and dwell_angle), caught by the database
    ],
)
@pytest.mark.parametrize("form", FORMS)
def test_a_bad_row_rolls_the_whole_shard_back(engine, bad, form):
    """Plain rows are checked by the writer, packed ones by the packing (a worker): the same
    error either way, and nothing of the shard is written."""
    h, lock = start(engine)
    write_shard(engine, h.build_id, form(shard_rows(0)), lock_token=lock.token)
    with pytest.raises(ShardWriteError, match="shard 1"):
        write_shard(engine, h.build_id, form(shard_rows(1, **bad)), lock_token=lock.token)
    # shard 0 intact, nothing at all of shard 1 (its linkage came first in the transaction)
    assert [count(engine, m) for m in (Linkage, Segment, dwell_staging, Shard)] == [1, 1, 1, 1]


def _dangling_segment_refused(engine) -> None:
    """A pooled connection has its foreign keys on: a segment of no linkage is refused."""
    row = {**shard_rows(0).segments.rows()[0], "id": 7, "linkage_id": -7}
    with pytest.raises(IntegrityError), engine.begin() as conn:
        conn.execute(insert(Segment), [row])


def _repeated(one):
    return with_rows(one, dwells=[one.dwells.rows()[0], one.dwells.rows()[0]])  # the same (segment, level) twice


def _foreign_segment(one):
    return with_rows(one, dwells=[{**one.dwells.rows()[0], "segment_id": shard_rows(0).segments.rows()[0]["id"]}])


def _foreign_linkage(one):
    return with_rows(one, segments=[{**one.segments.rows()[0], "linkage_id": shard_rows(0).linkages.rows()[0]["id"]}])


def _negative_angle(one):
    return with_rows(one, dwells=[{**one.dwells.rows()[0], "dwell_angle": -0.1}])


@pytest.mark.parametrize(
    "spoil, message",
    [
        (_repeated, r"shard 1: two dwell rows of segment \d+ at level 0; nothing of the shard was written"),
        (_foreign_segment, r"shard 1: a dwell row names segment \d+, which is not one of the shard's"),
        (_foreign_linkage, r"shard 1: a segment names linkage 1, which is not one of the shard's"),
        (_negative_angle, r"shard 1 of build \d+ rolled back: CHECK constraint failed|violates check constraint"),
    ],
)
@pytest.mark.parametrize("form", FORMS)
def test_a_shard_whose_rows_break_a_key_is_refused_whole(engine, form, spoil, message):
    """Rows that repeat a (segment, level) or name a segment or linkage of another shard are
    refused by the check that packs them (a packed shard is copied with SQLite's foreign key
    checks off, on that check's word), a row check by the database: nothing of the shard is
    written, and the connection goes back to the pool as it came (foreign keys on, a packed
    shard detached)."""
    h, lock = start(engine)
    write_shard(engine, h.build_id, form(shard_rows(0)), lock_token=lock.token)
    with pytest.raises(ShardWriteError, match=message):
        write_shard(engine, h.build_id, form(spoil(shard_rows(1))), lock_token=lock.token)
    assert count(engine, Shard) == 1 and count(engine, Linkage) == 1 and count(engine, dwell_staging) == 1
    write_shard(engine, h.build_id, form(shard_rows(2)), lock_token=lock.token)
    assert count(engine, Shard) == 2 and count(engine, Linkage) == 2
    _dangling_segment_refused(engine)


def test_resume_knows_done_shards_and_drops_orphans(engine):
    h, lock = start(engine)
    write_shard(engine, h.build_id, shard_rows(0), lock_token=lock.token)
    # an orphan: rows of shard 2 without a shard row (a writer that was not atomic)
    orphan = shard_rows(2)
    with engine.begin() as conn:
        conn.execute(insert(Linkage), [{**orphan.linkages.rows()[0], "build_id": h.build_id}])
        conn.execute(insert(Segment), orphan.segments.rows())
        conn.execute(insert(dwell_staging), orphan.dwells.rows())
        conn.execute(insert(Dwell), orphan.dwells.rows())  # in either table
    release_lock(engine, h.build_id, lock.token)
    h2, lock2 = start(engine)
    assert h2.build_id == h.build_id and h2.done == {0} and h2.resumed
    assert [count(engine, m) for m in (Linkage, Segment, dwell_staging, Dwell)] == [1, 1, 1, 0]
    for i in (1, 2):
        write_shard(engine, h2.build_id, shard_rows(i), lock_token=lock2.token)
    assert finish_build(engine, h2.build_id, lock2.token)
    # the staged rows moved into the dwell table, in its key order
    assert [count(engine, m) for m in (Linkage, Segment, dwell_staging, Dwell)] == [3, 3, 0, 3]
    with engine.connect() as conn:  # equal angles: in segment order
        assert conn.execute(select(Dwell.segment_id)).scalars().all() == [
            shard_rows(i).dwells.rows()[0]["segment_id"] for i in range(3)
        ]
    with engine.connect() as conn:
        b = conn.execute(select(Build)).one()
    assert b.status == "complete" and b.finished_at and b.lock_token is None
    h3, _ = start(engine)
    assert h3.complete and h3.done == {0, 1, 2}


def test_finish_is_refused_while_shards_are_missing(engine):
    h, lock = start(engine)
    write_shard(engine, h.build_id, shard_rows(0), lock_token=lock.token)
    assert finish_build(engine, h.build_id, lock.token) is False
    with engine.connect() as conn:
        assert conn.execute(select(Build.status)).scalar_one() == "building"


def test_different_sweep_refused_then_replaced(engine):
    h, lock = start(engine)
    write_shard(engine, h.build_id, shard_rows(0), lock_token=lock.token)
    release_lock(engine, h.build_id, lock.token)
    with pytest.raises(
        AtlasError, match=r"built with a different sweep \(preset demo, digest aaaaaaaa…\); use --replace"
    ):
        start(engine, digest=DIGEST_B, spec=SPEC_B)
    assert count(engine, Linkage) == 1  # nothing changed
    h2, _ = start(engine, digest=DIGEST_B, spec=SPEC_B, replace=True)
    assert h2.replaced and "preset demo" in h2.replaced and h2.done == frozenset()
    assert [count(engine, m) for m in (Linkage, Segment, dwell_staging, Dwell, Shard)] == [0, 0, 0, 0, 0]
    with engine.connect() as conn:
        assert conn.execute(select(Build.spec_digest)).scalars().all() == [DIGEST_B]


def test_resume_by_another_code_version_is_refused(engine):
    h, lock = start(engine)
    release_lock(engine, h.build_id, lock.token)
    with engine.begin() as conn:
        conn.execute(update(Build).values(code_version="0.0.1-old"))
    with pytest.raises(AtlasError, match="partly built by dwell-atlas 0.0.1-old.*--replace"):
        start(engine)


def set_lock(engine, *, pid, host, age):
    with engine.begin() as conn:
        conn.execute(
            update(Build).values(lock_token="x" * 32, lock_pid=pid, lock_host=host, lock_heartbeat=time.time() - age)
        )


def dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()  # reaped: the pid is free
    return p.pid


@pytest.mark.parametrize(
    "pid, host, age, alive",
    [
        ("me", "here", 0, True),  # a live process on this host
        ("me", "here", STALE_SECONDS * 2, True),  # slow but alive: the pid decides on this host
        ("dead", "here", 0, False),  # killed on this host: taken over at once
        (1, "elsewhere.example", 5, True),  # another host, fresh heartbeat
        (1, "elsewhere.example", STALE_SECONDS + 5, False),  # another host, stale heartbeat
    ],
)
def test_lock_liveness(engine, pid, host, age, alive):
    h, _ = start(engine)
    pid = os.getpid() if pid == "me" else dead_pid() if pid == "dead" else pid
    host = socket.gethostname() if host == "here" else host
    set_lock(engine, pid=pid, host=host, age=age)
    if alive:
        with pytest.raises(AtlasError, match=rf"being built by another process \(pid {pid} on {host}"):
            start(engine)
        with pytest.raises(AtlasError, match="being built by another process"):
            start(engine, digest=DIGEST_B, spec=SPEC_B, replace=True)  # --replace does not break a live lock
    else:
        h2, lock2 = start(engine)
        assert h2.build_id == h.build_id
        with engine.connect() as conn:
            assert conn.execute(select(Build.lock_token)).scalar_one() == lock2.token


def test_a_builder_that_lost_its_lock_writes_nothing(engine):
    h, lock = start(engine)
    set_lock(engine, pid=dead_pid(), host=socket.gethostname(), age=0)  # as if we had been seen as dead
    h2, lock2 = start(engine)
    with pytest.raises(LockLostError, match="taken over"):
        write_shard(engine, h.build_id, shard_rows(0), lock_token=lock.token)
    assert count(engine, Linkage) == 0 and count(engine, Shard) == 0
    write_shard(engine, h2.build_id, shard_rows(0), lock_token=lock2.token)
    assert count(engine, Shard) == 1


def test_a_writer_blocked_behind_a_takeover_loses_cleanly(engine):
    """The compare-and-swap under contention: while another builder's takeover is still
    uncommitted, our shard write waits for it, then finds its token gone and writes nothing
    (on PostgreSQL this relies on READ COMMITTED re-reading the row, see db/engine.py)."""
    h, lock = start(engine)
    holder = engine.connect()
    takeover = holder.begin()
    holder.execute(
        update(Build).values(lock_token="t" * 32, lock_pid=1, lock_host="elsewhere.example", lock_heartbeat=time.time())
    )
    outcome: list[BaseException | None] = []

    def write() -> None:
        try:
            write_shard(engine, h.build_id, shard_rows(0), lock_token=lock.token)
            outcome.append(None)
        except BaseException as exc:  # noqa: BLE001 - recorded for the assertion
            outcome.append(exc)

    writer = threading.Thread(target=write)
    writer.start()
    writer.join(0.5)
    assert writer.is_alive() and outcome == []  # blocked on the uncommitted takeover, not failed
    takeover.commit()
    holder.close()
    writer.join(60)
    assert len(outcome) == 1 and isinstance(outcome[0], LockLostError), outcome
    assert [count(engine, m) for m in (Linkage, Segment, dwell_staging, Dwell, Shard)] == [0, 0, 0, 0, 0]


AWKWARD = [1 / 3, 2.0**-1074, 1e-300, -1e300, math.pi * 1e17, math.nextafter(1.0, 2.0), -0.0]


@pytest.mark.parametrize("path", ["bulk", "insert", "packed"])
def test_floats_round_trip_bit_for_bit(engine, monkeypatch, path):
    """What is read back is exactly what was written (the digest rounds to 40 bits, the
    query and the report do not), through COPY on PostgreSQL, through INSERT, and packed by a
    worker (copied by INSERT … SELECT on SQLite, read back and loaded on PostgreSQL)."""
    if path == "insert":
        monkeypatch.setattr(db.writes, "_uses_copy", lambda conn: False)
    form = packed if path == "packed" else plain
    h, lock = start(engine)
    rows = shard_rows(0)
    values = dict(zip(("u", "v", "phi_gen", "phi_gen2"), AWKWARD[:4], strict=True))
    dwell = dict(zip(("x", "y", "radius"), AWKWARD[4:], strict=True))
    rows = with_rows(rows, segments=[rows.segments.rows()[0] | values], dwells=[rows.dwells.rows()[0] | dwell])
    write_shard(engine, h.build_id, form(rows), lock_token=lock.token)
    with engine.connect() as conn:
        got = [
            *conn.execute(select(*(getattr(Segment, k) for k in values))).one(),
            *conn.execute(select(*(dwell_staging.c[k] for k in dwell))).one(),
        ]
    for i in (1, 2):  # the move into the dwell table at the end keeps them too
        write_shard(engine, h.build_id, shard_rows(i), lock_token=lock.token)
    assert finish_build(engine, h.build_id, lock.token)
    with engine.connect() as conn:
        assert conn.execute(
            select(*(getattr(Dwell, k) for k in dwell)).where(Dwell.segment_id == rows.dwells.rows()[0]["segment_id"])
        ).one() == tuple(got[len(values) :])
    values |= dwell
    # x + 0.0 turns −0.0 into 0.0: SQLite does not keep the sign of zero (PostgreSQL does),
    # which is why the content digest takes both as 0
    assert [(v + 0.0).hex() for v in got] == [(v + 0.0).hex() for v in values.values()]


def _complete(engine, n_shards=2):
    h, lock = start(engine, n_shards=n_shards)
    for i in range(n_shards):
        write_shard(engine, h.build_id, shard_rows(i), lock_token=lock.token)
    assert finish_build(engine, h.build_id, lock.token)
    return h


def test_the_move_at_the_end_keeps_every_foreign_key_and_gives_them_back(engine):
    """finish_build moves the staged rows with SQLite's foreign keys and row checks off (each
    was checked when it was staged): the moved rows still meet them, and the connection that
    moved them goes back to the pool with both on (a dwell row of no segment, a negative dwell
    key are refused)."""
    _complete(engine)
    with engine.connect() as conn:
        if engine.dialect.name == "sqlite":
            assert conn.exec_driver_sql("PRAGMA foreign_key_check").all() == []
            assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
        assert conn.execute(select(func.count()).select_from(dwell_staging)).scalar_one() == 0
        moved = conn.execute(select(Dwell.__table__)).mappings().first()
    assert moved is not None
    with pytest.raises(IntegrityError), engine.begin() as conn:
        conn.execute(insert(Dwell), [{**moved, "segment_id": -7}])
    with pytest.raises(IntegrityError, match="CHECK|check constraint"), engine.begin() as conn:  # row checks back on
        conn.execute(insert(Dwell), [{**moved, "level": 5, "dwell_key": -1.0}])


def test_verify_passes_a_whole_atlas_and_names_a_changed_value_and_orphans(engine):
    from db.summary import verify_atlas

    h = _complete(engine)
    ok = verify_atlas(engine)
    assert ok.problems == () and ok.orphans == {"dwell": 0, "segment": 0, "linkage": 0, "shard": 0}
    assert list(ok.digests) == [h.build_id] and ok.digests[h.build_id][0] == ok.digests[h.build_id][1]
    assert ok.integrity == ("ok" if engine.dialect.name == "sqlite" else None)
    with engine.begin() as conn:  # shard 1's dwell row (segment ids follow linkage ids)
        first = conn.execute(select(func.max(Dwell.segment_id))).scalar_one()
        conn.execute(
            update(Dwell).where(Dwell.segment_id == first).values(x=Dwell.x + 1e-6)
        )  # above the digest's 40 bits
    bad = verify_atlas(engine)
    # the shard whose rows changed (against its shard row's digest), then the build's digest
    assert len(bad.problems) == 2 and "the rows of shard(s) 1 do not give the digest stored" in bad.problems[0]
    assert "do not give its stored content digest" in bad.problems[1]


def test_a_build_row_deleted_is_one_line_not_a_collision(engine):
    _complete(engine)
    with engine.begin() as conn:  # what a hand edit with foreign keys off leaves
        if engine.dialect.name == "sqlite":
            conn.exec_driver_sql("PRAGMA foreign_keys=OFF")
            conn.execute(delete(Build))
        else:  # the owner (not a superuser: no DISABLE TRIGGER ALL) drops and re-adds the keys
            keys = [
                (t, fk)
                for t in ("linkage", "shard")
                for fk in inspect(conn).get_foreign_keys(t)
                if fk["referred_table"] == "build"
            ]
            for table, fk in keys:
                conn.execute(text(f'ALTER TABLE {table} DROP CONSTRAINT "{fk["name"]}"'))
            conn.execute(delete(Build))
            for table, fk in keys:  # NOT VALID: the orphans stay, as a hand edit would leave them
                cols = ", ".join(fk["constrained_columns"])
                ref = ", ".join(fk["referred_columns"])
                conn.execute(
                    text(
                        f'ALTER TABLE {table} ADD CONSTRAINT "{fk["name"]}" FOREIGN KEY ({cols}) '
                        f"REFERENCES build ({ref}) NOT VALID"
                    )
                )
    with pytest.raises(AtlasError, match=r"holds rows of build 1, which has no build row; restore .* --replace"):
        start(engine)
    h, _ = start(engine, replace=True)  # the way back: everything is deleted, orphans included
    assert count(engine, Linkage) == 0 and (h.replaced or "").startswith("rows of no recorded build")


@pytest.mark.parametrize("form", FORMS)
def test_a_shard_whose_rows_are_already_stored_is_a_damaged_atlas(engine, form):
    h, lock = start(engine)
    write_shard(engine, h.build_id, shard_rows(0), lock_token=lock.token)
    with engine.begin() as conn:  # its shard row lost, its rows kept: what no writer leaves
        conn.execute(delete(Shard))
    with pytest.raises(
        AtlasError,
        match=r"is damaged: it already holds linkage \d+ of shard 0, which has no shard "
        r"row \(shard rolled back\); restore",
    ):
        write_shard(engine, h.build_id, form(shard_rows(0)), lock_token=lock.token)
    assert count(engine, Linkage) == 1 and count(engine, Shard) == 0


@pytest.mark.parametrize("empty", [False, True])
def test_a_packed_shard_stores_what_its_plain_rows_store(engine, tmp_path, empty):
    """The same shards written packed into this atlas and plain into another hold the same
    rows, value for value, and the same shard rows; a packed shard unpacks to its rows (an
    empty shard too: a batch of linkages none of which gives a segment)."""
    rows = [shard_rows(i) for i in range(3)]
    if empty:
        rows[1] = with_rows(rows[1], segments=[], dwells=[])
    other = open_atlas(str(tmp_path / "plain.sqlite"), create=True)
    for target, form in ((engine, packed), (other, plain)):
        h, lock = start(target)
        for r in rows:
            write_shard(target, h.build_id, form(r), lock_token=lock.token)
    for r in rows:
        p = pack(r, "d")
        assert (
            isinstance(p, PackedShard)
            and p.digest == "d"
            and p.linkage_ids == r.linkage_ids == tuple(x["id"] for x in r.linkages.rows())
        )
        assert [t.rows() for t in (p.linkages, p.segments, p.dwells)] == [
            t.rows() for t in (r.linkages, r.segments, r.dwells)
        ]
        assert (p.n_linkages, p.n_segments, p.n_dwells) == (len(r.linkages), len(r.segments), len(r.dwells))
    tables = (Linkage.__table__, Segment.__table__, dwell_staging, Shard.__table__)
    read = []
    for target in (engine, other):
        with target.connect() as conn:
            read.append([sorted(tuple(map(repr, row)) for row in conn.execute(select(t))) for t in tables])
    assert read[0] == read[1] and len(read[0][2]) == 3 - empty
    other.dispose()
