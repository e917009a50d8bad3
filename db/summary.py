"""What an atlas holds (``dwell atlas info``): counts, dwell-angle coverage, build, digest.

Angles are reported in degrees (the user interface), lengths in crank lengths. Every kind of
segment (``line``, ``arc``, ``double_line``) and every tolerance level of the build's sweep is
always present, with zero counts when empty, so that consumers never have to test for keys.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from sqlalchemy import Engine, bindparam, case, func, select, text, union_all

from db.digest import combine, content_digest, shard_digests
from db.engine import display_target, structure_check
from db.schema import Base, Build, Dwell, Linkage, Segment, Shard, dwell_staging, stored_dwell_angle
from db.spec import stored_spec, tolerances
from synth.kinds import SEGMENT_KINDS

__all__ = [
    "BIN_DEG",
    "AtlasSummary",
    "Verification",
    "atlas_summary",
    "format_summary",
    "quick_check",
    "row_counts",
    "verify_atlas",
]

#: Segment kinds, in report order (the schema's CHECK constraint lists the same).
#: Width of a dwell-angle histogram bin (degrees); bins cover [0°, 360°], the last one closed.
BIN_DEG = 10.0
_N_BINS = int(round(360.0 / BIN_DEG))


@dataclass(frozen=True, slots=True)
class AtlasSummary:
    """Counts and coverage of one atlas (see :meth:`to_dict` for the JSON layout)."""

    linkages: int
    segments: dict[str, int]
    dwells: dict[str, int]
    #: kind → list of {level, tolerance, counts[_N_BINS], max_dwell_deg}
    histogram: dict[str, list[dict[str, Any]]]
    skipped: dict[str, int]
    build: dict[str, Any] | None
    builds: int
    content_digest: str
    #: "stored" (the complete build's digest as written when it completed, not rechecked:
    #: ``--verify`` recomputes it) or "recomputed" (from the rows, now)
    digest_source: str = "recomputed"
    #: bytes the atlas takes in its database (SQLite: the file's pages; PostgreSQL: the tables
    #: with their indexes and TOAST); None where the dialect does not say
    storage_bytes: int | None = None

    @property
    def bytes_per_linkage(self) -> float | None:
        if self.storage_bytes is None or not self.linkages:
            return None
        return self.storage_bytes / self.linkages

    def to_dict(self) -> dict[str, Any]:
        """The ``--json`` document: ``linkages``, ``segments`` (kind → count), ``dwells``,
        ``dwell_histogram`` ({bin_deg, edges_deg, kinds: kind → per level}), ``skipped``
        (reason → count), ``build`` (spec, status, versions, shards_done, n_shards, …; null
        when the atlas has no build), ``builds``, ``content_digest``, ``storage_bytes`` and
        ``bytes_per_linkage`` (null where the database does not say)."""
        return {
            "linkages": self.linkages,
            "segments": dict(self.segments),
            "dwells": dict(self.dwells),
            "dwell_histogram": {
                "bin_deg": BIN_DEG,
                "edges_deg": [BIN_DEG * i for i in range(_N_BINS + 1)],
                "kinds": self.histogram,
            },
            "skipped": dict(self.skipped),
            "build": self.build,
            "builds": self.builds,
            "content_digest": self.content_digest,
            "content_digest_source": self.digest_source,
            "storage_bytes": self.storage_bytes,
            "bytes_per_linkage": None if self.bytes_per_linkage is None else round(self.bytes_per_linkage, 1),
        }


def _dwell_rows():
    """Every dwell row's kind, level, angle and segment: the ``dwell`` table's and, while a
    build is in progress, the staging table's (empty in a complete atlas)."""
    return union_all(
        *(
            select(t.c.kind, t.c.level, stored_dwell_angle(t).label("dwell_angle"), t.c.segment_id)
            for t in (Dwell.__table__, dwell_staging)
        )
    ).subquery("dwell_rows")


def _histogram_rows(engine: Engine) -> dict[tuple[str, int], tuple[list[int], float]]:
    """(kind, level) → (counts per bin, max dwell in rad), one portable scan.

    Bins are counted with ``SUM(CASE …)`` rather than ``FLOOR``/``CAST`` arithmetic, which
    differs between SQLite (truncation) and PostgreSQL (rounding).
    """
    edges = [math.radians(BIN_DEG * i) for i in range(_N_BINS + 1)]
    rows = _dwell_rows()
    bins = []
    for i in range(_N_BINS):
        upper = rows.c.dwell_angle <= edges[i + 1] if i == _N_BINS - 1 else rows.c.dwell_angle < edges[i + 1]
        bins.append(func.sum(case(((rows.c.dwell_angle >= edges[i]) & upper, 1), else_=0)))
    stmt = select(rows.c.kind, rows.c.level, func.max(rows.c.dwell_angle), *bins).group_by(rows.c.kind, rows.c.level)
    out = {}
    with engine.connect() as conn:
        for kind, level, top, *counts in conn.execute(stmt):
            out[(SEGMENT_KINDS[int(kind)].value, int(level))] = ([int(c or 0) for c in counts], float(top))
    return out


def _holds_other_builds(engine: Engine, build_id: int) -> bool:
    """Whether the atlas holds linkages (and so segments and dwell rows) of another build than
    ``build_id`` — never after a build started (an atlas holds one build), but the counts do
    not rely on it."""
    with engine.connect() as conn:
        return conn.execute(select(Linkage.id).where(Linkage.build_id != build_id).limit(1)).first() is not None


def row_counts(engine: Engine, build_id: int | None = None) -> tuple[int, dict[str, int], int]:
    """(linkages, segments per kind — all kinds present —, dwells) of one build or all."""
    links = select(Linkage.id)
    if build_id is not None:
        links = links.where(Linkage.build_id == build_id)
    seg_q = select(Segment.kind, func.count()).group_by(Segment.kind)
    rows = _dwell_rows()
    dwell_q = select(func.count()).select_from(rows)
    link_q = select(func.count()).select_from(Linkage)
    if build_id is not None and not _holds_other_builds(engine, build_id):
        build_id = None  # every row is the build's: the plain counts (the filtered ones read every dwell row twice)
    if build_id is not None:
        link_q = link_q.where(Linkage.build_id == build_id)
        seg_q = seg_q.where(Segment.linkage_id.in_(links))
        dwell_q = dwell_q.where(rows.c.segment_id.in_(select(Segment.id).where(Segment.linkage_id.in_(links))))
    with engine.connect() as conn:
        segments = dict.fromkeys(SEGMENT_KINDS, 0)
        segments.update({k: int(n) for k, n in conn.execute(seg_q)})
        return int(conn.execute(link_q).scalar_one()), segments, int(conn.execute(dwell_q).scalar_one())


def atlas_summary(engine: Engine) -> AtlasSummary:
    """Summarise the atlas behind ``engine`` (read only)."""
    with engine.connect() as conn:
        linkages = conn.execute(select(func.count()).select_from(Linkage)).scalar_one()
        segments = dict.fromkeys(SEGMENT_KINDS, 0)
        segments.update({k: int(n) for k, n in conn.execute(select(Segment.kind, func.count()).group_by(Segment.kind))})
        dwells = dict.fromkeys(SEGMENT_KINDS, 0)
        rows = _dwell_rows()
        dwells.update(
            {
                SEGMENT_KINDS[int(k)].value: int(n)
                for k, n in conn.execute(select(rows.c.kind, func.count()).group_by(rows.c.kind))
            }
        )
        builds = conn.execute(select(Build).order_by(Build.id)).all()
        skipped: dict[str, int] = {}
        for (text,) in conn.execute(select(Shard.skipped_json)):
            for reason, n in json.loads(text).items():
                skipped[reason] = skipped.get(reason, 0) + int(n)
        shard_stats = {
            bid: (int(n), float(sec or 0.0))
            for bid, n, sec in conn.execute(
                select(Shard.build_id, func.count(), func.sum(Shard.seconds)).group_by(Shard.build_id)
            )
        }

    build = None
    levels_tol: list[float] = []
    if builds:
        row = builds[-1]
        spec = stored_spec(row.spec_json)
        levels_tol = tolerances(spec)
        done, seconds = shard_stats.get(row.id, (0, 0.0))
        build = {
            "id": row.id,
            "spec": spec,
            "spec_digest": row.spec_digest,
            "status": row.status,
            "code_version": row.code_version,
            "schema_version": row.schema_version,
            "shards_done": done,
            "n_shards": row.n_shards,
            "compute_seconds": round(seconds, 3),
            "created_at": row.created_at,
            "finished_at": row.finished_at,
            "builder": (
                {"pid": row.lock_pid, "host": row.lock_host, "heartbeat": row.lock_heartbeat}
                if row.lock_token is not None
                else None
            ),
        }

    found = _histogram_rows(engine)
    levels = sorted(set(range(len(levels_tol))) | {lvl for _, lvl in found})
    histogram: dict[str, list[dict[str, Any]]] = {}
    for kind in SEGMENT_KINDS:
        per_level = []
        for lvl in levels:
            counts, top = found.get((kind, lvl), ([0] * _N_BINS, None))
            per_level.append(
                {
                    "level": lvl,
                    "tolerance": levels_tol[lvl] if lvl < len(levels_tol) else None,
                    "counts": counts,
                    "max_dwell_deg": None if top is None else math.degrees(top),
                }
            )
        histogram[kind] = per_level

    # a complete build stores its digest (re-reading every row of a big atlas takes minutes);
    # a build in progress, or an atlas holding more than one build, is digested now
    stored = builds[0].content_digest if len(builds) == 1 and builds[0].status == "complete" else None
    return AtlasSummary(
        linkages=int(linkages),
        segments=segments,
        dwells=dwells,
        histogram=histogram,
        skipped=dict(sorted(skipped.items())),
        build=build,
        builds=len(builds),
        content_digest=stored or content_digest(engine),
        digest_source="stored" if stored else "recomputed",
        storage_bytes=storage_bytes(engine),
    )


def storage_bytes(engine: Engine) -> int | None:
    """Bytes the atlas takes: SQLite's pages (page_count × page_size, the file without a
    ``-wal``), PostgreSQL's tables with their indexes (``pg_total_relation_size``); None for
    another dialect."""
    with engine.connect() as conn:
        if engine.dialect.name == "sqlite":
            pages = conn.exec_driver_sql("PRAGMA page_count").scalar_one()
            return int(pages) * int(conn.exec_driver_sql("PRAGMA page_size").scalar_one())
        if engine.dialect.name == "postgresql":
            tables = [t.name for t in Base.metadata.sorted_tables]
            sizes = conn.execute(
                text(
                    "SELECT sum(pg_total_relation_size(c.oid)) FROM pg_class c JOIN pg_namespace n ON n.oid = c.relnamespace "
                    "WHERE n.nspname = current_schema() AND c.relkind = 'r' AND c.relname IN :names"
                ).bindparams(bindparam("names", expanding=True)),
                {"names": tables},
            ).scalar_one()
            return None if sizes is None else int(sizes)
    return None


def format_summary(summary: AtlasSummary, target: str) -> str:
    """A readable multi-line text of ``summary`` (no trailing newline)."""
    lines = [f"atlas {display_target(target)}"]
    b = summary.build
    if b is None:
        lines.append("build: none (an empty atlas)")
    else:
        spec = b["spec"]
        lines.append(
            f"build {b['id']}: {b['status']}, {b['shards_done']}/{b['n_shards']} shards, "
            f"sweep {spec.get('name', '?')} (digest {b['spec_digest'][:12]}), "
            f"dwell-atlas {b['code_version']}, schema {b['schema_version']}"
        )
        lines.append(
            "sweep: "
            + ", ".join(
                f"{k}={spec[k]}"
                for k in (
                    "samples",
                    "seed",
                    "b",
                    "c",
                    "d",
                    "crank_rockers_only",
                    "branches",
                    "crank_step_deg",
                    "rays",
                    "tolerances",
                    "min_dwell_deg",
                    "shard_size",
                )
                if k in spec
            )
        )
        if b["builder"] is not None:
            lines.append(f"builder: pid {b['builder']['pid']} on {b['builder']['host']}")
    if summary.builds > 1:
        lines.append(f"note: {summary.builds} builds in this atlas; the last one is shown, counts cover all")
    lines.append(f"linkages: {summary.linkages}")
    if summary.storage_bytes is not None:
        per = "" if summary.bytes_per_linkage is None else f" ({summary.bytes_per_linkage / 1024:.1f} KiB per linkage)"
        lines.append(f"storage: {summary.storage_bytes / 2**20:.1f} MiB{per}")
    lines.append("segments: " + ", ".join(f"{k} {n}" for k, n in summary.segments.items()))
    lines.append("dwells: " + ", ".join(f"{k} {n}" for k, n in summary.dwells.items()))
    lines.append(f"dwell angles (dwell intervals per {BIN_DEG:g}° bin, by tolerance):")
    for kind, levels in summary.histogram.items():
        for lvl in levels:
            tol = "?" if lvl["tolerance"] is None else f"{lvl['tolerance']:g}"
            bins = [f"{BIN_DEG * i:g}-{BIN_DEG * (i + 1):g}°:{n}" for i, n in enumerate(lvl["counts"]) if n]
            top = "" if lvl["max_dwell_deg"] is None else f" (max {lvl['max_dwell_deg']:.1f}°)"
            lines.append(f"  {kind:<11} tol {tol:<7} {' '.join(bins) if bins else '-'}{top}")
    if summary.skipped:
        lines.append("skipped: " + "; ".join(f"{reason}: {n}" for reason, n in summary.skipped.items()))
    else:
        lines.append("skipped: none")
    if summary.digest_source == "stored":  # not checked here: only --verify reads every row again
        lines.append(f"content digest (stored, unchecked; --verify recomputes it): {summary.content_digest}")
    else:
        lines.append(f"content digest (recomputed from the rows): {summary.content_digest}")
    return "\n".join(lines)


@dataclass(frozen=True, slots=True)
class Verification:
    """What ``dwell atlas info --verify`` checked: SQLite's ``PRAGMA integrity_check`` (None on
    other databases), rows naming a missing parent, and each complete build's stored content
    digest against one recomputed from its rows. ``problems`` is empty when all agree."""

    integrity: str | None
    orphans: dict[str, int]
    digests: dict[int, tuple[str | None, str]]  #: build id → (stored, recomputed)
    problems: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        return {
            "ok": not self.problems,
            "integrity_check": self.integrity,
            "orphans": dict(self.orphans),
            "digests": {str(k): {"stored": s, "recomputed": r} for k, (s, r) in self.digests.items()},
            "problems": list(self.problems),
        }

    def line(self) -> str:
        """One line for people (``ok`` or the problems)."""
        checks = ([f"integrity check {self.integrity}"] if self.integrity is not None else []) + [
            "no orphaned rows" if not any(self.orphans.values()) else "orphaned rows",
            f"content digest of {len(self.digests)} build(s) recomputed",
        ]
        return "verify: " + ("ok (" + ", ".join(checks) + ")" if not self.problems else "; ".join(self.problems))


#: child table → (its column naming the parent, parent model): the rows ``--verify`` counts.
_PARENTS = (
    (Dwell, Dwell.segment_id, Segment),
    (Segment, Segment.linkage_id, Linkage),
    (Linkage, Linkage.build_id, Build),
    (Shard, Shard.build_id, Build),
)


def quick_check(engine: Engine) -> str | None:
    """SQLite's whole ``PRAGMA quick_check`` (:func:`db.engine.structure_check`): None when it
    passes or the database is not SQLite, else its first complaint. About 0.04 s on the demo
    atlas (26 MB), 4 % of ``atlas info``; 3–6 s on ``standard`` (200 MB), where ``info``
    reads every row anyway."""
    return structure_check(engine, whole=True)


def _list(indices: list[int]) -> str:
    return ", ".join(map(str, indices[:10])) + (f" and {len(indices) - 10} more" if len(indices) > 10 else "")


def _shard_problems(conn: Any, build_id: int, status: str, n_shards: int, again: dict[int, str]) -> list[str]:
    """What is wrong with build ``build_id``'s shards: its status, shard rows out of range or
    missing (a complete build has one per shard), rows of shards without a shard row, and
    shards whose rows no longer give the digest stored in their shard row (``shard.digest``;
    ``again``: each shard's digest recomputed from its rows, :func:`db.digest.shard_digests`)."""
    problems = []
    if status not in ("building", "complete"):
        problems.append(f"build {build_id} has the unknown status {status!r}")
    kept = {
        int(i): d for i, d in conn.execute(select(Shard.shard_index, Shard.digest).where(Shard.build_id == build_id))
    }
    outside = sorted(i for i in kept if not 0 <= i < n_shards)
    if outside:
        problems.append(f"build {build_id} has shard rows outside its {n_shards} shards: {_list(outside)}")
    if status == "complete":
        missing = sorted(set(range(n_shards)) - set(kept))
        if missing:
            problems.append(f"build {build_id} is complete but has no shard row for shard(s) {_list(missing)}")
    unrecorded = sorted(set(again) - set(kept))
    if unrecorded:
        problems.append(f"build {build_id} holds rows of shard(s) {_list(unrecorded)}, which have no shard row")
    changed = sorted(i for i, d in kept.items() if again.get(i) != d)
    if changed:
        problems.append(
            f"build {build_id}: the rows of shard(s) {_list(changed)} do not give the digest stored in their shard row"
        )
    return problems


def verify_atlas(engine: Engine) -> Verification:
    """Check the atlas behind ``engine`` in full (reads every row: seconds on a big atlas).

    Database errors (a page that cannot be read) propagate; the caller names the atlas."""
    problems: list[str] = []
    integrity = None
    with engine.connect() as conn:
        if conn.dialect.name == "sqlite":
            rows = [r[0] for r in conn.exec_driver_sql("PRAGMA integrity_check(20)")]
            integrity = "ok" if rows == ["ok"] else f"failed ({len(rows)} problem(s), first: {rows[0]})"
            if rows != ["ok"]:
                problems.append(f"SQLite integrity check {integrity}")
        orphans = {}
        for child, column, parent in _PARENTS:
            n = conn.execute(
                select(func.count()).select_from(child).where(column.not_in(select(parent.id)))
            ).scalar_one()
            orphans[child.__tablename__] = int(n)
            if n:
                problems.append(f"{n} {child.__tablename__} row(s) name a {parent.__tablename__} that does not exist")
        digests = {}
        builds = conn.execute(select(Build.id, Build.status, Build.content_digest, Build.n_shards)).all()
        for build_id, status, stored, n_shards in builds:
            per_shard = shard_digests(conn, build_id)  # one pass over the build's rows
            problems += _shard_problems(conn, int(build_id), status, int(n_shards or 0), per_shard)
            if status != "complete":
                continue  # a build in progress has no stored content digest yet
            again = combine(per_shard.items())
            digests[int(build_id)] = (stored, again)
            if stored != again:
                problems.append(
                    f"build {build_id}'s rows do not give its stored content digest "
                    f"({(stored or 'none')[:12]}…, recomputed {again[:12]}…)"
                )
    return Verification(integrity, orphans, digests, tuple(problems))
