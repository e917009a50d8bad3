"""The content digest of an atlas: one hash for "these two atlases hold the same data".

SHA-256 (hex) over every linkage, segment and dwell row, table by table, each in canonical
order (by primary key: ids are deterministic in the sweep, see ``db.rows``, and a dwell row's key
is its kind, level, dwell angle and segment id), all columns in schema order except volatile or
bookkeeping ones:

* ``linkage.build_id`` — an autoincrement handle of the build row, not content (a rebuild
  after ``--replace`` gets a new one);
* the ``shard`` and ``build`` tables entirely (compute seconds, timestamps, lock, versions).

Canonical text of a value: floats ``'%.12g'`` (12 significant digits, so that the last-bit
noise of a different BLAS or CPU does not change the digest) with −0 written as 0; integers
in decimal; strings as JSON; NULL as ``~``. Fields are tab-separated, rows end with a newline,
and each table starts with a header naming it and its columns, so a schema change changes
the digest. Two builds of the same spec give the same digest whatever the worker count,
completion order or resume history.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from typing import Any

from sqlalchemy import Column, Connection, Engine, Float, Integer, select
from sqlalchemy.sql import Select

from db.schema import Dwell, Linkage, Segment

__all__ = ["DIGEST_EXCLUDED", "content_digest", "format_value"]

#: Columns left out of the digest, by table.
DIGEST_EXCLUDED: dict[str, frozenset[str]] = {"linkage": frozenset({"build_id"}), "segment": frozenset(), "dwell": frozenset()}

_NULL = "~"
_BATCH = 20_000


def _float(value: Any) -> str:
    x = float(value)
    if x == 0.0:  # also −0.0
        return "0"
    return "%.12g" % x


def _int(value: Any) -> str:
    return str(int(value))


def _text(value: Any) -> str:
    return json.dumps(value)


def _formatter(column: Column) -> Callable[[Any], str]:
    if isinstance(column.type, Float):
        return _float
    if isinstance(column.type, Integer):  # BigInteger too
        return _int
    return _text


def format_value(column: Column, value: Any) -> str:
    """The canonical text of ``value`` in ``column`` (see the module docstring)."""
    return _NULL if value is None else _formatter(column)(value)


def _statements(build_id: int | None) -> list[tuple[str, list[Column], Select]]:
    out = []
    for model in (Linkage, Segment, Dwell):
        table = model.__table__
        cols = [c for c in table.columns if c.name not in DIGEST_EXCLUDED[table.name]]
        stmt = select(*cols)
        if build_id is not None:
            links = select(Linkage.id).where(Linkage.build_id == build_id)
            if model is Linkage:
                stmt = stmt.where(Linkage.build_id == build_id)
            elif model is Segment:
                stmt = stmt.where(Segment.linkage_id.in_(links))
            else:
                stmt = stmt.where(Dwell.segment_id.in_(select(Segment.id).where(Segment.linkage_id.in_(links))))
        out.append((table.name, cols, stmt.order_by(*table.primary_key.columns)))
    return out


def content_digest(bind: Engine | Connection, build_id: int | None = None) -> str:
    """SHA-256 hex of the atlas content (of one build if ``build_id`` is given).

    ``bind`` may be a connection, to digest inside a transaction (``db.writes.finish_build``).
    """
    if isinstance(bind, Connection):
        return _digest(bind, build_id)
    with bind.connect() as conn:
        return _digest(conn, build_id)


def _digest(conn: Connection, build_id: int | None) -> str:
    h = hashlib.sha256()
    for name, cols, stmt in _statements(build_id):
        h.update(_header(name, cols))
        fmts = [_formatter(c) for c in cols]
        # streamed in batches: a big atlas does not fit in memory. The option goes on the
        # statement: ``Connection.execution_options`` changes the connection itself, and on
        # PostgreSQL every later statement of the transaction would then run through a
        # server-side cursor (which an UPDATE cannot).
        result = conn.execute(stmt.execution_options(yield_per=_BATCH))
        for part in result.partitions():
            lines = []
            for row in part:
                lines.append("\t".join(_NULL if v is None else f(v) for f, v in zip(fmts, row)))
                lines.append("\n")
            h.update("".join(lines).encode())
    return h.hexdigest()


def _header(name: str, cols: list[Column]) -> bytes:
    return ("#" + name + "\t" + "\t".join(c.name for c in cols) + "\n").encode()
