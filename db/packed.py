"""A shard's rows packed as a small SQLite database: what a worker hands the single writer.

Why: most of the writer's share of a build was Python — unpickling a shard's rows as dicts,
making tuples of them, checking their floats — and binding every value of every row
(``executemany``, ~3.6 µs a row). A worker instead checks its rows and inserts them into an
in-memory SQLite database of its own, under the atlas's table and column names, and hands over
its bytes (:meth:`sqlite3.Connection.serialize`: ~2 MB for a ``standard`` shard, against
3.8 MB of pickled dicts). The writer attaches them (:meth:`~sqlite3.Connection.deserialize`)
and copies each table with one ``INSERT … SELECT``, in C: the same rows in the same order, the
same values bit for bit (SQLite stores the same REAL, INTEGER and TEXT either way), under the
atlas's own constraints. On another database the writer reads the tuples back and loads them
as it loads any rows (``COPY`` on PostgreSQL).

NaN and ±inf: SQLite stores a NaN as NULL, which a nullable column would take silently, so rows
are checked before they are packed (:func:`checked_rows`: ``isfinite`` over each float column
of the shard's :class:`db.rows.TableColumns`, the first culprit named) — the check the writer
made before, moved with the rows.
"""

from __future__ import annotations

import math
import sqlite3
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from sqlalchemy import Table

from db.rows import TableColumns
from db.schema import Linkage, Segment, dwell_staging

__all__ = ["PACKING", "PackedShard", "ShardRows", "ShardWriteError", "checked_rows", "pack", "unpack"]

#: Whether this Python's sqlite3 can serialize a database (SQLite ≥ 3.36, Python ≥ 3.11 on
#: most builds); where it cannot, workers hand over plain rows.
PACKING = hasattr(sqlite3.Connection, "serialize") and hasattr(sqlite3.Connection, "deserialize")


class ShardWriteError(RuntimeError):
    """A shard's rows could not be stored (a bug upstream: NaN/inf, a duplicate id, …).

    The whole shard was rolled back; nothing of it is in the database.
    """


class ShardRows(Protocol):
    """What a shard result holds (``atlas.shard.ShardResult``): its rows per table, as columns."""

    shard_index: int
    linkages: TableColumns
    segments: TableColumns
    dwells: TableColumns
    skipped: dict[str, int]
    seconds: float

    @property
    def linkage_ids(self) -> tuple[int, ...]: ...


#: Per table: its name in messages, its columns' attribute in :class:`ShardRows`, the atlas table its rows
#: go to; parents first (where the writer's foreign keys are on, each row is checked as it goes in).
TABLES: tuple[tuple[str, str, Table], ...] = (
    ("linkage", "linkages", Linkage.__table__),
    ("segment", "segments", Segment.__table__),
    ("dwell", "dwells", dwell_staging),
)


def checked_rows(
    result: ShardRows, extra: dict[str, dict[str, Any]] | None = None
) -> list[tuple[Table, list[str], list[tuple]]]:
    """The rows of ``result`` per atlas table — (table, column names in schema order, tuples of
    plain Python values) — after checking that every float is finite (:class:`ShardWriteError`
    naming the first that is not, row by row). ``extra`` adds a column of one value to every
    row of a table (the writer's ``build_id``)."""
    index = int(result.shard_index)
    out = []
    for name, attr, table in TABLES:
        columns: TableColumns = getattr(result, attr)
        bad = columns.first_nonfinite()
        if bad is not None:
            i, key, value = bad
            raise ShardWriteError(
                f"shard {index}: {name} row {i} has {key}={value!r}; nothing of the shard was written"
            )
        n = len(columns)
        given = dict(zip(columns.values, columns.lists()))
        if n:
            given.update({k: [v] * n for k, v in (extra or {}).get(table.name, {}).items()})
        names = [c.name for c in table.columns if c.name in given]
        out.append((table, names, list(zip(*(given[k] for k in names)))))
    if not math.isfinite(result.seconds):
        raise ShardWriteError(f"shard {index}: seconds={result.seconds!r}; nothing of the shard was written")
    problem = _foreign_reference(result)
    if problem:
        raise ShardWriteError(f"shard {index}: {problem}; nothing of the shard was written")
    return out


def _foreign_reference(result: ShardRows) -> str | None:
    """What in ``result`` names a row outside the shard — a segment of a linkage it does not
    hold, a dwell row of a segment it does not hold — or names one (segment, level) twice;
    None if nothing. A shard's rows name only each other (ids derive from its linkages, see
    ``db.rows``), so its foreign keys hold within the shard itself: a packed shard is copied
    with SQLite's foreign key checks off (``db.writes._attached``), on this check's word."""
    values = lambda table, name: np.asarray(table.values.get(name, ()), np.int64)  # noqa: E731
    links, segments = values(result.linkages, "id"), values(result.segments, "id")
    owner = values(result.segments, "linkage_id")
    stray = owner[~np.isin(owner, links)]
    if stray.size:
        return f"a segment names linkage {int(stray[0])}, which is not one of the shard's"
    seg, level = values(result.dwells, "segment_id"), values(result.dwells, "level")
    stray = seg[~np.isin(seg, segments)]
    if stray.size:
        return f"a dwell row names segment {int(stray[0])}, which is not one of the shard's"
    order = np.lexsort((level, seg))
    twice = np.flatnonzero((np.diff(seg[order]) == 0) & (np.diff(level[order]) == 0))
    if twice.size:
        i = order[twice[0]]
        return f"two dwell rows of segment {int(seg[i])} at level {int(level[i])}"
    return None


@dataclass(frozen=True, slots=True)
class PackedShard:
    """A shard's rows packed by :func:`pack`: ``data`` is a serialized SQLite database with a
    table per atlas table it fills (``linkage`` without ``build_id``, ``segment``,
    ``dwell_staging``), its columns named as the atlas's. The rest is what the writer stores
    beside the rows (:class:`ShardRows`' fields, the counts and the shard's digest)."""

    shard_index: int
    data: bytes
    n_linkages: int
    n_segments: int
    n_dwells: int
    linkage_ids: tuple[int, ...]
    skipped: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0
    digest: str | None = None

    # the rows as columns again (tests, and the writer where it cannot attach the packed database)
    @property
    def linkages(self) -> TableColumns:
        return TableColumns.of_rows(None, unpack(self.data, "linkage"))

    @property
    def segments(self) -> TableColumns:
        return TableColumns.of_rows(None, unpack(self.data, "segment"))

    @property
    def dwells(self) -> TableColumns:
        return TableColumns.of_rows(None, unpack(self.data, dwell_staging.name))


def pack(result: ShardRows, digest: str | None) -> PackedShard:
    """``result``'s rows checked (:func:`checked_rows`) and packed; ``digest`` is the shard's
    ``db.digest.shard_digest``, computed from the same rows."""
    batches = checked_rows(result)
    con = sqlite3.connect(":memory:")
    try:
        for table, names, tuples in batches:
            # no types, no constraints: the values go in as Python gives them (REAL, INTEGER,
            # TEXT, NULL) and come out the same; the atlas's tables check them on the copy
            declared = names or [c.name for c in table.columns if c.name != "build_id"]  # (an empty table)
            con.execute(f"CREATE TABLE {_quote(table.name)} ({', '.join(map(_quote, declared))})")
            if tuples:
                con.executemany(f"INSERT INTO {_quote(table.name)} VALUES ({', '.join('?' * len(names))})", tuples)
        con.commit()
        data = con.serialize()
    finally:
        con.close()
    return PackedShard(
        shard_index=int(result.shard_index),
        data=data,
        n_linkages=len(batches[0][2]),
        n_segments=len(batches[1][2]),
        n_dwells=len(batches[2][2]),
        linkage_ids=tuple(result.linkage_ids),
        skipped=dict(result.skipped),
        seconds=float(result.seconds),
        digest=digest,
    )


def unpack(data: bytes, table: str) -> list[dict[str, Any]]:
    """The rows of ``table`` in packed ``data``, as dicts in their packed order."""
    con = sqlite3.connect(":memory:")
    try:
        con.deserialize(data)
        con.row_factory = sqlite3.Row
        return [dict(row) for row in con.execute(f"SELECT * FROM {_quote(table)} ORDER BY rowid")]
    finally:
        con.close()


def columns(raw: sqlite3.Connection, schema: str, table: str) -> list[str]:
    """The column names of ``table`` in the attached packed ``schema``."""
    return [row[1] for row in raw.execute(f"PRAGMA {_quote(schema)}.table_info({_quote(table)})")]


def _quote(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'
