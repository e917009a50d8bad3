"""Writes of an atlas build: the build row, its builder lock, one transaction per shard.

Invariants
----------
* **A shard is all or nothing.** :func:`write_shard` inserts a shard's linkage, segment and
  dwell rows *and* its shard row in one transaction; a shard row therefore means "every row
  of this shard is here". Resume = compute the shards without a shard row. On PostgreSQL
  with psycopg the rows go in by ``COPY`` (in the same transaction, CHECKs enforced alike):
  ten times faster than an executemany of ``INSERT``, which would make the single writer
  the bottleneck of a big build; on SQLite a shard packed by its worker (:mod:`db.packed`) is
  attached and copied with one ``INSERT … SELECT`` per table, plain rows go in by one raw
  ``executemany`` of tuples per table. A
  shard's dwell rows are appended to ``dwell_staging``; :func:`finish_build` moves them into
  the clustered ``dwell`` table in its key order, in the transaction that completes the build
  (and stores its digest, combined from the shard digests of the shard rows).
* **An atlas holds one build.** A different sweep (by spec digest, the preset name is
  ignored) is refused unless ``replace`` is given; replacing deletes the old build's rows in
  the same transaction that creates the new build row.
* **One writer per build.** The builder lock is a row lock kept in the ``build`` table
  (``lock_token``, ``lock_pid``, ``lock_host``, ``lock_heartbeat``), not SQLite's file lock, so
  it works the same on PostgreSQL and survives between transactions. It is taken and every
  shard is written by compare-and-swap on ``lock_token`` (``UPDATE … WHERE lock_token = ours``
  first in the transaction), so even two builders that both believe they hold it can never
  both write: the loser's next shard fails with :class:`LockLostError` and is rolled back.

  A lock is *dead* (and is taken over silently) when its holder is on this host and its pid
  no longer runs (a zombie counts as dead), or its heartbeat is older than
  :data:`STALE_SECONDS` (another host, whose pids we cannot see), or older than
  :data:`PID_REUSE_SECONDS` on this host (the pid was reused by an unrelated process). So a
  killed build on the same machine is resumable at once, a killed build on another machine
  after :data:`STALE_SECONDS`.

Nothing here imports ``atlas``: a shard result is anything shaped like :class:`ShardRows`.
"""

from __future__ import annotations

import json
import math
import os
import socket
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import Connection, Engine, Table, delete, func, insert, select, update
from sqlalchemy.exc import IntegrityError

from db.digest import shard_digest, stored_digest
from db.engine import AtlasError, atlas_name, damaged, display_target, start_writing
from db.packed import TABLES, PackedShard, ShardRows, ShardWriteError, checked_rows
from db.packed import columns as packed_columns
from db.schema import SCHEMA_VERSION, Build, Dwell, Linkage, Segment, Shard, dwell_staging
from db.spec import spec_name

__all__ = [
    "PID_REUSE_SECONDS",
    "STALE_SECONDS",
    "BuildHandle",
    "BuildLock",
    "LockLostError",
    "ShardRows",
    "ShardWriteError",
    "code_version",
    "finish_build",
    "heartbeat",
    "open_build",
    "release_lock",
    "write_shard",
]

#: A lock held from another host is dead when its heartbeat is older than this (seconds).
#: Heartbeats come with every shard commit and, while waiting on workers, every few seconds.
STALE_SECONDS = 300.0
#: On this host a live pid keeps a lock alive unless its heartbeat is older than this: then
#: the pid has been reused by some unrelated process.
PID_REUSE_SECONDS = 3600.0


class LockLostError(AtlasError):
    """Another builder took this build's lock over (ours was seen as dead)."""


@dataclass(frozen=True, slots=True)
class BuildLock:
    """This process's claim on a build: a random token plus who we are (for messages)."""

    token: str
    pid: int
    host: str

    @classmethod
    def mine(cls) -> BuildLock:
        return cls(uuid.uuid4().hex, os.getpid(), socket.gethostname())


@dataclass(frozen=True, slots=True)
class BuildHandle:
    """The build a builder works on, as found or created by :func:`open_build`.

    ``done`` holds the shard indices already written; ``resumed`` is True when some were;
    ``replaced`` describes the build that ``replace`` deleted (None if none); ``complete``
    is True when there is nothing left to do (then no lock is held).
    """

    build_id: int
    n_shards: int
    done: frozenset[int]
    resumed: bool
    complete: bool
    replaced: str | None = None


def code_version() -> str:
    """The installed package version (``importlib.metadata``); no git involved."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("dwell-atlas")
    except PackageNotFoundError:  # running from a source tree that was never installed
        return "unknown"


def _now_iso() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _pid_alive(pid: int) -> bool:
    """True if ``pid`` runs on this host (a zombie — killed, not yet reaped — is dead)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    except OSError:
        return False
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            # state is the field after the parenthesised command name (which may hold spaces)
            state = fh.read().rsplit(b")", 1)[1].split()[0]
        return state not in (b"Z", b"X")
    except (OSError, IndexError):
        return True  # no /proc (macOS …): the signal test above is all we have


def _lock_alive(row: Any, now: float) -> bool:
    """Whether the lock recorded in build ``row`` belongs to a process that still runs."""
    if row.lock_token is None:
        return False
    age = now - (row.lock_heartbeat if row.lock_heartbeat is not None else -math.inf)
    if row.lock_host == socket.gethostname() and row.lock_pid is not None:
        return _pid_alive(int(row.lock_pid)) and age < PID_REUSE_SECONDS
    return age < STALE_SECONDS


def _describe_holder(target: str, row: Any, now: float) -> str:
    age = now - row.lock_heartbeat if row.lock_heartbeat is not None else float("nan")
    return (
        f"atlas {target!r} is being built by another process (pid {row.lock_pid} on {row.lock_host}, "
        f"last heartbeat {age:.0f} s ago); wait for it to finish or stop it"
    )


def _describe_spec(spec_json: str, spec_digest: str) -> str:
    return f"preset {spec_name(spec_json)}, digest {spec_digest[:8]}…"


def _take_lock(conn: Connection, row: Any, lock: BuildLock, target: str) -> None:
    """Compare-and-swap ``row``'s lock (as read) for ours; refuse if someone was faster."""
    old = Build.lock_token.is_(None) if row.lock_token is None else Build.lock_token == row.lock_token
    res = conn.execute(
        update(Build)
        .where(Build.id == row.id, old)
        .values(lock_token=lock.token, lock_pid=lock.pid, lock_host=lock.host, lock_heartbeat=time.time())
    )
    if res.rowcount != 1:
        raise AtlasError(
            f"atlas {target!r} is being built by another process (it took the lock just now); wait for it to finish"
        )


def _delete_rows(conn: Connection, build_id: int, *, unfinished_only: bool = False) -> None:
    """Delete a build's linkage, segment and dwell rows (with ``unfinished_only``, only those
    of shards that have no shard row)."""
    links = select(Linkage.id).where(Linkage.build_id == build_id)
    if unfinished_only:
        # a subquery, not a literal list: thousands of shards would exceed SQLite's parameter limit
        links = links.where(Linkage.shard_index.not_in(select(Shard.shard_index).where(Shard.build_id == build_id)))
    segs = select(Segment.id).where(Segment.linkage_id.in_(links))
    conn.execute(delete(dwell_staging).where(dwell_staging.c.segment_id.in_(segs)))
    conn.execute(delete(Dwell).where(Dwell.segment_id.in_(segs)))
    conn.execute(delete(Segment).where(Segment.linkage_id.in_(links)))
    conn.execute(delete(Linkage).where(Linkage.id.in_(links)))


def open_build(
    engine: Engine,
    *,
    target: str,
    spec_json: str,
    spec_digest: str,
    n_shards: int,
    lock: BuildLock,
    replace: bool = False,
) -> BuildHandle:
    """Create the build of ``spec_digest`` or resume it, taking the builder lock.

    Refuses (:class:`AtlasError`, nothing changed) a different sweep unless ``replace``, a
    build locked by a live builder, and resuming a build half-made by another code version.
    With ``replace`` every existing build (same sweep or not) is deleted and rebuilt.
    On resume the rows of shards without a shard row are deleted first (there should be
    none, shards are atomic: this is a defence against a writer that was not).
    """
    if not 1 <= n_shards:
        raise ValueError(f"n_shards must be >= 1, got {n_shards}")
    target = display_target(target)  # messages below name it; never with a password
    now = time.time()
    with engine.connect() as conn:
        builds = conn.execute(select(Build).order_by(Build.id)).all()
    for row in builds:
        # a live builder of another sweep matters only if we are about to delete its build
        relevant = replace or row.spec_digest == spec_digest
        if relevant and row.lock_token is not None and row.lock_token != lock.token and _lock_alive(row, now):
            raise AtlasError(_describe_holder(target, row, now))
    others = [r for r in builds if r.spec_digest != spec_digest]
    if others and not replace:
        old = others[0]
        raise AtlasError(
            f"atlas {target!r} was built with a different sweep ({_describe_spec(old.spec_json, old.spec_digest)}); "
            "use --replace to rebuild it"
        )
    same = next((r for r in builds if r.spec_digest == spec_digest), None)
    version = code_version()

    if replace and (builds or _holds_rows(engine)):
        replaced = "; ".join(_describe_spec(r.spec_json, r.spec_digest) for r in builds) or "rows of no recorded build"
        start_writing(engine)
        with engine.begin() as conn:
            for row in builds:
                _take_lock(conn, row, lock, target)  # first: fails fast if a builder sneaked in
            # everything, children first: also rows a damaged atlas holds for no recorded build
            for table in (
                dwell_staging,
                Dwell.__table__,
                Segment.__table__,
                Linkage.__table__,
                Shard.__table__,
                Build.__table__,
            ):
                conn.execute(delete(table))
            build_id = _insert_build(conn, spec_json, spec_digest, n_shards, lock, version)
        return BuildHandle(build_id, n_shards, frozenset(), resumed=False, complete=False, replaced=replaced)

    if not replace:
        _refuse_unrecorded_rows(engine, target)
    if same is None:
        start_writing(engine)
        try:
            with engine.begin() as conn:
                build_id = _insert_build(conn, spec_json, spec_digest, n_shards, lock, version)
        except IntegrityError:  # a concurrent builder created the same build a moment ago
            raise AtlasError(
                f"atlas {target!r} is being built by another process (it started just now); wait for it to finish"
            ) from None
        return BuildHandle(build_id, n_shards, frozenset(), resumed=False, complete=False)

    if same.n_shards != n_shards:  # same spec digest ⇒ same sweep: a different count is a bug
        raise AtlasError(
            f"atlas {target!r} records {same.n_shards} shards for this sweep, this code makes {n_shards}; use --replace"
        )
    with engine.connect() as conn:
        done = frozenset(conn.execute(select(Shard.shard_index).where(Shard.build_id == same.id)).scalars())
    if same.status == "complete":
        return BuildHandle(same.id, n_shards, done, resumed=True, complete=True)
    if same.code_version != version:
        raise AtlasError(
            f"atlas {target!r} was partly built by dwell-atlas {same.code_version} (this is {version}); "
            "use --replace to rebuild it"
        )
    start_writing(engine)
    with engine.begin() as conn:
        _take_lock(conn, same, lock, target)
        _delete_rows(conn, same.id, unfinished_only=True)
    return BuildHandle(same.id, n_shards, done, resumed=bool(done), complete=False)


def _holds_rows(engine: Engine) -> bool:
    with engine.connect() as conn:
        return any(conn.execute(select(model).limit(1)).first() is not None for model in (Linkage, Shard))


def _refuse_unrecorded_rows(engine: Engine, target: str) -> None:
    """A damaged atlas whose build row was deleted still holds that build's shards and
    linkages; building into it would collide with them (their ids are deterministic)."""
    known = select(Build.id)
    with engine.connect() as conn:
        for column in (Shard.build_id, Linkage.build_id):
            stray = conn.execute(select(column).where(column.not_in(known)).limit(1)).scalar()
            if stray is not None:
                raise damaged(target, f"it holds rows of build {stray}, which has no build row")


def _insert_build(
    conn: Connection, spec_json: str, spec_digest: str, n_shards: int, lock: BuildLock, version: str
) -> int:
    res = conn.execute(
        insert(Build).values(
            spec_json=spec_json,
            spec_digest=spec_digest,
            code_version=version,
            schema_version=SCHEMA_VERSION,
            status="building",
            n_shards=n_shards,
            created_at=_now_iso(),
            lock_token=lock.token,
            lock_pid=lock.pid,
            lock_host=lock.host,
            lock_heartbeat=time.time(),
        )
    )
    return int(res.inserted_primary_key[0])


def _assert_lock(conn: Connection, build_id: int, token: str) -> None:
    """Refresh our heartbeat; a write first, so it also takes SQLite's write lock at once."""
    res = conn.execute(
        update(Build).where(Build.id == build_id, Build.lock_token == token).values(lock_heartbeat=time.time())
    )
    if res.rowcount != 1:
        raise LockLostError(
            f"build {build_id} was taken over by another builder (this one was seen as dead); this builder stops"
        )


def heartbeat(engine: Engine, build_id: int, token: str) -> None:
    """Refresh the lock's heartbeat (call every few seconds while waiting on workers)."""
    with engine.begin() as conn:
        _assert_lock(conn, build_id, token)


def _uses_copy(conn: Connection) -> bool:
    """Whether rows are bulk-loaded with ``COPY`` (PostgreSQL through psycopg 3's copy API)."""
    return conn.dialect.name == "postgresql" and conn.dialect.driver == "psycopg"


def _copy_rows(conn: Connection, table: Table, names: list[str], tuples: list[tuple]) -> None:
    """``COPY table FROM STDIN`` of ``tuples`` (values in ``names`` order) inside ``conn``'s
    transaction.

    Text format: psycopg writes floats with ``repr`` (shortest round trip), so the stored
    values are bit-identical to an ``INSERT``'s. A violated constraint is re-raised as
    SQLAlchemy's :class:`IntegrityError`, as an ``INSERT`` would have raised it.
    """
    quote = conn.dialect.identifier_preparer.quote
    sql = f"COPY {quote(table.name)} ({', '.join(quote(n) for n in names)}) FROM STDIN"
    raw = conn.connection.dbapi_connection
    try:
        with raw.cursor() as cur, cur.copy(sql) as copy:
            for row in tuples:
                copy.write_row(row)
    except conn.dialect.loaded_dbapi.IntegrityError as exc:
        raise IntegrityError(sql, None, exc) from exc


def _insert_rows(conn: Connection, table: Table, names: list[str], tuples: list[tuple]) -> None:
    """Bulk insert: ``COPY`` on PostgreSQL (psycopg 3); on a qmark driver (SQLite) one
    ``executemany`` of the tuples as they are (SQLAlchemy's per-row parameter processing cost
    as much as SQLite's own inserts); elsewhere SQLAlchemy's executemany."""
    if not tuples:
        return
    if _uses_copy(conn):
        _copy_rows(conn, table, names, tuples)
    elif conn.dialect.paramstyle == "qmark":
        quote = conn.dialect.identifier_preparer.quote
        conn.exec_driver_sql(
            f"INSERT INTO {quote(table.name)} ({', '.join(map(quote, names))}) VALUES ({', '.join('?' * len(names))})",
            tuples,
        )
    else:
        conn.execute(insert(table), [dict(zip(names, t)) for t in tuples])


def write_shard(
    engine: Engine, build_id: int, result: ShardRows | PackedShard, *, lock_token: str | None = None
) -> None:
    """Store one shard — linkages, segments, dwells and the shard row — in ONE transaction.

    ``result`` is a shard's rows as columns (checked here) or packed by a worker
    (:class:`db.packed.PackedShard`, checked there): on SQLite a packed shard is attached and
    copied table by table with ``INSERT … SELECT``, plain rows go in by one raw
    ``executemany`` of tuples per table; on PostgreSQL both by ``COPY``. With ``lock_token``
    the transaction first checks (and refreshes) our builder lock. Any failure rolls back the
    whole shard: a NaN or inf (SQLite would turn NaN into NULL and a nullable column would
    silently take it) or a constraint violation raises :class:`ShardWriteError`.
    """
    index = int(result.shard_index)
    packed = result if isinstance(result, PackedShard) else None
    extra = {"linkage": {"build_id": build_id}}
    batches = None if packed is not None else checked_rows(result, extra)
    if packed is not None and not math.isfinite(packed.seconds):
        raise ShardWriteError(f"shard {index}: seconds={packed.seconds!r}; nothing of the shard was written")
    counts = (packed.n_linkages, packed.n_segments) if packed is not None else (len(batches[0][2]), len(batches[1][2]))
    shard_row = dict(
        build_id=build_id,
        shard_index=index,
        n_linkages=counts[0],
        n_segments=counts[1],
        skipped_json=json.dumps(dict(sorted(result.skipped.items())), sort_keys=True),
        seconds=float(result.seconds),
        digest=result.digest or shard_digest(result.linkages, result.segments, result.dwells),
    )
    try:
        with engine.connect() as conn, _attached(conn, packed) as schema:
            with conn.begin():
                if lock_token is not None:
                    _assert_lock(conn, build_id, lock_token)
                if schema is not None:
                    _copy_packed(conn, schema, packed, build_id)
                else:
                    # a packed shard that cannot be attached: its rows read back (PostgreSQL)
                    for table, names, tuples in batches if batches is not None else checked_rows(packed, extra):
                        _insert_rows(conn, table, names, tuples)
                conn.execute(insert(Shard), [shard_row])
    except IntegrityError as exc:
        clash = _stored_already(engine, result)
        if clash is not None:  # rows the atlas should not hold (ids are deterministic): damage, not a bug
            raise damaged(
                atlas_name(engine),
                f"it already holds {clash} of shard {index}, which has no shard row (shard rolled back)",
            ) from None
        first = str(exc.orig).splitlines()[0] if exc.orig is not None else str(exc)
        raise ShardWriteError(f"shard {index} of build {build_id} rolled back: {first}") from exc


#: The schema name a packed shard is attached under while it is copied.
_PACKED_SCHEMA = "packed_shard"


@contextmanager
def _attached(conn: Connection, packed: PackedShard | None) -> Iterator[str | None]:
    """On SQLite, ``packed``'s database attached to ``conn`` for the copy, detached afterwards;
    its schema name, or None when there is nothing to attach (plain rows, another database).

    Outside any transaction (SQLite attaches only there, and changes ``foreign_keys`` only
    there), the copy runs with foreign key checks off: a packed shard's rows name only each
    other, which :func:`db.packed.checked_rows` made sure of when it packed them, so the
    checks only cost time (a tenth of the writer's ingest). Its primary keys, uniqueness and
    row checks all still apply."""
    if packed is None or conn.dialect.name != "sqlite":
        yield None
        return
    raw = conn.connection.dbapi_connection
    raw.execute("PRAGMA foreign_keys=OFF")
    try:
        raw.execute(f"ATTACH ':memory:' AS {_PACKED_SCHEMA}")
        try:
            raw.deserialize(packed.data, name=_PACKED_SCHEMA)
            yield _PACKED_SCHEMA
        finally:
            _restore(conn, lambda: raw.execute(f"DETACH {_PACKED_SCHEMA}"))
    finally:
        _restore(conn, lambda: raw.execute("PRAGMA foreign_keys=ON"))


def _restore(conn: Connection, undo: Callable[[], object]) -> None:
    """Run ``undo`` (what puts ``conn`` back as the pool hands it out); if it fails, the
    connection is invalidated (closed, never reused) and the failure raised — unless another
    error (a Ctrl-C, a failed write) is already on its way out, which it must not mask."""
    in_flight = sys.exc_info()[1]  # (called from a finally: the error leaving, if any)
    try:
        undo()
    except Exception:  # noqa: BLE001
        conn.invalidate()
        if in_flight is None:
            raise


def _copy_packed(conn: Connection, schema: str, packed: PackedShard, build_id: int) -> None:
    """The packed tables into the atlas's, one ``INSERT … SELECT`` each, parents first (the
    linkage rows get ``build_id``)."""
    raw = conn.connection.dbapi_connection
    quote = conn.dialect.identifier_preparer.quote
    for (_, _, table), n in zip(TABLES, (packed.n_linkages, packed.n_segments, packed.n_dwells)):
        if not n:
            continue
        names = [quote(c) for c in packed_columns(raw, schema, table.name)]
        source = ", ".join(names)
        if table.name == "linkage":
            conn.exec_driver_sql(
                f"INSERT INTO main.linkage ({quote('build_id')}, {source}) "
                f"SELECT ?, {source} FROM {schema}.linkage ORDER BY rowid",
                (build_id,),
            )
        else:
            conn.exec_driver_sql(
                f"INSERT INTO main.{quote(table.name)} ({source}) "
                f"SELECT {source} FROM {schema}.{quote(table.name)} ORDER BY rowid"
            )


def _stored_already(engine: Engine, result: ShardRows | PackedShard) -> str | None:
    """ "linkage ID" if the atlas already holds one of this shard's linkages — its ids derive
    from the shard index, so that is this shard's own row, stored without its shard row (or
    under a build row since deleted): a damaged atlas. None otherwise (a bug upstream)."""
    ids = list(result.linkage_ids)
    with engine.connect() as conn:
        for start in range(0, len(ids), 500):  # under every dialect's parameter limit
            found = conn.execute(select(Linkage.id).where(Linkage.id.in_(ids[start : start + 500])).limit(1)).scalar()
            if found is not None:
                return f"linkage {found}"
    return None


def finish_build(engine: Engine, build_id: int, token: str) -> bool:
    """Mark the build complete, store its content digest and release the lock — if every
    shard is written. Returns True when it was complete; otherwise only the heartbeat is
    refreshed. The digest combines the shard digests stored with the shards, in the same
    transaction (each was stored in the transaction that wrote its shard's rows)."""
    with engine.connect() as conn, _moving_staged_rows(conn), conn.begin():
        _assert_lock(conn, build_id, token)
        n_shards = conn.execute(select(Build.n_shards).where(Build.id == build_id)).scalar_one()
        done = conn.execute(select(func.count()).select_from(Shard).where(Shard.build_id == build_id)).scalar_one()
        if done < n_shards:
            return False
        # the shards' dwell rows into the clustered table, in its key order: written once,
        # page after page (see ``db.schema.dwell_staging``)
        names = [c.name for c in Dwell.__table__.columns]
        staged = select(*(dwell_staging.c[n] for n in names)).order_by(
            *(dwell_staging.c[c.name] for c in Dwell.__table__.primary_key.columns)
        )
        conn.execute(insert(Dwell).from_select(names, staged))
        conn.execute(delete(dwell_staging))
        conn.execute(
            update(Build)
            .where(Build.id == build_id)
            .values(
                status="complete",
                finished_at=_now_iso(),
                content_digest=stored_digest(conn, build_id),
                lock_token=None,
                lock_pid=None,
                lock_host=None,
                lock_heartbeat=None,
            )
        )
    return True


@contextmanager
def _moving_staged_rows(conn: Connection) -> Iterator[None]:
    """SQLite settings for the move of the staged dwell rows, on ``conn`` outside any
    transaction (SQLite ignores these pragmas inside one), restored afterwards.

    * ``foreign_keys=OFF``: every staged row's segment was checked when the row was staged
      (one of its shard's segments, ``db.packed.checked_rows``), and nothing deletes a segment
      in the move's transaction, so checking each moved row's segment again only costs time:
      ``standard``'s move and delete 9.5 → 5 s.
    * ``ignore_check_constraints=ON``: the staging table has the row checks of ``dwell``
      (``db.schema._dwell_checks``, one definition for both), which every staged row passed
      when it was appended; checking them again took ~15 % of the move.
    * ``threads=2``: the sort of the ``ORDER BY`` may use a helper thread (the workers are done
      by then, a core is free); the sorted rows are the same.

    A connection whose settings cannot be restored is invalidated (closed, never reused)."""
    if conn.dialect.name != "sqlite":
        yield
        return
    conn.exec_driver_sql("PRAGMA foreign_keys=OFF")
    conn.exec_driver_sql("PRAGMA ignore_check_constraints=ON")
    conn.exec_driver_sql("PRAGMA threads=2")
    conn.commit()  # SQLAlchemy's own begin around the pragmas (pysqlite sent no BEGIN for them)
    try:
        yield
    finally:

        def undo() -> None:
            conn.exec_driver_sql("PRAGMA foreign_keys=ON")
            conn.exec_driver_sql("PRAGMA ignore_check_constraints=OFF")
            conn.exec_driver_sql("PRAGMA threads=0")
            conn.commit()

        _restore(conn, undo)


def release_lock(engine: Engine, build_id: int, token: str) -> None:
    """Give the lock up (no-op if it is not ours any more)."""
    with engine.begin() as conn:
        conn.execute(
            update(Build)
            .where(Build.id == build_id, Build.lock_token == token)
            .values(lock_token=None, lock_pid=None, lock_host=None, lock_heartbeat=None)
        )
