"""The only place that creates a database engine: URL handling, SQLite pragmas, schema checks.

An atlas is refused — with one clear :class:`AtlasError` and the file untouched — when it is
not an SQLite file, is an SQLite file of another application, has a newer schema version
than this code, or does not exist (unless ``create=True``).

PostgreSQL (``postgresql+psycopg://user:pw@host:port/dbname``; a bare ``postgresql://`` means
the same driver) runs the same code. The database must exist (the tool creates tables in an
empty one, never databases); an unreachable server, bad credentials or a missing database is
one :class:`AtlasError` line. Dialect differences handled here:

* transactions are pinned to READ COMMITTED: the builder lock's compare-and-swap
  (``db.writes``) relies on a blocked ``UPDATE … WHERE lock_token = ?`` re-reading the row
  once the other transaction commits, and so matching nothing; under REPEATABLE READ or
  SERIALIZABLE (a server default some sites set) it would fail with a serialisation error;
* ``readonly`` makes every transaction READ ONLY (SQLite: ``mode=ro``);
* a connect timeout (10 s unless the URL sets ``connect_timeout``): a firewalled server
  must not hang the command;
* creating the schema takes an advisory lock and runs in one transaction (PostgreSQL has
  transactional DDL), so two builders starting on one empty database cannot both create it.

Messages never show a URL's password (:func:`display_target`).

SQLite journal modes and the files beside an atlas (``-wal``, ``-shm``, ``-journal``):

* a build writes in WAL mode (readers are never blocked by the builder) and, once the build
  is complete, switches the file to rollback (DELETE) journal mode (:func:`settle_sqlite`):
  a complete atlas is one file with nothing beside it, and readers open it ``mode=ro``
  without creating anything — so it can be read from a read-only folder or medium;
* SQLite applies any ``-journal`` or ``-wal`` it finds beside a database, and neither names
  its database. An atlas carries a random id in its header and its builders put page 1 into
  every transaction, so :mod:`db.sidefiles` can tell the atlas's own side files from another
  database's before anything opens the file (:func:`_check_side_files`; the threat model is
  in docs/atlas-files.md): another database's journal or log is refused by every command, a
  ``-wal`` beside a complete atlas (DELETE mode) always; the atlas's own journal of a killed
  write is rolled back by the next build, readers refuse it (they may not write). A WAL-mode
  atlas in a folder that cannot be written, with no ``-wal`` to apply, is read
  ``immutable=1`` (nothing to miss, no ``-shm`` needed);
* an existing atlas gets the structure check it can afford on every open
  (:data:`WHOLE_CHECK_BYTES`).

A refusal changes and creates nothing: the file is only read, by our own code, first.
"""

from __future__ import annotations

import json
import os
import re
import tempfile
from pathlib import Path
from typing import Any
from urllib.parse import unquote, unquote_plus

from sqlalchemy import (
    CheckConstraint,
    Connection,
    Engine,
    Float,
    Integer,
    Numeric,
    String,
    Table,
    UniqueConstraint,
    create_engine,
    event,
    func,
    insert,
    inspect,
    select,
)
from sqlalchemy.engine import URL, make_url
from sqlalchemy.exc import ArgumentError, DatabaseError, DBAPIError, OperationalError

from db.schema import APPLICATION, SCHEMA_VERSION, Base, Build, Linkage, Meta, Shard
from db.sidefiles import (
    Ownership,
    journal_verdict,
    mark_commits,
    new_atlas_id,
    page_size,
    read_page_one,
    wal_page_size,
    wal_verdict,
)

__all__ = [
    "BUILD_STATUSES",
    "WHOLE_CHECK_BYTES",
    "AtlasError",
    "atlas_name",
    "check_url",
    "damaged",
    "database_url",
    "display_target",
    "open_atlas",
    "scrub",
    "settle_sqlite",
    "sqlite_path",
    "start_writing",
    "structure_check",
]

_SQLITE_MAGIC = b"SQLite format 3\x00"
#: Seconds to wait for a PostgreSQL server before giving up (unless the URL says otherwise).
CONNECT_TIMEOUT = 10
#: pg_advisory_xact_lock key serialising schema creation (any constant; "dwel" in ASCII).
_CREATE_LOCK_KEY = 0x6477656C


class AtlasError(Exception):
    """An atlas database that cannot be used as asked (message names the file and problem)."""


#: What a user can do about a damaged atlas (every message about damage ends with it).
RECOVER = "restore a copy of the atlas or rebuild it (dwell atlas build --replace)"


def damaged(target: str, problem: str) -> AtlasError:
    """The one-line error for an atlas whose content is damaged: ``problem`` names what is
    wrong (e.g. "3 dwell rows name a segment that does not exist"). A stored text the driver
    quotes is left out, and control characters are escaped: damaged bytes never reach the terminal."""
    if "Could not decode to UTF-8" in problem:
        problem = problem.split(" with text ", 1)[0]
    problem = "".join(c if c.isprintable() else repr(c)[1:-1] for c in problem)
    return AtlasError(f"atlas {display_target(target)!r} is damaged: {problem}; {RECOVER}")


def atlas_name(engine: Engine) -> str:
    """The atlas behind ``engine`` as messages name it (a file path, or the URL without its
    password): for errors found after opening, e.g. ``damaged(atlas_name(engine), …)``."""
    url = engine.url
    if url.get_backend_name() == "sqlite" and url.database:
        return url.database.removeprefix("file:").split("?", 1)[0]
    return url.render_as_string(hide_password=True)


def database_url(target: str) -> str:
    """A SQLAlchemy URL from ``target``: a URL as is, anything else a SQLite file path.

    A bare ``postgresql://`` (or ``postgres://``) URL gets the psycopg (3) driver, the one
    the ``postgres`` extra installs (SQLAlchemy 2.0 would pick psycopg2 for it). A path that
    cannot be resolved (a symlink loop) is one :class:`AtlasError`.
    """
    if "://" not in target:
        try:
            return f"sqlite:///{Path(target).expanduser().resolve()}"
        except (RuntimeError, OSError) as exc:  # RuntimeError: Python 3.11's "Symlink loop"
            why = getattr(exc, "strerror", None) or "a symlink loop"
            raise AtlasError(f"cannot use {display_target(target)!r} as an atlas path: {why}") from None
    scheme, rest = target.split("://", 1)
    if scheme in ("postgresql", "postgres"):
        return f"postgresql+psycopg://{rest}"
    return target


#: Query keys whose values are secrets (compared lower-case): any key containing "password"
#: (password, sslpassword, …) and libpq's passfile (a path that says where the secrets are).
_SECRET_KEYS = ("password", "passfile")
_MASK = "***"


def _split_userinfo(rest: str) -> tuple[str | None, str]:
    """``rest`` (a URL after ``scheme://``) as (userinfo or None, the rest: host, path, query).

    The userinfo ends at the LAST ``@``: a password with an unescaped ``@``, ``:``, ``/`` or
    ``#`` then stays whole inside it (a ``?`` before that ``@``: see :func:`_ambiguous`)."""
    at = rest.rfind("@")
    return (rest[:at], rest[at + 1 :]) if at >= 0 else (None, rest)


def _ambiguous(rest: str) -> bool:
    """True if ``rest`` (a URL after ``scheme://``) has a raw ``?`` before its last ``@``: a
    userinfo password holding ``?`` reads the same as a query password holding ``@``."""
    return "?" in rest[: rest.rfind("@") + 1]


def _secret_query_key(key: str) -> bool:
    k = unquote_plus(key).lower()
    return any(word in k for word in _SECRET_KEYS)


def _secrets(target: str) -> list[str]:
    """The secret strings in ``target`` as written and percent-decoded (longest first): the
    userinfo password and the values of password-like query keys.

    Two readings are taken, as a raw ``@`` or ``?`` makes a URL ambiguous: the userinfo ending
    at the last ``@`` (a password holding ``?``), and the query starting at the first ``?`` (a
    query password holding ``@``); the secrets of both are hidden."""
    if "://" not in target:
        return []
    rest = target.split("://", 1)[1]
    head, sep, query = rest.partition("?")
    readings = [_split_userinfo(rest), (_split_userinfo(head)[0], f"{head}{sep}{query}")]
    found = []
    for userinfo, tail in readings:
        if userinfo is not None and ":" in userinfo:
            found.append(userinfo.split(":", 1)[1])
        if "?" in tail:
            pairs = tail.split("?", 1)[1].split("&")
            for i, pair in enumerate(pairs):
                key, _, value = pair.partition("=")
                if _secret_query_key(key):
                    # the value up to the next '&', and up to the end (a raw '&' inside it)
                    to_end = "&".join([value, *pairs[i + 1 :]])
                    # a raw '&' makes the value's tail other options, which drivers name in
                    # errors: hide those pieces too (not 1-2 characters: that garbles messages)
                    pieces = re.split(r"[&=+\s]", f"{to_end}&{unquote_plus(to_end)}")
                    # (an option's name stays: it is the tail's key, and the message must name it)
                    found += [value, to_end, *(p for p in pieces if len(p) >= 3 and p.lower() not in _LIBPQ_KEYS)]
    found += [unquote_plus(v) for v in found] + [unquote(v) for v in found]
    return sorted({v for v in found if v}, key=len, reverse=True)


#: libpq's connection keywords (PostgreSQL manual, "Parameter Key Words"): a ``--db`` holding
#: ``key=value`` pairs with one of these is a libpq connection string, not a file name.
_LIBPQ_KEYS = frozenset(
    {
        "host",
        "hostaddr",
        "port",
        "dbname",
        "user",
        "password",
        "passfile",
        "require_auth",
        "channel_binding",
        "connect_timeout",
        "client_encoding",
        "options",
        "application_name",
        "fallback_application_name",
        "keepalives",
        "keepalives_idle",
        "keepalives_interval",
        "keepalives_count",
        "tcp_user_timeout",
        "replication",
        "gssencmode",
        "sslmode",
        "requiressl",
        "sslcompression",
        "sslcert",
        "sslkey",
        "sslpassword",
        "sslcertmode",
        "sslrootcert",
        "sslcrl",
        "sslcrldir",
        "sslsni",
        "requirepeer",
        "ssl_min_protocol_version",
        "ssl_max_protocol_version",
        "krbsrvname",
        "gsslib",
        "gssdelegation",
        "service",
        "target_session_attrs",
        "load_balance_hosts",
    }
)
_KEY = re.compile(r"(?:^|\s)([A-Za-z_]+)\s*=")
#: A URL's scheme (RFC 3986: a letter, then letters, digits, "+", ".", "-").
_SCHEME = re.compile(r"[A-Za-z][A-Za-z0-9+.\-]*")
#: Names a URL's scheme starts with (SQLAlchemy's dialects and the usual misspellings of one).
_DIALECTS = ("postgresql", "postgres", "psql", "pgsql", "sqlite", "mysql", "mariadb", "oracle", "mssql", "cockroachdb")
#: "scheme:" (one word of two letters or more, a driver after "+") at the start of a value
#: without "://": a URL with a slash or colon missing.
_SCHEME_START = re.compile(r"\s*([A-Za-z][A-Za-z0-9.\-]+(?:\+[A-Za-z0-9_.\-]+)?)(:|[;|\\/]+)")


def _connection_string_shape(target: str) -> str | None:
    """What ``target`` looks like when it is neither a path nor a well-formed URL but a
    connection string or a mistyped URL ("a libpq connection string (keys host, password)",
    "a URL missing '://' after 'postgresql'"); None for a path or a URL. Names no value. A
    "://" counts as a URL's only after a scheme (letters, digits, ``+ . -``): a password may
    hold it ("password=3://")."""
    if "://" in target and _SCHEME.fullmatch(target.split("://", 1)[0]):
        return None
    keys = [k for k in _KEY.findall(target) if k.lower() in _LIBPQ_KEYS]
    if keys:
        return f"a libpq connection string (keys {', '.join(dict.fromkeys(k.lower() for k in keys))})"
    scheme = _SCHEME_START.match(target)
    dialect = scheme is not None and scheme.group(1).split("+")[0].lower() in _DIALECTS
    if scheme and (scheme.group(2) == ":" or (dialect and scheme.group(2) != "/")):
        return f"a URL missing '://' after its scheme {scheme.group(1)!r}"
    if "@" in target and ":" in target[: target.rfind("@")]:
        return "a URL without its scheme (user:password@host…)"
    return None


def display_target(target: str) -> str:
    """``target`` as messages show it: every secret of a URL replaced by ``***``.

    The one masking function: a userinfo password (also one with unescaped ``@ : / # ?``),
    and the value of every query key containing ``password`` (any case: ``password``,
    ``sslpassword``, …) or ``passfile``. A URL whose host part cannot be a host (e.g. a
    password without ``@``) shows only its scheme. A connection string or mistyped URL (see
    :func:`check_url`) shows only what it looks like. Paths (no ``://``) are shown as given."""
    shape = _connection_string_shape(target)
    if shape is not None:
        return f"<{shape}>"
    if "://" not in target:
        return target
    scheme, rest = target.split("://", 1)
    if _ambiguous(rest):
        return f"{scheme}://…"
    userinfo, rest = _split_userinfo(rest)
    head, sep, query = rest.partition("?")
    host_port = head.split("/", 1)[0].rsplit("]", 1)[-1]  # after an IPv6 literal's brackets
    port = host_port.rpartition(":")[2] if ":" in host_port else ""
    if (port and not port.isdigit()) or "#" in head:
        return f"{scheme}://…"  # not host[:port]: the secret may hide anywhere in it
    if userinfo is not None:
        user, colon, _ = userinfo.partition(":")
        userinfo = f"{user}:{_MASK}" if colon else user
    if sep:
        # everything after the first secret key is hidden: a raw '&' or '#' in its value would
        # otherwise show the value's tail as if it were the next parameter
        pairs = query.split("&")
        for i, pair in enumerate(pairs):
            key = pair.partition("=")[0]
            if _secret_query_key(key):
                query = "&".join([*pairs[:i], f"{key}={_MASK}"])
                break
    return f"{scheme}://{'' if userinfo is None else userinfo + '@'}{head}{sep}{query}"


def scrub(message: str, target: str) -> str:
    """``message`` (e.g. a driver's error) with every secret of ``target`` replaced by ``***``."""
    for secret in _secrets(target):
        message = message.replace(secret, _MASK)
    return message


def sqlite_path(target: str) -> Path | None:
    """The file behind ``target`` if it names an SQLite file (None for other URLs, memory)."""
    if _connection_string_shape(target) is not None:
        return None  # refused by check_url, never a file
    try:
        return _sqlite_path(database_url(target))
    except (ArgumentError, ValueError, AtlasError):  # ValueError: a port that is not a number
        return None


def _sqlite_path(url: str) -> Path | None:
    u = make_url(url)
    if u.get_backend_name() != "sqlite" or not u.database or u.database == ":memory:":
        return None
    return Path(u.database)


#: An SQLite atlas up to this size gets SQLite's whole ``PRAGMA quick_check`` whenever it is
#: opened (the demo atlas, 26 MB: ~0.04 s). A bigger one gets it on its small tables (meta,
#: build, shard), and every page a command reads is checked as SQLite loads it
#: (``cell_size_check``): the whole check of the 200 MB ``standard`` atlas takes 3–6 s, a
#: hundred times its sampled query (docs/atlas-files.md).
WHOLE_CHECK_BYTES = 64 * 2**20
#: The tables a big atlas's bounded check covers (a few rows each, read by every command).
_SMALL_TABLES = ("meta", "build", "shard")


def structure_check(engine: Engine, *, whole: bool) -> str | None:
    """SQLite's ``PRAGMA quick_check`` (page and b-tree structure, no index-to-row matching)
    of the whole file (``whole``) or of its small tables: None when it passes or the database
    is not SQLite, else its first complaint."""
    if engine.dialect.name != "sqlite":
        return None
    with engine.connect() as conn:
        for table in (None,) if whole else _SMALL_TABLES:
            rows = [
                r[0]
                for r in conn.exec_driver_sql(
                    "PRAGMA quick_check(1)" if table is None else f"PRAGMA quick_check({table})"
                )
            ]
            if rows != ["ok"]:
                return f"SQLite quick check failed: {rows[0]}"
    return None


def open_atlas(target: str, *, create: bool = False, readonly: bool = False, check_structure: bool = True) -> Engine:
    """Open (or with ``create`` make) the atlas at ``target`` (path or SQLAlchemy URL).

    SQLite: foreign keys on, a busy timeout; a new file is made in WAL mode, an existing one
    keeps its journal mode until a build writes (:func:`start_writing`). ``readonly`` opens
    SQLite files read-only (``mode=ro``; ``immutable=1`` for a WAL-mode file in a folder
    that cannot be written and with no ``-wal`` beside it). The files beside an existing
    atlas are checked before anything opens it (module docstring). An existing SQLite atlas
    then gets the structure check it can afford (:data:`WHOLE_CHECK_BYTES`) unless
    ``check_structure`` is False (``atlas info`` runs the whole one itself).
    """
    check_url(target)
    url = database_url(target)
    path = _sqlite_path(url)
    existing = False
    if path is not None:
        existing = _check_sqlite_file(path, target, create=create)
        if existing:
            header = read_page_one(path)
            hot = _check_side_files(path, target, header, readonly=readonly)
            read_only_url = _read_only_url(path, header)
            # Look before touching: a file that turns out not to be an atlas (or a damaged
            # one) must only ever be read. A build skips the look when a killed write left a
            # rollback journal: only a writer can roll it back (then the schema check below).
            # (an empty database is fine to build in: what a build killed before its schema leaves)
            if not (hot and create):
                before = _side_files(path)
                try:
                    _checked(_engine(read_only_url, target), target, create=False, empty_ok=create).dispose()
                except AtlasError:
                    _remove_new_side_files(path, before)
                    raise
            if readonly:
                url = read_only_url
    engine = _engine(url, target, readonly=readonly)
    if engine.dialect.name == "sqlite":
        _sqlite_pragmas(engine, wal=create and not readonly and not existing, writer=create and not readonly)
    engine = _checked(engine, target, create=create and not readonly)
    if existing and check_structure:
        try:
            problem = structure_check(engine, whole=path.stat().st_size <= WHOLE_CHECK_BYTES)
        except (DatabaseError, OSError) as exc:
            problem = _first_line(exc)
        if problem:
            engine.dispose()
            raise damaged(target, problem)
    return engine


def _check_side_files(path: Path, target: str, page_one: bytes, *, readonly: bool) -> bool:
    """Refuse a ``-journal`` or ``-wal`` beside ``path`` that is not proven the atlas's own
    (:mod:`db.sidefiles`), and, for readers, the atlas's own unfinished rollback; True when the
    atlas's own rollback journal of a killed write lies beside it (a build rolls it back)."""
    name = display_target(target)
    journal = path.with_name(path.name + "-journal")
    try:
        file_size = path.stat().st_size
    except OSError:
        file_size = 0
    verdict = journal_verdict(journal, page_one, file_size)
    if verdict.ownership is Ownership.FOREIGN:
        raise AtlasError(
            f"{journal.name!r} beside {name!r} is not the atlas's own rollback journal ({verdict.why}): "
            "move that file away (SQLite would roll it back into the atlas), or restore the atlas"
        )
    # harmless: SQLite would still have to delete it, which a reader may not
    hot = verdict.ownership in (Ownership.OWN, Ownership.HARMLESS)
    if hot and readonly:
        raise AtlasError(
            f"{name!r} has an unfinished write ({journal.name!r} beside it, left by a stopped build): "
            "run dwell atlas build on it to roll it back and resume, or restore the atlas"
        )
    wal = path.with_name(path.name + "-wal")
    if wal.exists() and page_size(page_one) is not None:
        if page_one[18] == 1:
            raise AtlasError(
                f"{name!r} is a complete atlas (it keeps no write-ahead log) but {wal.name!r} lies beside it, "
                "which is not its own: move that file away (SQLite would apply it), or restore the atlas"
            )
        verdict = wal_verdict(wal, page_one)
        if verdict.ownership is Ownership.FOREIGN:
            raise AtlasError(
                f"{wal.name!r} beside {name!r} is not the atlas's own write-ahead log ({verdict.why}): "
                "move that file away (SQLite would apply it), or restore the atlas"
            )
    return hot


def _read_only_url(path: Path, header: bytes) -> str:
    """``mode=ro``; ``immutable=1`` for a WAL-mode file whose folder cannot be written and
    which has no ``-wal`` to apply (``mode=ro`` would need to make a ``-shm`` there)."""
    wal = path.with_name(path.name + "-wal")
    wal_mode = len(header) >= 100 and header[18] == 2
    nothing_to_apply = not wal.exists() or wal_page_size(wal) is None
    if wal_mode and nothing_to_apply and not os.access(path.parent, os.W_OK):
        return f"sqlite:///file:{path}?immutable=1&uri=true"
    return f"sqlite:///file:{path}?mode=ro&uri=true"


def start_writing(engine: Engine) -> None:
    """Before a build's first write: SQLite atlases to WAL mode (readers are then never
    blocked by the builder). No-op elsewhere and when the file already is in WAL mode."""
    if engine.dialect.name != "sqlite":
        return
    with engine.connect() as conn:
        if str(conn.exec_driver_sql("PRAGMA journal_mode").scalar()).lower() != "wal":
            cur = conn.connection.dbapi_connection.cursor()
            _name_atlas(cur)  # an atlas made before ids: named while the file is still in rollback mode
            cur.close()
            conn.exec_driver_sql("PRAGMA journal_mode=WAL")


def settle_sqlite(engine: Engine) -> bool:
    """After a complete build: pack the file (``VACUUM``), fold the WAL into it and switch it
    to DELETE journal mode, so that a complete atlas is one file (read-only folders can read
    it, and any ``-wal`` found beside it later is refused). Disposes ``engine``'s connections. Returns False when
    another connection (a reader) kept the file busy: it then stays in WAL mode, which is
    safe, and the next ``dwell atlas build`` of the same sweep switches it."""
    if engine.dialect.name != "sqlite":
        return True
    engine.dispose()
    try:
        with engine.connect() as conn:
            conn.exec_driver_sql("PRAGMA busy_timeout=2000")  # a reader must not hold the build up long
            mode = str(conn.exec_driver_sql("PRAGMA journal_mode").scalar()).lower()
            if mode != "delete":
                # the dwell table's b-tree grew by inserts in key order of no shard's making:
                # its pages are ~88 % full; rewritten once they are packed (standard: 8 090 →
                # 7 340 bytes per linkage, ~2 s). Still in WAL mode, so a kill here loses nothing.
                conn.exec_driver_sql("VACUUM")
                mode = str(conn.exec_driver_sql("PRAGMA journal_mode=DELETE").scalar()).lower()
    except OperationalError:
        return False
    finally:
        engine.dispose()
    return mode == "delete"


def check_url(target: str) -> URL:
    """``target`` (path or URL) parsed, or one :class:`AtlasError` that shows no secret.

    Refuses a URL whose password SQLAlchemy reads differently from the masking (an unescaped
    ``@`` in it, or a ``?`` before its last ``@``): the rest would become the host name and
    show in the driver's errors, and the connection would go to the wrong server anyway."""
    shape = _connection_string_shape(target)
    if shape is not None:
        raise AtlasError(
            f"not a database path or URL: {shape}; write a PostgreSQL database as "
            "postgresql://USER:PASSWORD@HOST:PORT/DBNAME, an SQLite file as its path"
        )
    try:
        parsed = make_url(database_url(target))
    except (ArgumentError, ValueError):  # ValueError: a port that is not a number
        raise AtlasError(f"not a database path or URL: {display_target(target)!r}") from None
    if "://" not in target:
        return parsed
    rest = target.split("://", 1)[1]
    userinfo, _ = _split_userinfo(rest)
    written = userinfo.partition(":")[2] if userinfo and ":" in userinfo else None
    if _ambiguous(rest):
        raise AtlasError(
            f"{display_target(target)!r}: a raw '?' before the last '@' makes the URL ambiguous "
            "(user password or query?): percent-encode the password (%3F for ?, %40 for @)"
        )
    if (written and unquote(written)) != (parsed.password or None):
        raise AtlasError(
            f"the password in {display_target(target)!r} holds an unescaped '@': "
            "percent-encode it (%40 for @, %3A for :, %2F for /, %23 for #, %3F for ?)"
        )
    return parsed


def _engine(url: str, target: str, *, readonly: bool = False) -> Engine:
    u = make_url(url)
    options = _postgresql_options(u, readonly=readonly) if u.get_backend_name() == "postgresql" else {}
    try:
        return create_engine(u, **options)
    except (ModuleNotFoundError, ImportError) as exc:
        hint = " (install it with: pip install 'dwell-atlas[postgres]')" if u.get_backend_name() == "postgresql" else ""
        raise AtlasError(f"cannot open {display_target(target)!r}: database driver missing: {exc}{hint}") from None
    except ArgumentError as exc:
        raise AtlasError(f"cannot open {display_target(target)!r}: {scrub(str(exc), target)}") from None


def _postgresql_options(url: URL, *, readonly: bool) -> dict[str, Any]:
    """``create_engine`` keywords for PostgreSQL (why each: see the module docstring)."""
    connect_args: dict[str, Any] = {}
    if "connect_timeout" not in url.query:
        connect_args["connect_timeout"] = CONNECT_TIMEOUT
    if "application_name" not in url.query:
        connect_args["application_name"] = APPLICATION  # names the builders in pg_stat_activity
    options: dict[str, Any] = {"isolation_level": "READ COMMITTED", "connect_args": connect_args}
    if readonly:
        options["execution_options"] = {"postgresql_readonly": True}
    return options


def _first_line(exc: BaseException) -> str:
    """The driver's message, first line, without psycopg's ``connection failed:`` preamble."""
    text = str(getattr(exc, "orig", None) or exc).strip()
    first = text.splitlines()[0] if text else type(exc).__name__
    return " ".join(first.removeprefix("connection failed: ").split())


def _connected(engine: Engine, target: str) -> None:
    """Open one connection, turning every way of failing into one :class:`AtlasError` line.

    Servers only: an SQLite file was checked before, and its failures (corrupt, not a
    database) surface in the schema check, with that wording."""
    if engine.dialect.name == "sqlite":
        return
    try:
        with engine.connect():
            pass
    except DBAPIError as exc:
        message = scrub(_first_line(exc), target)
        hint = ""
        if engine.dialect.name == "postgresql" and "does not exist" in message and "database" in message:
            database = engine.url.database
            hint = f"; create it first (createdb {database}), the atlas's tables are made by dwell atlas build"
        raise AtlasError(f"cannot connect to {display_target(target)!r}: {message}{hint}") from None


def _checked(engine: Engine, target: str, *, create: bool, empty_ok: bool = False) -> Engine:
    """``engine`` after the schema check (or creation); disposed and refused on failure."""
    try:
        _connected(engine, target)
        _check_or_create_schema(engine, display_target(target), create=create, empty_ok=empty_ok)
    except (OperationalError, DatabaseError) as exc:
        engine.dispose()
        code = str(getattr(exc.orig, "sqlite_errorname", ""))
        if code.startswith(("SQLITE_CORRUPT", "SQLITE_NOTADB")):
            raise damaged(target, _first_line(exc)) from None
        raise AtlasError(
            f"cannot use {display_target(target)!r} as an atlas: {scrub(_first_line(exc), target)}"
        ) from None
    except ValueError as exc:  # a damaged page read as a value the driver cannot convert
        engine.dispose()
        raise damaged(target, _first_line(exc)) from None
    except AtlasError:
        engine.dispose()
        raise
    return engine


def _check_sqlite_file(path: Path, target: str, *, create: bool) -> bool:
    """Refuse paths that cannot be an atlas; True if a non-empty file is already there."""
    if path.exists():
        if path.is_dir():
            raise AtlasError(f"{display_target(target)!r} is a folder, not an atlas file")
        if not path.is_file():  # a FIFO, device or socket: opening it would block or never end
            raise AtlasError(
                f"{display_target(target)!r} is not a regular file (a FIFO, device or socket), not an atlas"
            )
        try:
            with path.open("rb") as fh:
                head = fh.read(len(_SQLITE_MAGIC))
        except OSError as exc:
            raise AtlasError(f"cannot read {display_target(target)!r}: {exc.strerror}") from None
        if head != _SQLITE_MAGIC and not (create and head == b""):
            raise AtlasError(
                f"{display_target(target)!r} is not an SQLite database (it may be corrupt or another kind of file)"
            )
        return head != b""
    if not create:
        raise AtlasError(
            f"no atlas at {display_target(target)!r} (build one with: dwell atlas build --db {display_target(target)})"
        )
    if not path.parent.is_dir():
        raise AtlasError(f"cannot create {display_target(target)!r}: folder {str(path.parent)!r} does not exist")
    try:  # SQLite would only say "unable to open database file"; it needs the folder for its side files too
        with tempfile.TemporaryFile(dir=path.parent):
            pass
    except OSError as exc:
        raise AtlasError(
            f"cannot create {display_target(target)!r}: folder {str(path.parent)!r} cannot be written ({exc.strerror})"
        ) from None
    return False


def _side_files(path: Path) -> set[Path]:
    return {p for p in (path.with_name(path.name + "-wal"), path.with_name(path.name + "-shm")) if p.exists()}


def _remove_new_side_files(path: Path, before: set[Path]) -> None:
    """Leave a refused file as it was found: a read-only look at a WAL-mode file makes an
    empty ``-wal`` and a ``-shm`` beside it; remove those (only if they are new and empty)."""
    wal, shm = path.with_name(path.name + "-wal"), path.with_name(path.name + "-shm")
    try:
        if wal not in before and wal.exists() and wal.stat().st_size == 0:
            wal.unlink()
        if shm not in before and shm.exists() and not wal.exists():
            shm.unlink()
    except OSError:
        pass


#: The page size of a new SQLite atlas (bytes). 16 KiB rather than SQLite's 4 KiB: a build
#: writes and sorts millions of ~130-byte dwell rows, and a quarter as many pages to split,
#: log and check took the single writer from 2 430 to ~3 000 linkages/s (``dwell bench atlas
#: --ingest``); the query is as fast, the file 1 % smaller (docs/atlas.md, "Speed").
SQLITE_PAGE_SIZE = 16384


def _sqlite_pragmas(engine: Engine, *, wal: bool, writer: bool) -> None:
    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_conn, _record):  # noqa: ANN001 - DBAPI connection
        cur = dbapi_conn.cursor()
        cur.execute("PRAGMA foreign_keys=ON")
        cur.execute("PRAGMA busy_timeout=30000")
        # every page read is checked as it is loaded (cell sizes and offsets): the check of
        # what a command reads, where the whole file's is too slow (WHOLE_CHECK_BYTES)
        cur.execute("PRAGMA cell_size_check=ON")
        if wal:  # a new file; an existing one changes mode when a build writes (start_writing)
            cur.execute(f"PRAGMA page_size={SQLITE_PAGE_SIZE}")  # before the first table: fixed from then on
            _name_atlas(cur)  # in rollback mode: the file itself holds the id (db.sidefiles)
            cur.execute("PRAGMA journal_mode=WAL")
        cur.execute("PRAGMA journal_mode")
        if str(cur.fetchone()[0]).lower() == "wal":  # durable in WAL mode, unlike in rollback mode
            cur.execute("PRAGMA synchronous=NORMAL")
        cur.close()

    if writer:
        mark_commits(engine)


def _name_atlas(cur: Any) -> None:
    """Give the database on ``cur`` its atlas id (:mod:`db.sidefiles`) unless it has one.
    Call it in rollback-journal mode only: in WAL mode the id would reach the log, not the file."""
    cur.execute("PRAGMA user_version")
    if int(cur.fetchone()[0]) == 0:
        cur.execute(f"PRAGMA user_version={new_atlas_id()}")


def _check_or_create_schema(engine: Engine, target: str, *, create: bool, empty_ok: bool = False) -> None:
    """Refuse what is not an atlas of this schema version; with ``create`` make the schema in
    an empty database. ``target`` is the name for messages."""
    with engine.begin() as conn:
        if create and conn.dialect.name == "postgresql":
            # held to the end of this transaction: a second builder waits, then sees the tables
            conn.execute(select(func.pg_advisory_xact_lock(_CREATE_LOCK_KEY)))
        elif create and conn.dialect.name == "sqlite" and not inspect(conn).get_table_names():
            # pysqlite runs DDL outside any transaction: a kill between CREATE TABLE and the meta
            # rows would leave a half-made atlas that every later build refuses. IMMEDIATE also
            # makes a second builder wait here, then see the tables.
            conn.exec_driver_sql("BEGIN IMMEDIATE")
        tables = set(inspect(conn).get_table_names())
        if not tables:
            if create:
                _create_schema(conn)
            elif not empty_ok:
                raise AtlasError(f"{target!r} is an empty database, not an atlas")
            return
        _check_schema(conn, tables, target)


def _create_schema(conn: Connection) -> None:
    Base.metadata.create_all(conn)
    conn.execute(
        insert(Meta),
        [
            {"key": "application", "value": APPLICATION},
            {"key": "schema_version", "value": str(SCHEMA_VERSION)},
        ],
    )


def _check_schema(conn: Connection, tables: set[str], target: str) -> None:
    if "meta" not in tables:
        raise AtlasError(f"{target!r} is a database of another application (no Dwell atlas meta table)")
    meta = {key: value for key, value in conn.execute(select(Meta.key, Meta.value))}
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
        raise AtlasError(
            f"{target!r} has schema version {version}, older than {SCHEMA_VERSION}; rebuild the atlas "
            "(delete it and build again, or build into another --db: --replace cannot open an older schema)"
        )
    missing = set(Base.metadata.tables) - tables
    if missing:
        raise AtlasError(f"{target!r} is an incomplete atlas (missing tables: {', '.join(sorted(missing))})")
    inspector = inspect(conn)
    for table in Base.metadata.sorted_tables:
        problem = _table_mismatch(inspector, table)
        if problem:
            raise damaged(target, f"table {table.name} does not match the schema of this dwell-atlas ({problem})")
    _check_json(conn, target)
    _check_builds(conn, target)


#: The values of ``build.status`` (its CHECK constraint; a damaged file may hold others).
BUILD_STATUSES = ("building", "complete")


def _check_builds(conn: Connection, target: str) -> None:
    """Each build row's status is known and, when complete, it has all its shard rows (one
    count over the shard table: a deleted shard row would otherwise pass as complete and a
    build would redo it under a builder lock it no longer holds). The linkages belong to a build row: the lowest and highest ``linkage.build_id`` (two
    index look-ups, whatever the atlas's size) name existing builds. ``atlas info --verify``
    finds every orphan; this catches the usual damage (a build row deleted) on every open,
    where the query would otherwise answer "no six-bar" from an atlas that has them."""
    shards = dict(conn.execute(select(Shard.build_id, func.count()).group_by(Shard.build_id)).all())
    for build_id, status, n_shards in conn.execute(select(Build.id, Build.status, Build.n_shards)):
        if status not in BUILD_STATUSES:
            raise damaged(target, f"build {build_id} has the unknown status {status!r} (build.status)")
        if not isinstance(n_shards, int) or n_shards < 1:
            raise damaged(target, f"build {build_id} records {n_shards!r} shards (build.n_shards)")
        done = shards.get(build_id, 0)
        if done > n_shards or (status == "complete" and done != n_shards):
            raise damaged(target, f"build {build_id} is {status} with {done} of its {n_shards} shard rows")
    lo, hi = conn.execute(select(func.min(Linkage.build_id), func.max(Linkage.build_id))).one()
    if lo is None:
        return
    builds = set(conn.execute(select(Build.id)).scalars())
    missing = sorted({lo, hi} - builds)
    if missing:
        raise damaged(target, f"its linkages name build {missing[0]}, which has no row in the build table")


def _type_family(type_: Any) -> str:
    """What a column type means across dialects and reflection: integer, float or text."""
    if isinstance(type_, Integer):
        return "integer"
    if isinstance(type_, (Float, Numeric)):
        return "float"
    if isinstance(type_, String):  # Text too
        return "text"
    return str(type_) or type(type_).__name__


def _table_mismatch(inspector: Any, table: Table) -> str | None:
    """How the stored ``table`` differs from the model (columns, types, NOT NULL, keys,
    named CHECK constraints and indexes), or None. Constraints only need to be there:
    a dialect may reflect more (PostgreSQL's NOT NULL checks, SQLite's autoindexes)."""
    stored = {c["name"]: c for c in inspector.get_columns(table.name)}
    model = {c.name: c for c in table.columns}
    if set(stored) != set(model):
        parts = []
        if set(model) - set(stored):
            parts.append("missing column " + ", ".join(sorted(set(model) - set(stored))))
        if set(stored) - set(model):
            parts.append("unexpected column " + ", ".join(sorted(set(stored) - set(model))))
        return "; ".join(parts)
    for name, col in model.items():
        got = _type_family(stored[name]["type"])
        if got != _type_family(col.type):
            return f"column {name} is {stored[name]['type']}, not {_type_family(col.type)}"
        if not col.primary_key and bool(stored[name]["nullable"]) != bool(col.nullable):
            return f"column {name} is {'nullable' if stored[name]['nullable'] else 'NOT NULL'}"
    pk = inspector.get_pk_constraint(table.name).get("constrained_columns") or []
    if list(pk) != [c.name for c in table.primary_key.columns]:
        return f"primary key ({', '.join(pk)})"
    fks = {
        (tuple(fk["constrained_columns"]), fk["referred_table"], tuple(fk["referred_columns"]))
        for fk in inspector.get_foreign_keys(table.name)
    }
    for fk in table.foreign_key_constraints:
        want = (tuple(c.name for c in fk.columns), fk.referred_table.name, tuple(e.column.name for e in fk.elements))
        if want not in fks:
            return f"no foreign key ({', '.join(want[0])}) → {want[1]}"
    checks = {c["name"] for c in inspector.get_check_constraints(table.name)}
    for c in table.constraints:
        if isinstance(c, CheckConstraint) and c.name not in checks:
            return f"no constraint {c.name}"
    uniques = {tuple(u["column_names"]) for u in inspector.get_unique_constraints(table.name)}
    indexes = inspector.get_indexes(table.name)
    uniques |= {tuple(i["column_names"]) for i in indexes if i.get("unique")}
    wanted = [tuple(c.name for c in u.columns) for u in table.constraints if isinstance(u, UniqueConstraint)]
    wanted += [(c.name,) for c in table.columns if c.unique]
    for cols in wanted:
        if cols not in uniques:
            return f"no unique constraint on ({', '.join(cols)})"
    names = {i["name"] for i in indexes}
    for index in table.indexes:
        if index.name not in names:
            return f"no index {index.name}"
    return None


def _check_json(conn: Connection, target: str) -> None:
    """The JSON columns (a few rows: builds and shards) parse as what the code reads."""
    from db.spec import SpecError, stored_spec

    for build_id, text in conn.execute(select(Build.id, Build.spec_json)):
        try:
            stored_spec(text)
        except SpecError as exc:
            raise damaged(
                target, f"the sweep spec of build {build_id} (build.spec_json) is not readable: {exc}"
            ) from None
        except TypeError:  # not a text at all (a damaged record)
            raise damaged(target, f"the sweep spec of build {build_id} (build.spec_json) is not readable") from None
    for build_id, index, text in conn.execute(select(Shard.build_id, Shard.shard_index, Shard.skipped_json)):
        try:
            skipped = json.loads(text)
            ok = isinstance(skipped, dict) and all(isinstance(n, int) for n in skipped.values())
        except (ValueError, TypeError):
            ok = False
        if not ok:
            raise damaged(target, f"shard {index} of build {build_id} has an unreadable shard.skipped_json")
