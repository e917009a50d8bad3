"""PostgreSQL for the tests (a pytest plugin, registered in ``tests/conftest.py``).

Fixtures
--------
``postgres_server`` (session)
    A running server, as a :class:`PostgresServer`. Found, in this order:

    1. ``DWELL_TEST_POSTGRES`` — a SQLAlchemy URL of an admin connection to the server's
       ``postgres`` database (``postgresql+psycopg://user:pw@127.0.0.1:5432/postgres``). It must
       be reachable: a configured server that does not answer fails the tests.
    2. A private throwaway server: ``initdb`` into a temporary folder (as the ``postgres`` OS
       user when running as root, since initdb refuses root) listening only on a Unix socket
       in that folder, with password authentication (a random password, so that a wrong one
       is really refused), stopped and deleted at the end of the session.
    3. Otherwise the PostgreSQL tests are skipped, saying how to enable them — or fail, when
       ``DWELL_REQUIRE_POSTGRES=1`` (CI sets it, so they can never be skipped silently there).
``postgres_url`` (function)
    The URL (``postgresql+psycopg://...``) of a fresh, empty database, dropped at teardown
    (with ``FORCE``, so engines the test left open do not matter).
``atlas_url`` (function, parametrised ``sqlite`` / ``postgresql``)
    A target for ``db.open_atlas``: a fresh SQLite file path in ``tmp_path``, or
    ``postgres_url``. The ``postgresql`` case carries the ``postgres`` marker
    (``pytest -m 'not postgres'`` leaves them all out).

``demo_atlases`` (session)
    The ``demo`` preset built once on each backend (2 workers): ``{"sqlite": path,
    "postgresql": url}``, for tests that compare the two (digest, info, query, report).
    Read only: a test must not change them.

Longer-lived databases (a module's atlas): ``with postgres_server.database() as url: ...``.
:func:`atlas_snapshot` tells whether an atlas database was left untouched, on either backend.
"""

from __future__ import annotations

import glob
import hashlib
import itertools
import os
import pwd
import secrets
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

__all__ = ["ENV_REQUIRE", "ENV_SERVER", "PostgresServer", "atlas_snapshot"]

ENV_SERVER = "DWELL_TEST_POSTGRES"
ENV_REQUIRE = "DWELL_REQUIRE_POSTGRES"
_HOW = (
    f"set {ENV_SERVER}=postgresql+psycopg://USER:PW@HOST:PORT/postgres (an admin connection), "
    "or install PostgreSQL's server binaries (Debian: apt-get install postgresql) so that the tests "
    "can start a private server"
)
# several test processes may share one configured server: names carry the pid
_names = (f"dwell_test_{os.getpid()}_{n}" for n in itertools.count())


class PostgresServer:
    """A reachable server: ``admin_url`` is a SQLAlchemy URL to its ``postgres`` database
    with the right to create and drop databases; ``origin`` says where it came from."""

    def __init__(self, admin_url: str, origin: str) -> None:
        from sqlalchemy import create_engine

        self.admin_url = admin_url
        self.origin = origin
        # CREATE/DROP DATABASE cannot run inside a transaction
        self._admin = create_engine(admin_url, isolation_level="AUTOCOMMIT", poolclass=_null_pool())

    def __repr__(self) -> str:
        return f"PostgresServer({self.origin})"

    def database_url(self, name: str) -> str:
        """The URL of database ``name`` on this server (same user, password, host, options)."""
        from sqlalchemy.engine import make_url

        return make_url(self.admin_url).set(database=name).render_as_string(hide_password=False)

    def execute(self, sql: str, **params: Any) -> None:
        """Run one statement on the admin database, outside a transaction."""
        from sqlalchemy import text

        with self._admin.connect() as conn:
            conn.execute(text(sql), params)

    @contextmanager
    def database(self) -> Iterator[str]:
        """A fresh, empty database for the ``with`` block (its URL); dropped afterwards,
        with ``FORCE`` so that engines left open do not keep it alive."""
        name = next(_names)
        self.drop(name)  # left over by a killed run
        self.execute(f'CREATE DATABASE "{name}"')
        try:
            yield self.database_url(name)
        finally:
            self.drop(name)

    def drop(self, name: str, *, attempts: int = 20) -> None:
        """DROP DATABASE ``name`` WITH (FORCE). An autovacuum worker in it belongs to the
        server, which a role without pg_signal_backend may not end: FORCE then fails with
        InsufficientPrivilege (found by a random-seed run of the suite); the worker is gone
        a moment later, so the drop is retried."""
        import time

        from sqlalchemy.exc import ProgrammingError

        for attempt in range(attempts):
            try:
                self.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
                return
            except ProgrammingError as exc:
                if "InsufficientPrivilege" not in type(exc.orig).__name__ or attempt == attempts - 1:
                    raise
                time.sleep(0.25)

    def close(self) -> None:
        self._admin.dispose()


def _null_pool() -> type:
    from sqlalchemy.pool import NullPool

    return NullPool  # no idle admin connection: it would only be in the way of DROP DATABASE


def atlas_snapshot(target: str) -> str:
    """A hash of everything the atlas database at ``target`` holds: equal before and after
    means untouched. SQLite: the file's bytes. A server: every table's definition and rows
    (in the current schema), read without opening the atlas the tool's way."""
    if "://" not in target:
        path = Path(target)
        return hashlib.sha256(path.read_bytes()).hexdigest() if path.exists() else "absent"
    from sqlalchemy import MetaData, create_engine, select

    engine = create_engine(target, poolclass=_null_pool())
    h = hashlib.sha256()
    try:
        with engine.connect() as conn:
            meta = MetaData()
            meta.reflect(conn)
            for name in sorted(meta.tables):
                table = meta.tables[name]
                h.update(repr((name, [(c.name, str(c.type), c.nullable) for c in table.columns])).encode())
                for row in conn.execute(select(table).order_by(*table.columns)):
                    h.update(repr(tuple(row)).encode())
    finally:
        engine.dispose()
    return h.hexdigest()


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "postgres: needs a PostgreSQL server (see tests/postgres.py)")


def _unavailable(reason: str) -> None:
    """Skip — or fail, when the environment requires PostgreSQL."""
    if os.environ.get(ENV_REQUIRE, "") not in ("", "0"):
        pytest.fail(f"PostgreSQL required ({ENV_REQUIRE}=1) but {reason}", pytrace=False)
    pytest.skip(f"no PostgreSQL server: {reason}; to run these tests {_HOW}")


def _normalised(url: str) -> str:
    """``url`` with the psycopg (3) driver when it names none (``postgresql://``)."""
    from sqlalchemy.engine import make_url

    u = make_url(url)
    if u.drivername in ("postgresql", "postgres"):
        u = u.set(drivername="postgresql+psycopg")
    return u.render_as_string(hide_password=False)


def _reachable(url: str) -> str | None:
    """None if the server at ``url`` answers, else the first line of the error."""
    from sqlalchemy import create_engine, text

    engine = create_engine(url, connect_args={"connect_timeout": 5})
    try:
        with engine.connect() as conn:
            conn.execute(text("SELECT 1"))
        return None
    except Exception as exc:  # noqa: BLE001 - any failure means "not usable", reported as is
        return str(getattr(exc, "orig", None) or exc).strip().splitlines()[0]
    finally:
        engine.dispose()


def _server_bindir() -> Path | None:
    """The folder holding ``initdb`` and ``pg_ctl`` (PATH first, then Debian's layout)."""
    initdb = shutil.which("initdb")
    if initdb:
        return Path(initdb).resolve().parent  # a link on PATH: pg_ctl may only be beside the target
    # Debian puts the server binaries outside PATH, one folder per major version: newest first
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"), key=lambda p: int(Path(p).parts[-3]), reverse=True)
    return Path(found[0]).parent if found else None


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class _PrivateServer:
    """A throwaway cluster in a temporary folder, on a Unix socket only (no port to clash on).

    The folder records the pid of the test process that owns it (``owner``): a session that
    was killed cannot stop its server, so the next one stops every server whose owner is gone.
    """

    PORT = 5432  # only names the socket file, which lives in our own folder
    PREFIX = "dwell-pg-"

    def __init__(self, bindir: Path, root: Path | None = None) -> None:
        self.bindir = bindir
        self.root = root if root is not None else Path(tempfile.mkdtemp(prefix=self.PREFIX))
        self.data = self.root / "data"
        self.run_as: list[str] = []
        if os.geteuid() == 0:  # initdb and postgres refuse to run as root
            try:
                owner = pwd.getpwnam("postgres")
            except KeyError:
                shutil.rmtree(self.root)
                raise RuntimeError("running as root and there is no 'postgres' OS user to run the server") from None
            os.chown(self.root, owner.pw_uid, owner.pw_gid)
            self.run_as = ["runuser", "-u", "postgres", "--"]

    def _run(self, *args: str) -> None:
        res = subprocess.run([*self.run_as, *args], capture_output=True, text=True, timeout=120)
        if res.returncode != 0:
            tail = (res.stderr or res.stdout).strip().splitlines()[-3:]
            raise RuntimeError(f"{Path(args[0]).name} failed: {' / '.join(tail)}")

    @classmethod
    def reap_orphans(cls, bindir: Path) -> None:
        """Stop and delete the private servers of test sessions that no longer run."""
        for root in Path(tempfile.gettempdir()).glob(cls.PREFIX + "*"):
            try:
                owner = int((root / "owner").read_text())
            except (OSError, ValueError):
                continue  # not ours, or still being set up
            if not _pid_alive(owner):
                try:
                    cls(bindir, root).stop()
                except (RuntimeError, OSError, subprocess.TimeoutExpired):
                    pass

    def start(self) -> str:
        (self.root / "owner").write_text(str(os.getpid()))
        password = secrets.token_hex(12)
        pwfile = self.root / "pw"
        pwfile.write_text(password + "\n")
        if self.run_as:
            os.chown(pwfile, pwd.getpwnam("postgres").pw_uid, -1)
        self._run(
            str(self.bindir / "initdb"),
            "-D",
            str(self.data),
            "-U",
            "postgres",
            "--auth=scram-sha-256",
            f"--pwfile={pwfile}",
            "-E",
            "UTF8",
            "--locale=C",
            "--no-sync",
        )
        # durability is worthless for a throwaway test server, and fsync dominates its time
        options = (
            f"-k {self.root} -c listen_addresses='' -p {self.PORT} "
            "-c fsync=off -c synchronous_commit=off -c full_page_writes=off"
        )
        self._run(
            str(self.bindir / "pg_ctl"),
            "-D",
            str(self.data),
            "-l",
            str(self.root / "log"),
            "-o",
            options,
            "-w",
            "-t",
            "60",
            "start",
        )
        return f"postgresql+psycopg://postgres:{password}@/postgres?host={self.root}&port={self.PORT}"

    def stop(self) -> None:
        try:
            if (self.data / "postmaster.pid").exists():
                self._run(str(self.bindir / "pg_ctl"), "-D", str(self.data), "-m", "immediate", "-w", "stop")
        finally:
            shutil.rmtree(self.root, ignore_errors=True)


@pytest.fixture(scope="session")
def postgres_server() -> Iterator[PostgresServer]:
    """A reachable PostgreSQL server for the session (see the module docstring)."""
    try:
        import psycopg  # noqa: F401 - the driver every URL here names
    except ImportError:
        _unavailable("the psycopg driver is not installed (pip install '.[postgres]')")
    configured = os.environ.get(ENV_SERVER, "").strip()
    if configured:
        url = _normalised(configured)
        error = _reachable(url)
        if error is not None:
            pytest.fail(f"{ENV_SERVER} names a server that does not answer: {error}", pytrace=False)
        server = PostgresServer(url, origin=ENV_SERVER)
        yield server
        server.close()
        return
    bindir = _server_bindir()
    if bindir is None:
        _unavailable(f"{ENV_SERVER} is not set and no initdb was found")
    _PrivateServer.reap_orphans(bindir)
    try:
        server = _PrivateServer(bindir)
        try:
            url = server.start()
        except BaseException:
            server.stop()
            raise
    except (RuntimeError, OSError, subprocess.TimeoutExpired) as exc:
        _unavailable(f"{ENV_SERVER} is not set and a private server could not be started ({exc})")
    try:
        error = _reachable(url)
        if error is not None:
            _unavailable(f"the private server does not answer: {error}")
        found = PostgresServer(url, origin=f"private server in {server.root}")
        yield found
        found.close()
    finally:
        server.stop()


@pytest.fixture
def postgres_url(postgres_server: PostgresServer) -> Iterator[str]:
    """The URL of a fresh, empty database on ``postgres_server``, dropped afterwards."""
    with postgres_server.database() as url:
        yield url


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def atlas_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """An atlas target on each backend: a fresh SQLite file path, or a fresh PostgreSQL URL."""
    if request.param == "sqlite":
        return str(tmp_path / "atlas.sqlite")
    return request.getfixturevalue("postgres_url")


@pytest.fixture(scope="session")
def demo_atlases(postgres_server: PostgresServer, tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, str]]:
    """The demo preset built on SQLite and on PostgreSQL (see the module docstring)."""
    from atlas.build import build_atlas
    from atlas.sweep import PRESETS

    path = str(tmp_path_factory.mktemp("demo-atlas") / "demo.sqlite")
    with postgres_server.database() as url:
        for target in (path, url):
            build_atlas(target, PRESETS["demo"], workers=2)
        yield {"sqlite": path, "postgresql": url}
