"""The only place that creates a database engine: URL handling, SQLite pragmas, schema checks.

An atlas is refused — with one clear :class:`AtlasError` and the file untouched — when it is
not an SQLite file, is an SQLite file of another application, has a newer schema version
than this code, or does not exist (unless ``create=True``).
"""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import Engine, create_engine, event, inspect, select
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError, DatabaseError, OperationalError
from sqlalchemy.orm import Session

from db.schema import APPLICATION, SCHEMA_VERSION, Base, Meta

__all__ = ["AtlasError", "database_url", "open_atlas", "sqlite_path"]

_SQLITE_MAGIC = b"SQLite format 3\x00"


class AtlasError(Exception):
    """An atlas database that cannot be used as asked (message names the file and problem)."""


def database_url(target: str) -> str:
    """A SQLAlchemy URL from ``target``: a URL as is, anything else a SQLite file path."""
    if "://" in target:
        return target
    return f"sqlite:///{Path(target).expanduser().resolve()}"


def sqlite_path(target: str) -> Path | None:
    """The file behind ``target`` if it names an SQLite file (None for other URLs, memory)."""
    try:
        return _sqlite_path(database_url(target))
    except ArgumentError:
        return None


def _sqlite_path(url: str) -> Path | None:
    u = make_url(url)
    if u.get_backend_name() != "sqlite" or not u.database or u.database == ":memory:":
        return None
    return Path(u.database)


def open_atlas(target: str, *, create: bool = False, readonly: bool = False) -> Engine:
    """Open (or with ``create`` make) the atlas at ``target`` (path or SQLAlchemy URL).

    SQLite runs in WAL mode (readers are never blocked by the builder) with foreign keys on
    and a busy timeout. ``readonly`` opens SQLite files read-only (``mode=ro``).
    """
    try:
        url = database_url(target)
        make_url(url)
    except ArgumentError as exc:
        raise AtlasError(f"not a database path or URL: {target!r} ({exc})") from None
    path = _sqlite_path(url)
    if path is not None:
        existing = _check_sqlite_file(path, target, create=create)
        read_only_url = f"sqlite:///file:{path}?mode=ro&uri=true"
        if existing:
            # Look before touching: even setting WAL mode rewrites the file header, so a file
            # that turns out not to be an atlas must only ever be read.
            _checked(_engine(read_only_url, target), target, create=False).dispose()
        if readonly:
            url = read_only_url
    engine = _engine(url, target)
    if engine.dialect.name == "sqlite":
        _sqlite_pragmas(engine, wal=not readonly)
    return _checked(engine, target, create=create and not readonly)


def _engine(url: str, target: str) -> Engine:
    try:
        return create_engine(url)
    except (ArgumentError, ModuleNotFoundError, ImportError) as exc:
        raise AtlasError(f"cannot open {target!r}: {exc}") from None


def _checked(engine: Engine, target: str, *, create: bool) -> Engine:
    """``engine`` after the schema check (or creation); disposed and refused on failure."""
    try:
        _check_or_create_schema(engine, target, create=create)
    except (OperationalError, DatabaseError) as exc:
        engine.dispose()
        first = str(exc.orig if hasattr(exc, "orig") else exc).splitlines()[0]
        raise AtlasError(f"cannot use {target!r} as an atlas: {first}") from None
    except AtlasError:
        engine.dispose()
        raise
    return engine


def _check_sqlite_file(path: Path, target: str, *, create: bool) -> bool:
    """Refuse paths that cannot be an atlas; True if a non-empty file is already there."""
    if path.exists():
        if path.is_dir():
            raise AtlasError(f"{target!r} is a folder, not an atlas file")
        try:
            with path.open("rb") as fh:
                head = fh.read(len(_SQLITE_MAGIC))
        except OSError as exc:
            raise AtlasError(f"cannot read {target!r}: {exc.strerror}") from None
        if head != _SQLITE_MAGIC and not (create and head == b""):
            raise AtlasError(f"{target!r} is not an SQLite database (it may be corrupt or another kind of file)")
        return head != b""
    if not create:
        raise AtlasError(f"no atlas at {target!r} (build one with: dwell atlas build --db {target})")
    if not path.parent.is_dir():
        raise AtlasError(f"cannot create {target!r}: folder {str(path.parent)!r} does not exist")
    return False


def _sqlite_pragmas(engine: Engine, *, wal: bool) -> None:
    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_conn, _record):  # noqa: ANN001 - DBAPI connection
        cur = dbapi_conn.cursor()
        cur.execute("PRAGMA foreign_keys=ON")
        cur.execute("PRAGMA busy_timeout=30000")
        if wal:
            cur.execute("PRAGMA journal_mode=WAL")
            cur.execute("PRAGMA synchronous=NORMAL")
        cur.close()


def _check_or_create_schema(engine: Engine, target: str, *, create: bool) -> None:
    tables = set(inspect(engine).get_table_names())
    if not tables:
        if not create:
            raise AtlasError(f"{target!r} is an empty database, not an atlas")
        Base.metadata.create_all(engine)
        with Session(engine) as s, s.begin():
            s.add_all([Meta(key="application", value=APPLICATION), Meta(key="schema_version", value=str(SCHEMA_VERSION))])
        return
    if "meta" not in tables:
        raise AtlasError(f"{target!r} is a database of another application (no Dwell atlas meta table)")
    with Session(engine) as s:
        meta = {key: value for key, value in s.execute(select(Meta.key, Meta.value))}
    if meta.get("application") != APPLICATION:
        raise AtlasError(f"{target!r} is a database of another application (application={meta.get('application')!r})")
    try:
        version = int(meta.get("schema_version", ""))
    except ValueError:
        raise AtlasError(f"{target!r} has an unreadable schema version {meta.get('schema_version')!r}") from None
    if version > SCHEMA_VERSION:
        raise AtlasError(
            f"{target!r} has schema version {version}, newer than this dwell-atlas ({SCHEMA_VERSION}); upgrade the tool"
        )
    if version < SCHEMA_VERSION:
        raise AtlasError(f"{target!r} has schema version {version}, older than {SCHEMA_VERSION}; rebuild the atlas")
    missing = set(Base.metadata.tables) - tables
    if missing:
        raise AtlasError(f"{target!r} is an incomplete atlas (missing tables: {', '.join(sorted(missing))})")
