"""The atlas schema (SQLAlchemy 2.x typed declarative models). Models only.

Units inside the database: lengths in crank lengths (crank = 1), angles in radians, points in
the four-bar's fixed frame (A0 = (0, 0), B0 = (d, 0)) unless a column says otherwise.

Every float column is checked to lie in [−1e300, 1e300] (and is NOT NULL unless it is
optional geometry). This rejects ±inf on both dialects and NaN on PostgreSQL, where 'NaN'
equals itself and sorts above every number, so ``BETWEEN`` is false for it (the server folds
the numeric bounds to float8 once). SQLite binds a NaN parameter as NULL: a NOT NULL column
refuses it, an optional one would take it as NULL — which is why ``db.writes`` refuses
non-finite values before writing. ``tests/db/test_engine.py`` tries every float column.
"""

from __future__ import annotations

from sqlalchemy import (
    BigInteger,
    CheckConstraint,
    Column,
    Float,
    ForeignKey,
    Index,
    Integer,
    PrimaryKeyConstraint,
    String,
    Table,
    Text,
    UniqueConstraint,
    func,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column
from sqlalchemy.sql.elements import ColumnElement

from synth.kinds import SEGMENT_KINDS

__all__ = [
    "SCHEMA_VERSION",
    "APPLICATION",
    "Base",
    "Meta",
    "Build",
    "Shard",
    "Linkage",
    "Segment",
    "Dwell",
    "dwell_staging",
    "stored_dwell_angle",
]

#: Bumped whenever a table or column changes meaning; an atlas of a newer version is refused,
#: an older one must be rebuilt. 2: deterministic 64-bit row ids, per-level fitted geometry
#: in ``dwell`` (with copies of the linkage's constraint figures for the query's covering
#: index), the builder lock columns and the stored content digest of ``build``. 3: only what
#: is read — the segment's osculating geometry, its transmission range, the double line's
#: intersection, the scan ray and the dwell's deviation from its fit are no longer stored. 4: the
#: ``dwell`` table is the query's index (one row per segment and level, clustered on the walk's
#: key, ``WITHOUT ROWID`` on SQLite), a double line's second stretch in the same row, a line as
#: (direction, offset), no stored ``phi_end`` or tolerance, the linkage's constraint copies as
#: conservative integers, no index that only a rare path uses (issue #16: 19 972 → ~7 300 bytes
#: per linkage on ``standard``); each shard row holds its shard's digest, and the content digest
#: is defined over them (``db.digest``); shards append their dwell rows to ``dwell_staging``,
#: moved into ``dwell`` in key order when the build completes. 5: arc rows are keyed by their dwell
#: key (the stored dwell × the path's excursion from the circle^¼, :mod:`synth.segment_search.dwell_key`), which
#: orders them by the RRR dwell they predict; their dwell angle moves to a column of its own. 6:
#: the shard digest (``shard.digest``, and so ``build.content_digest``) is defined over binary
#: records of the rows, floats rounded to 40 bits, instead of their ``%.12g`` text (``db.digest``):
#: the same rows, another hash — an atlas of schema 5 would fail ``--verify``; ``dwell_staging``
#: has no index and no foreign key (its keys are checked on the way in).
SCHEMA_VERSION = 6
#: Written to the meta table so that a foreign SQLite file is recognised as such.
APPLICATION = "dwell-atlas"

_FINITE = "BETWEEN -1e300 AND 1e300"

#: Row ids are assigned by the builder, deterministically from the sweep (see
#: ``db.rows``), so they are the same whatever the worker count or resume history and
#: can name a segment across machines. 64-bit everywhere; on SQLite an INTEGER PRIMARY KEY
#: (the rowid itself, also 64-bit).
RowId = BigInteger().with_variant(Integer, "sqlite")


def _finite_checks(table: str, *columns: str) -> tuple[CheckConstraint, ...]:
    return tuple(CheckConstraint(f"{c} {_FINITE}", name=f"ck_{table}_{c}_finite") for c in columns)


def _finite_or_null_checks(table: str, *columns: str) -> tuple[CheckConstraint, ...]:
    # optional geometry (a line has no radius): NULL allowed, but never NaN/inf
    return tuple(CheckConstraint(f"{c} IS NULL OR {c} {_FINITE}", name=f"ck_{table}_{c}_finite") for c in columns)


def _dwell_checks(table: str) -> tuple[CheckConstraint, ...]:
    """The row checks of ``dwell`` and of its staging table (the same rows, before and after)."""
    return (
        CheckConstraint(f"kind BETWEEN 0 AND {len(SEGMENT_KINDS) - 1}", name=f"ck_{table}_kind"),
        CheckConstraint("dwell_key > 0", name=f"ck_{table}_positive"),
        CheckConstraint("dwell_angle IS NULL OR dwell_angle > 0", name=f"ck_{table}_dwell_angle_positive"),
        *_finite_checks(table, "dwell_key", "phi_start", "x"),
        *_finite_or_null_checks(
            table, "dwell_angle", "radius", "y", "direction", "dwell_angle2", "phi_start2", "x2", "direction2"
        ),
    )


class Base(DeclarativeBase):
    pass


class Meta(Base):
    """Key/value facts about the database itself: ``application``, ``schema_version``."""

    __tablename__ = "meta"
    key: Mapped[str] = mapped_column(String(64), primary_key=True)
    value: Mapped[str] = mapped_column(Text)


class Build(Base):
    """One atlas build: its full sweep spec (JSON), code and schema version, status.

    The ``lock_*`` columns hold the builder lock (see ``db.writes``): the one process allowed
    to write this build's shards, named by a random token, its pid and host, and a heartbeat
    (Unix time, seconds) refreshed at every shard commit. All NULL when no builder holds it.
    """

    __tablename__ = "build"
    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    spec_json: Mapped[str] = mapped_column(Text)
    spec_digest: Mapped[str] = mapped_column(String(64), unique=True)
    code_version: Mapped[str] = mapped_column(String(64))
    schema_version: Mapped[int] = mapped_column(Integer)
    status: Mapped[str] = mapped_column(String(16))  # building | complete
    n_shards: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[str] = mapped_column(String(32))
    finished_at: Mapped[str | None] = mapped_column(String(32), nullable=True)
    #: ``db.digest.content_digest`` of the build, stored when it completes (``info`` of a big
    #: atlas would otherwise re-read every row); NULL while building.
    content_digest: Mapped[str | None] = mapped_column(String(64), nullable=True)
    lock_token: Mapped[str | None] = mapped_column(String(32), nullable=True)
    lock_pid: Mapped[int | None] = mapped_column(Integer, nullable=True)
    lock_host: Mapped[str | None] = mapped_column(String(255), nullable=True)
    lock_heartbeat: Mapped[float | None] = mapped_column(Float, nullable=True)  #: Unix time (s)
    __table_args__ = (
        CheckConstraint("status IN ('building', 'complete')", name="ck_build_status"),
        *_finite_or_null_checks("build", "lock_heartbeat"),
    )


class Shard(Base):
    """A shard written in full (its linkages, segments and dwells commit in the same
    transaction), with the digest of its rows.

    Resume = build the shards that have no row here.
    """

    __tablename__ = "shard"
    build_id: Mapped[int] = mapped_column(ForeignKey("build.id"), primary_key=True)
    shard_index: Mapped[int] = mapped_column(Integer, primary_key=True)
    n_linkages: Mapped[int] = mapped_column(Integer)
    n_segments: Mapped[int] = mapped_column(Integer)
    skipped_json: Mapped[str] = mapped_column(Text)  #: {"reason": count} of degenerate cases
    seconds: Mapped[float] = mapped_column(Float)
    #: ``db.digest.shard_digest`` of the shard's rows, computed where they were computed; the
    #: build's content digest combines these (``db.digest.stored_digest``)
    digest: Mapped[str] = mapped_column(String(64))
    __table_args__ = _finite_checks("shard", "seconds")


class Linkage(Base):
    """A crank-normalised four-bar (a = 1) on one assembly branch."""

    __tablename__ = "linkage"
    id: Mapped[int] = mapped_column(RowId, primary_key=True, autoincrement=False)
    build_id: Mapped[int] = mapped_column(ForeignKey("build.id"))
    shard_index: Mapped[int] = mapped_column(Integer)
    sweep_index: Mapped[int] = mapped_column(Integer)  #: position in the sweep, for canonical order
    b: Mapped[float] = mapped_column(Float)
    c: Mapped[float] = mapped_column(Float)
    d: Mapped[float] = mapped_column(Float)
    branch: Mapped[int] = mapped_column(Integer)
    grashof: Mapped[int] = mapped_column(Integer)  #: kinematics.GrashofType value
    transmission_min: Mapped[float] = mapped_column(Float)  #: rad, over the turn, folded to [0, π/2]
    transmission_max: Mapped[float] = mapped_column(Float)
    __table_args__ = (
        UniqueConstraint("build_id", "sweep_index", "branch", name="uq_linkage_sweep"),
        CheckConstraint("branch IN (1, -1)", name="ck_linkage_branch"),
        *_finite_checks("linkage", "b", "c", "d", "transmission_min", "transmission_max"),
        # resume deletes a half-written shard's rows by (build, shard)
        Index("ix_linkage_build_shard", "build_id", "shard_index"),
    )


class Segment(Base):
    """A nearly straight (``line``, ``double_line``) or nearly circular (``arc``) stretch of a
    coupler curve, found from the curvature invariants at crank angle ``phi_gen`` (a double
    line's second stretch at ``phi_gen2``), traced by the coupler point (``u``, ``v``). Its
    lines or circle, fitted per tolerance level, are in its ``dwell`` rows: that is what the
    query reads (the osculating geometry at ``phi_gen`` is not stored).

    No index on ``linkage_id``: only resume's clean-up and the digest of one build of several
    read by it, and both scan anyway (a segment id is its linkage's id · ``SEGMENTS_PER_LINKAGE``
    plus an ordinal, ``db.rows``).
    """

    __tablename__ = "segment"
    id: Mapped[int] = mapped_column(RowId, primary_key=True, autoincrement=False)
    linkage_id: Mapped[int] = mapped_column(RowId, ForeignKey("linkage.id"))
    kind: Mapped[str] = mapped_column(String(12))
    phi_gen: Mapped[float] = mapped_column(Float)  #: generating crank angle (rad)
    phi_gen2: Mapped[float | None] = mapped_column(Float, nullable=True)  #: double Ball point: second angle
    u: Mapped[float] = mapped_column(Float)  #: coupler point, coupler frame
    v: Mapped[float] = mapped_column(Float)
    __table_args__ = (
        CheckConstraint(f"kind IN ({', '.join(repr(k.value) for k in SEGMENT_KINDS)})", name="ck_segment_kind"),
        *_finite_checks("segment", "phi_gen", "u", "v"),
        *_finite_or_null_checks("segment", "phi_gen2"),
    )


class Dwell(Base):
    """A segment's dwell interval and fitted geometry at one tolerance level: what the query walks.

    One row per (segment, level). The interval [``phi_start``, ``phi_start`` + its dwell angle]
    (rad, counter-clockwise; the angle as :func:`stored_dwell_angle` reads it) is the largest
    crank interval around the generating angle on which the coupler point stays within that level's tolerance (the build's sweep spec, by
    ``level``) of the level's own minimum-zone geometry: a circle (centre ``x``, ``y``,
    ``radius``) or a line (``direction`` δ, rad, and signed ``x`` = its distance from A0: the
    line is {x·i·e^{iδ} + t·e^{iδ}}; ``y`` and ``radius`` NULL). A double line's second stretch
    is in the ``*2`` columns of the same row (a double line is stored at a level only when
    both stretches have a dwell there: the query needs both).

    The table **is** the query's index: the primary key (``kind`` as the
    :data:`synth.kinds.SEGMENT_KINDS` code, ``level``, ``dwell_key``, ``segment_id``) is the
    walk's order. A line's (and a double line's) ``dwell_key`` is its dwell angle and its
    ``dwell_angle`` is NULL (no second copy); an arc's ``dwell_key`` is its dwell angle ×
    ``excursion``^¼ (:func:`synth.segment_search.dwell_key.arc_dwell_key`), the order of the RRR dwells it
    predicts, and ``dwell_angle`` holds the angle itself. On SQLite (``WITHOUT ROWID``) the row
    lives in that b-tree, so a walked row costs no second look-up. The linkage's constraint figures ride along for the walk's
    filters as conservative integers: the smallest folded transmission angle floored to
    0.01° and the longest of b, c, d ceiled to 0.001 crank. They can only let through a
    linkage that the exact figures then reject, never hold back one that meets a request.
    """

    __tablename__ = "dwell"
    kind: Mapped[int] = mapped_column(Integer)  #: synth.kinds.SegmentKind.code
    level: Mapped[int] = mapped_column(Integer)
    dwell_key: Mapped[float] = mapped_column(Float)  #: line: dwell angle (rad); arc: rad · crank^¼
    segment_id: Mapped[int] = mapped_column(RowId, ForeignKey("segment.id"))
    dwell_angle: Mapped[float | None] = mapped_column(Float, nullable=True)  #: arc: rad (a line's is its key)
    transmission_min_cdeg: Mapped[int] = mapped_column(Integer)  #: floor(min folded transmission, ° · 100)
    longest_link_milli: Mapped[int] = mapped_column(Integer)  #: ceil(max(b, c, d) · 1000), crank = 1000
    radius: Mapped[float | None] = mapped_column(Float, nullable=True)  #: arc: circle radius
    phi_start: Mapped[float] = mapped_column(Float)  #: rad
    x: Mapped[float] = mapped_column(Float)  #: arc: centre x; line: signed distance of the line from A0
    y: Mapped[float | None] = mapped_column(Float, nullable=True)  #: arc: centre y
    direction: Mapped[float | None] = mapped_column(Float, nullable=True)  #: line: direction δ (rad)
    # a double line's second stretch, at the same level
    dwell_angle2: Mapped[float | None] = mapped_column(Float, nullable=True)
    phi_start2: Mapped[float | None] = mapped_column(Float, nullable=True)
    x2: Mapped[float | None] = mapped_column(Float, nullable=True)
    direction2: Mapped[float | None] = mapped_column(Float, nullable=True)
    __table_args__ = (
        PrimaryKeyConstraint("kind", "level", "dwell_key", "segment_id", name="pk_dwell"),
        *_dwell_checks("dwell"),
        {"sqlite_with_rowid": False},
    )


#: Where a build's shards append their dwell rows: the columns and row checks of ``dwell`` and
#: nothing else — no clustered key, no index, no foreign key: a shard's rows go to the end of the
#: table, a few pages per shard. Their keys are checked on the way in, for every shard and
#: every database, by the packing's check (``db.packed.checked_rows``: each row's segment is one
#: of its shard's, no (segment, level) twice; a segment id derives from its linkage's, which is
#: its shard's alone), which made the unique (segment, level) index and the foreign key — a
#: third of the single writer's ingest — repeat work. The build's last transaction moves the
#: rows into ``dwell`` in its key order (``db.writes.finish_build``), so the clustered table is
#: written once, sequentially, instead of at a random place per row, which rewrote pages all
#: over it at every shard (the write-ahead log of a ``standard`` build took ~10 GB of writes).
#: Empty in a complete atlas; digested and counted with ``dwell``; a build's clean-up deletes its
#: rows before their segments (``db.writes._delete_rows``).
dwell_staging = Table(
    "dwell_staging",
    Base.metadata,
    *(Column(c.name, c.type, nullable=c.nullable) for c in Dwell.__table__.columns),
    *_dwell_checks("dwell_staging"),
)


def stored_dwell_angle(table) -> ColumnElement[float]:
    """A dwell row's dwell angle (rad) as SQL, for ``dwell`` or its staging table: an arc's own
    column, a line's key (see :class:`Dwell`)."""
    t = getattr(table, "__table__", table)
    return func.coalesce(t.c.dwell_angle, t.c.dwell_key)
