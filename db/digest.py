"""The content digest of an atlas: one hash for "these two atlases hold the same data".

Definition (schema 4; schema 5 adds an arc's dwell key). A **shard's digest** is SHA-256
(hex) over its linkage, segment and dwell rows, table by table: a header line naming the
table and its columns, then the shard's rows of that table in primary-key order (ids are deterministic in the sweep, see ``db.rows``;
a dwell row's key is its kind, level, dwell key and segment id), all columns in schema order
except volatile or bookkeeping ones:

* ``linkage.build_id`` — an autoincrement handle of the build row, not content (a rebuild
  after ``--replace`` gets a new one);
* the ``shard`` and ``build`` tables entirely (compute seconds, timestamps, lock, versions).

The **content digest** of a build (or of the whole atlas) is SHA-256 over one line per shard,
``<shard index>\\t<shard digest>\\n``, in shard order. A segment or dwell row belongs to the
shard of its linkage (a segment id is its linkage id · ``SEGMENTS_PER_LINKAGE`` plus an
ordinal).

Canonical text of a value: floats ``'%.12g'`` (12 significant digits, so that the last-bit
noise of a different BLAS or CPU does not change the digest) with −0 written as 0; integers
in decimal; strings as JSON; NULL as ``~``. Fields are tab-separated, rows end with a newline.

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
import itertools
import json
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from operator import is_, itemgetter
from typing import Any

from sqlalchemy import Column, Connection, Engine, Float, Integer, select, union_all

from db.rows import SEGMENTS_PER_LINKAGE
from db.schema import Dwell, Linkage, Segment, Shard, dwell_staging

__all__ = ["DIGEST_EXCLUDED", "combine", "content_digest", "format_value", "shard_digest", "shard_digests",
           "stored_digest"]

#: Columns left out of the digest, by table.
DIGEST_EXCLUDED: dict[str, frozenset[str]] = {"linkage": frozenset({"build_id"}), "segment": frozenset(), "dwell": frozenset()}
#: The tables digested, in digest order.
_MODELS = (Linkage, Segment, Dwell)

_NULL = "~"
_BATCH = 20_000


def _float(value: Any) -> str:
    text = "%.12g" % value
    return "0" if text == "-0" else text  # −0.0 is 0


def _int(value: Any) -> str:
    return "%d" % value


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


# The digest formats a table a row at a time, with one ``%`` format per row (:func:`_text_of`),
# not a value at a time through :func:`format_value`: the same text (``%.12g``, ``%d``, JSON,
# ``~``), but a worker digests ~330 000 values a shard and a Python call per value was most of
# its cost. ``tests/db/test_digest.py`` holds the two to the same text.

#: A NULL field in a row format: ``%.0s`` takes the None and writes nothing of it.
_NULL_SPEC = _NULL + "%.0s"


def _text_column(values: Sequence[Any]) -> list[str]:
    """:func:`format_value` of every value of a text column. A text column holds a few distinct
    strings (a segment's kind): each is encoded once. A ``str`` subclass (a ``StrEnum``
    member) encodes as its string, so equal strings share a text; anything else is encoded
    value by value."""
    if all(t is type(None) or issubclass(t, str) for t in set(map(type, values))):
        text = {v: _NULL if v is None else json.dumps(v) for v in set(values)}
        return list(map(text.__getitem__, values))
    return [_NULL if v is None else json.dumps(v) for v in values]


def _columns(model: type) -> list[Column]:
    table = model.__table__
    return [c for c in table.columns if c.name not in DIGEST_EXCLUDED[table.name]]


def _header(model: type) -> bytes:
    return ("#" + model.__tablename__ + "\t" + "\t".join(c.name for c in _columns(model)) + "\n").encode()


@functools.cache
def _plan(model: type) -> tuple[bytes, tuple[str, ...], tuple[str, ...], tuple[int, ...]]:
    """What digesting ``model``'s rows needs, worked out once: header, and in :func:`_columns`
    order the column names, their kinds ("float", "int", "text") and the positions of the
    nullable ones."""
    cols = _columns(model)
    kinds = tuple("float" if isinstance(c.type, Float) else "int" if isinstance(c.type, Integer) else "text"
                  for c in cols)  # Integer: BigInteger too (as :func:`_formatter`)
    return _header(model), tuple(c.name for c in cols), kinds, tuple(j for j, c in enumerate(cols) if c.nullable)


def _key(model: type) -> Callable[[Sequence[Any]], Any]:
    """The primary key of a row given as a tuple in :func:`_columns` order (one column: the
    value itself, which sorts as its 1-tuple would)."""
    names = _plan(model)[1]
    return itemgetter(*(names.index(c.name) for c in model.__table__.primary_key.columns))


class _RowFormats(dict):
    """Row format strings by the row's NULL pattern (a bool per column of ``nullable``, True:
    NULL), each made on first use: a table has a few patterns (a line's dwell row leaves the
    arc's columns NULL, an arc's the line's)."""

    def __init__(self, specs: list[str], nullable: list[int]) -> None:
        super().__init__()
        self.specs, self.nullable = specs, nullable

    def __missing__(self, pattern: tuple[bool, ...]) -> str:
        specs = list(self.specs)
        for j, null in zip(self.nullable, pattern):
            if null:
                specs[j] = _NULL_SPEC
        self[pattern] = fmt = "\t".join(specs) + "\n"
        return fmt


def _text_of(model: type, rows: list[tuple]) -> bytes:
    """The canonical text of ``rows`` (tuples of values in :func:`_columns` order).

    Each row is written by one format string: a float ``%.12g``, an int ``%d``, NULL ``~%.0s``
    (a row format per pattern of NULLs, :class:`_RowFormats`); text (JSON) is written
    beforehand and goes in as ``%s``. Then −0.0, which ``%.12g`` writes "-0", becomes "0": the
    field "-0" is that and nothing else (an exponent has two digits, a JSON string ends in a
    quote, and neither holds a tab or a newline), so the fix touches nothing else."""
    if not rows:
        return b""
    _, _, kinds, nullable = _plan(model)
    columns = list(zip(*rows))
    specs = ["%.12g" if kind == "float" else "%d" if kind == "int" else "%s" for kind in kinds]
    if "%s" in specs:
        for j, spec in enumerate(specs):
            if spec == "%s":
                columns[j] = _text_column(columns[j])
        rows = list(zip(*columns))
    try:  # a NULL is looked for in the schema's nullable columns ...
        text = _format_rows(rows, specs, [j for j in nullable if None in columns[j]], columns)
    except TypeError:  # ... and, where a row breaks the schema, in every column
        text = _format_rows(rows, specs, [j for j, values in enumerate(columns) if specs[j] != "%s" and None in values],
                            columns)
    if "-0\t" in text or "-0\n" in text:  # a field ends in "-0": only the field "-0" does
        text = _NEGATIVE_ZERO.sub("0", text)
    return text.encode()


#: The field "-0" (fields are separated by tabs, rows end with a newline).
_NEGATIVE_ZERO = re.compile(r"(?<![^\t\n])-0(?=[\t\n])")


def _format_rows(rows: list[tuple], specs: list[str], nullable: list[int], columns: list[Sequence[Any]]) -> str:
    """``rows`` written by ``specs``, NULL in columns ``nullable`` (none elsewhere)."""
    if not nullable:
        fmt = "\t".join(specs) + "\n"
        return "".join(map(fmt.__mod__, rows))
    formats = _RowFormats(specs, nullable)
    patterns = zip(*(map(is_, columns[j], itertools.repeat(None)) for j in nullable))
    return "".join(map(str.__mod__, map(formats.__getitem__, patterns), rows))


def _lines(model: type, rows: Iterable[Sequence[Any]]) -> bytes:
    """The canonical text of ``rows`` (values in :func:`_columns` order)."""
    return _text_of(model, list(map(tuple, rows)))


def shard_digest(linkages: Sequence[Mapping[str, Any]], segments: Sequence[Mapping[str, Any]],
                 dwells: Sequence[Mapping[str, Any]]) -> str:
    """The digest of one shard's rows, given as dicts keyed by column name (as ``db.rows``
    makes them; columns the digest leaves out may be absent)."""
    h = hashlib.sha256()
    for model, rows in zip(_MODELS, (linkages, segments, dwells)):
        header, names, _, _ = _plan(model)
        h.update(header)
        # the rows' values as tuples (one pass over the dicts), sorted by the key's positions
        # in them: the order of sorting the dicts by primary key (the sort is stable)
        values = list(map(itemgetter(*names), rows)) if len(names) > 1 else [(row[names[0]],) for row in rows]
        values.sort(key=_key(model))
        h.update(_text_of(model, values))
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
        owner, per_linkage = {Linkage: ("id", 1), Segment: ("linkage_id", 1),
                              Dwell: ("segment_id", SEGMENTS_PER_LINKAGE)}[model]
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
            for index, rows in by_shard.items():
                hashers[index].update(_lines(model, rows))
    return {index: h.hexdigest() for index, h in sorted(hashers.items())}
