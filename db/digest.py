"""The content digest of an atlas: one hash for "these two atlases hold the same data".

Definition (schema 6). A **shard's digest** is SHA-256 (hex) over its linkage, segment and
dwell rows, table by table: a header line naming the table and its columns
(``#<table>\t<column>\t…\n``), then the shard's rows of that table in primary-key order (ids
are deterministic in the sweep, see ``db.rows``; a dwell row's key is its kind, level, dwell key
and segment id), each row a fixed-width little-endian record of its columns in schema order,
except volatile or bookkeeping ones:

* ``linkage.build_id`` — an autoincrement handle of the build row, not content (a rebuild
  after ``--replace`` gets a new one);
* the ``shard`` and ``build`` tables entirely (compute seconds, timestamps, lock, versions).

A column's field in the record: one byte, 1 where the value is NULL and 0 otherwise, then

* a float: its IEEE-754 binary64 bits rounded to **40 significant bits** (2¹² added to the bit
  pattern, the low 13 bits cleared: round half away from zero; a carry moves to the next
  binade as it should), −0.0 taken as +0.0; 8 bytes. 40 bits are about 12 decimal digits, as
  the ``%.12g`` text of schema ≤ 5 was: the last-bit noise of a different BLAS or CPU does not
  change the digest (unless a value lies on a rounding edge, as with any rounding);
* an integer: int64, 8 bytes;
* a text: its UTF-8 bytes, zero-padded to the column's declared length;
* a NULL: zero bytes of the same width.

The **content digest** of a build (or of the whole atlas) is SHA-256 over one line per shard,
``<shard index>\t<shard digest>\n``, in shard order. A segment or dwell row belongs to the
shard of its linkage (a segment id is its linkage id · ``SEGMENTS_PER_LINKAGE`` plus an
ordinal).

Why records, not text: a worker digests a shard from the arrays it computed
(:class:`db.rows.TableColumns`, ~380 000 values a ``standard`` shard) in a few milliseconds;
the text of schema ≤ 5 cost ~0.1 s of the shard's 1.2 s. The rows read back from a database
give the same records (:func:`shard_digests`).

Why per shard: the worker that computes a shard digests its rows (:func:`shard_digest`, in
``atlas.shard``), the driver stores it in the shard's row, and a build's digest at the end
reads one row per shard (:func:`stored_digest`) instead of every row of the atlas — the single
writer does not re-read what it wrote. :func:`content_digest` recomputes it from the rows (one
pass over each table; ``dwell atlas info --verify``), and :func:`shard_digests` names the shards
whose rows no longer give their stored digest. Two builds of the same spec give the same digest
whatever the worker count, completion order or resume history.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from sqlalchemy import Column, Connection, Engine, Float, Integer, select, union_all

from db.rows import SEGMENTS_PER_LINKAGE, TableColumns
from db.schema import Dwell, Linkage, Segment, Shard, dwell_staging

__all__ = [
    "DIGEST_EXCLUDED",
    "combine",
    "content_digest",
    "rounded_bits",
    "shard_digest",
    "shard_digests",
    "stored_digest",
]

#: Columns left out of the digest, by table.
DIGEST_EXCLUDED: dict[str, frozenset[str]] = {
    "linkage": frozenset({"build_id"}),
    "segment": frozenset(),
    "dwell": frozenset(),
}
#: The tables digested, in digest order.
_MODELS = (Linkage, Segment, Dwell)

_BATCH = 20_000

#: Added to a float's bit pattern before its low :data:`_DROPPED_BITS` bits are cleared: 40
#: significant bits are kept (52 stored − 13 dropped + the implicit one), rounded half away from zero.
_DROPPED_BITS = 13
_HALF = np.uint64(1 << (_DROPPED_BITS - 1))
_KEPT = np.uint64(~((1 << _DROPPED_BITS) - 1) & 0xFFFF_FFFF_FFFF_FFFF)


def rounded_bits(values: ArrayLike) -> NDArray[np.uint64]:
    """The digest's form of floats: their binary64 bits rounded to 40 significant bits, −0.0
    as +0.0 (see the module docstring)."""
    bits = (np.asarray(values, np.float64) + 0.0).view(np.uint64)  # −0.0 + 0.0 is +0.0
    return (bits + _HALF) & _KEPT


def _columns(model: type) -> list[Column]:
    table = model.__table__
    return [c for c in table.columns if c.name not in DIGEST_EXCLUDED[table.name]]


def _header(model: type) -> bytes:
    return ("#" + model.__tablename__ + "\t" + "\t".join(c.name for c in _columns(model)) + "\n").encode()


@functools.cache
def _layout(model: type) -> tuple[bytes, np.dtype, tuple[tuple[str, str, int], ...], tuple[str, ...]]:
    """What digesting ``model``'s rows needs, worked out once: the header, the record's dtype
    (a NULL flag and a value per column, packed), (name, kind, text width) per column in
    :func:`_columns` order, and the primary key's column names."""
    fields, spec = [], []
    for c in _columns(model):
        if isinstance(c.type, Float):
            kind, width, dtype = "float", 8, "<u8"
        elif isinstance(c.type, Integer):  # BigInteger too
            kind, width, dtype = "int", 8, "<i8"
        else:
            kind, width = "text", int(c.type.length)
            dtype = f"S{width}"
        fields += [(c.name + ".null", "u1"), (c.name, dtype)]
        spec.append((c.name, kind, width))
    key = tuple(c.name for c in model.__table__.primary_key.columns)
    return _header(model), np.dtype(fields), tuple(spec), key


def _text(values: Sequence[str], width: int) -> NDArray[np.bytes_]:
    """UTF-8 of each text (a few distinct ones: each is encoded once), zero-padded to ``width``."""
    bad = next((v for v in values if not isinstance(v, str)), None)
    if bad is not None:  # a damaged record: SQLite keeps whatever type a value has, whatever the column says
        raise ValueError(f"a {type(bad).__name__} value where a text is stored")
    encoded = {v: v.encode() for v in set(values)}
    if any(len(b) > width for b in encoded.values()):
        longest = max(encoded, key=lambda v: len(encoded[v]))
        raise ValueError(f"text {longest!r} is longer than its column's {width} bytes")
    return np.array([encoded[v] for v in values], dtype=f"S{width}")


def _numbers(values: Any, kind: type) -> Any:
    """``values`` if every one is a number of the column's ``kind`` (None for NULL, an int
    also in a float column), else ValueError: numpy would read a text "12" as 12."""
    if isinstance(values, np.ndarray) and values.dtype.kind in ("iuf" if kind is float else "iu"):
        return values
    if isinstance(values, np.ndarray) and values.dtype.kind == "f":
        raise ValueError("a real value where an integer is stored")
    allowed = (int, float, np.integer, np.floating) if kind is float else (int, np.integer)
    bad = next((v for v in values if v is not None and (isinstance(v, bool) or not isinstance(v, allowed))), None)
    if bad is not None:
        raise ValueError(
            f"a {type(bad).__name__} value where {'a number' if kind is float else 'an integer'} is stored"
        )
    return values


def _records(model: type, table: TableColumns) -> bytes:
    """The digest's records of ``table``'s rows of ``model``, in primary-key order."""
    _, dtype, spec, key = _layout(model)
    n = len(table)
    if not n:
        return b""
    out = np.zeros(n, dtype)
    for name, kind, width in spec:
        values = table.values[name]
        try:
            value = (
                rounded_bits(_numbers(values, float))
                if kind == "float"
                else np.asarray(_numbers(values, int), np.int64)
                if kind == "int"
                else _text(values, width)
            )
        except (TypeError, ValueError, OverflowError) as exc:
            raise ValueError(f"column {model.__tablename__}.{name}: {exc}") from None
        null = table.nulls.get(name)
        if null is not None:
            value = np.where(null, np.zeros(1, value.dtype), value)
            out[name + ".null"] = null
        out[name] = value
    order = np.lexsort([np.asarray(table.values[k]) for k in reversed(key)])  # the last key sorts first
    return out[order].tobytes()


def _as_columns(model: type, rows: TableColumns | Sequence[Any]) -> TableColumns:
    return rows if isinstance(rows, TableColumns) else TableColumns.of_rows([c.name for c in _columns(model)], rows)


def shard_digest(
    linkages: TableColumns | Sequence[Mapping[str, Any]],
    segments: TableColumns | Sequence[Mapping[str, Any]],
    dwells: TableColumns | Sequence[Mapping[str, Any]],
) -> str:
    """The digest of one shard's rows, per table as columns (``db.rows``) or as dicts keyed by
    column name (columns the digest leaves out may be absent)."""
    h = hashlib.sha256()
    for model, rows in zip(_MODELS, (linkages, segments, dwells)):
        h.update(_layout(model)[0])
        h.update(_records(model, _as_columns(model, rows)))
    return h.hexdigest()


def combine(digests: Iterable[tuple[int, str]]) -> str:
    """The content digest of shards given as (shard index, shard digest), in any order."""
    h = hashlib.sha256()
    for index, digest in sorted(digests):
        h.update(f"{index}\t{digest}\n".encode())
    return h.hexdigest()


def stored_digest(conn: Connection, build_id: int) -> str:
    """The content digest of build ``build_id`` from the shard digests stored in its shard rows."""
    return combine(conn.execute(select(Shard.shard_index, Shard.digest).where(Shard.build_id == build_id)).all())


def shard_digests(bind: Engine | Connection, build_id: int | None = None) -> dict[int, str]:
    """Every shard's digest recomputed from the rows (of build ``build_id``, or of the whole
    atlas): one pass over each table in key order. Shards come from the shard table and from
    the linkage rows (rows without a shard row, a damage, count too)."""
    if isinstance(bind, Connection):
        return _shard_digests(bind, build_id)
    with bind.connect() as conn:
        return _shard_digests(conn, build_id)


def content_digest(bind: Engine | Connection, build_id: int | None = None) -> str:
    """SHA-256 hex of the atlas content (of one build if ``build_id`` is given), recomputed
    from its rows. ``bind`` may be a connection, to digest inside a transaction."""
    return combine(shard_digests(bind, build_id).items())


def _shard_digests(conn: Connection, build_id: int | None) -> dict[int, str]:
    shards = select(Shard.shard_index)
    links = select(Linkage.id, Linkage.shard_index)
    if build_id is not None:
        shards = shards.where(Shard.build_id == build_id)
        links = links.where(Linkage.build_id == build_id)
    hashers: dict[int, Any] = {int(i): hashlib.sha256() for i in conn.execute(shards).scalars()}
    shard_of: dict[int, int] = {}
    for lid, index in conn.execute(links.execution_options(yield_per=_BATCH)):
        shard_of[int(lid)] = int(index)
        hashers.setdefault(int(index), hashlib.sha256())
    for model in _MODELS:
        cols = _columns(model)
        header = _header(model)
        for h in hashers.values():
            h.update(header)
        # the column naming the row's linkage (a segment id is its linkage id · SEGMENTS_PER_LINKAGE + ordinal)
        owner, per_linkage = {
            Linkage: ("id", 1),
            Segment: ("linkage_id", 1),
            Dwell: ("segment_id", SEGMENTS_PER_LINKAGE),
        }[model]
        owner = [c.name for c in cols].index(owner)
        key = [c.name for c in model.__table__.primary_key.columns]
        if model is Dwell:  # a build in progress holds its dwell rows in the staging table
            both = union_all(select(*cols), select(*(dwell_staging.c[c.name] for c in cols)))
            stmt = both.order_by(*(both.selected_columns[n] for n in key))
        else:
            stmt = select(*cols).order_by(*(model.__table__.c[n] for n in key))
        # streamed in batches: a big atlas does not fit in memory. The option goes on the
        # statement: ``Connection.execution_options`` changes the connection itself, and on
        # PostgreSQL every later statement of the transaction would then run through a
        # server-side cursor (which an UPDATE cannot).
        for part in conn.execute(stmt.execution_options(yield_per=_BATCH)).partitions():
            by_shard: dict[int, list] = {}
            for row in part:
                index = shard_of.get(int(row[owner]) // per_linkage)
                if index is not None:  # another build's row (or an orphan: --verify counts those)
                    by_shard.setdefault(index, []).append(row)
            names = [c.name for c in cols]
            for index, rows in by_shard.items():
                try:
                    columns = TableColumns.of_rows(names, rows)
                except (TypeError, ValueError, OverflowError):  # e.g. a blob in a number column
                    raise ValueError(
                        f"table {model.__tablename__}: a value of the wrong type in shard {index}"
                    ) from None
                hashers[index].update(_records(model, columns))
    return {index: h.hexdigest() for index, h in sorted(hashers.items())}
