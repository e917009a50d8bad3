"""Atlas engine: creation, refusal of foreign/corrupt/newer databases (untouched), NaN/inf
guards, on SQLite and PostgreSQL; connection errors of a server as one clear line."""

from __future__ import annotations

import socket
import sqlite3
import sys
import threading

import pytest
from postgres import atlas_snapshot
from shards import shard_rows
from sqlalchemy import Float, create_engine, insert, inspect, select, text, update
from sqlalchemy.engine import make_url
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from db import SCHEMA_VERSION, AtlasError, Base, Build, Dwell, Linkage, Meta, open_atlas
from db.engine import SQLITE_PAGE_SIZE, database_url, display_target, settle_sqlite, wal_page_size
from db.writes import write_shard


@pytest.fixture
def atlas(atlas_url):
    """(target, engine) of a new atlas holding one build row, on each backend."""
    engine = open_atlas(atlas_url, create=True)
    with Session(engine) as s, s.begin():
        s.execute(
            insert(Build),
            [
                dict(
                    id=1,
                    spec_json="{}",
                    spec_digest="x",
                    code_version="0",
                    schema_version=SCHEMA_VERSION,
                    status="building",
                    n_shards=1,
                    created_at="t",
                )
            ],
        )
    yield atlas_url, engine
    engine.dispose()


def test_sqlite_atlas_is_in_wal_mode_with_foreign_keys(tmp_path):
    path = str(tmp_path / "a.sqlite")
    engine = open_atlas(path, create=True)
    with engine.connect() as conn:
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
        assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
    engine.dispose()


def test_settling_a_built_atlas_packs_it(tmp_path):
    """``settle_sqlite`` rewrites the file (``VACUUM``) before the switch to DELETE mode: pages
    freed or half filled by the build's writes are gone, the rows are kept."""
    from shards import shard_rows

    from db.writes import finish_build, write_shard

    path = str(tmp_path / "a.sqlite")
    engine = open_atlas(path, create=True)
    with engine.begin() as conn:
        conn.execute(
            insert(Build),
            [
                dict(
                    id=1,
                    spec_json="{}",
                    spec_digest="x",
                    code_version="0",
                    schema_version=SCHEMA_VERSION,
                    status="building",
                    n_shards=60,
                    created_at="t",
                    lock_token="t",
                )
            ],
        )
    for i in range(60):
        write_shard(engine, 1, shard_rows(i, dwell_angle=0.1 + 0.01 * ((37 * i) % 60)))
    assert finish_build(engine, 1, "t")
    with engine.begin() as conn:  # free pages, as a resume's clean-up deleting rows would
        conn.execute(text("CREATE TABLE scratch (x)"))
        conn.execute(text("INSERT INTO scratch SELECT zeroblob(2000) FROM dwell"))
        conn.execute(text("DROP TABLE scratch"))
    with engine.connect() as conn:
        pages = conn.exec_driver_sql("PRAGMA page_count").scalar()
        rows = conn.exec_driver_sql("SELECT count(*) FROM dwell").scalar()
    assert settle_sqlite(engine)
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)  # the engine's connections take WAL mode
    try:
        assert con.execute("PRAGMA journal_mode").fetchone()[0] == "delete"
        assert con.execute("PRAGMA freelist_count").fetchone()[0] == 0
        assert con.execute("PRAGMA page_count").fetchone()[0] < pages
        assert con.execute("SELECT count(*) FROM dwell").fetchone()[0] == rows == 60
    finally:
        con.close()


@pytest.mark.postgres
def test_postgresql_sessions_are_read_committed_whatever_the_server_default(postgres_url):
    # the builder lock's compare-and-swap needs READ COMMITTED (see db/engine.py); a site may
    # default to SERIALIZABLE, so the engine must pin it
    name = make_url(postgres_url).database
    admin = create_engine(postgres_url, isolation_level="AUTOCOMMIT")
    with admin.connect() as conn:
        conn.execute(text(f"ALTER DATABASE \"{name}\" SET default_transaction_isolation TO 'serializable'"))
    admin.dispose()
    engine = open_atlas(postgres_url, create=True)
    readonly = open_atlas(postgres_url, readonly=True)
    try:
        with engine.connect() as conn:
            assert conn.execute(text("SHOW default_transaction_isolation")).scalar() == "serializable"
            assert conn.execute(text("SHOW transaction_isolation")).scalar() == "read committed"
            assert conn.execute(text("SHOW transaction_read_only")).scalar() == "off"
            assert conn.execute(text("SHOW application_name")).scalar() == "dwell-atlas"
        with readonly.connect() as conn:
            assert conn.execute(text("SHOW transaction_read_only")).scalar() == "on"
    finally:
        engine.dispose()
        readonly.dispose()


def test_create_then_reopen(atlas):
    target, engine = atlas
    again = open_atlas(target)
    with again.connect() as conn:
        assert dict(conn.execute(select(Meta.key, Meta.value)).all()) == {
            "application": "dwell-atlas",
            "schema_version": str(SCHEMA_VERSION),
        }
        assert conn.execute(select(Build.id)).scalars().all() == [1]
    again.dispose()


def test_an_older_schema_is_refused_with_rebuild(atlas):
    """An atlas written by an older schema (fewer stored columns) is one line saying to rebuild."""
    target, engine = atlas
    with engine.begin() as conn:
        conn.execute(update(Meta).where(Meta.key == "schema_version").values(value=str(SCHEMA_VERSION - 1)))
    engine.dispose()
    with pytest.raises(AtlasError) as err:
        open_atlas(target)
    message = str(err.value)
    assert f"schema version {SCHEMA_VERSION - 1}, older than {SCHEMA_VERSION}; rebuild the atlas" in message
    assert "\n" not in message


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), float("-inf"), 1e301])
def test_nan_and_inf_never_stored(atlas, bad):
    _, engine = atlas
    row = dict(
        id=1,
        build_id=1,
        shard_index=0,
        sweep_index=0,
        b=bad,
        c=1.0,
        d=1.0,
        branch=1,
        grashof=1,
        transmission_min=0.1,
        transmission_max=1.0,
    )
    with pytest.raises(IntegrityError):
        with Session(engine) as s, s.begin():
            s.execute(insert(Linkage), [row])
    with Session(engine) as s:
        assert s.execute(Linkage.__table__.select()).first() is None


def _one_row_per_table(engine) -> None:
    """A valid row in every table (build 1 exists): the hand-made shard of ``shards.py`` (its
    dwell row staged, and the same row in the dwell table)."""
    write_shard(engine, 1, shard_rows(0))
    with engine.begin() as conn:
        conn.execute(insert(Dwell), shard_rows(0).dwells.rows())


def _float_columns_in_database(engine) -> tuple[int, int]:
    """(float columns, NOT NULL ones) as the database itself describes its tables."""
    total = not_null = 0
    for table in inspect(engine).get_table_names():
        for col in inspect(engine).get_columns(table):
            if isinstance(col["type"], Float):  # REAL on SQLite, DOUBLE PRECISION on PostgreSQL
                total += 1
                not_null += not col["nullable"]
    return total, not_null


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
def test_every_float_column_rejects_nan_and_inf(atlas, bad):
    """Each float column of each table, set to the bad value by the database itself (an UPDATE
    of a valid row): the CHECK constraints refuse it on both dialects — except that SQLite
    binds NaN as NULL, which an optional column takes (why db.writes refuses NaN itself)."""
    _, engine = atlas
    _one_row_per_table(engine)
    value = float(bad)
    sqlite_nan = engine.dialect.name == "sqlite" and bad == "nan"
    checked = 0
    for table in Base.metadata.sorted_tables:
        for column in table.columns:
            if not isinstance(column.type, Float):
                continue
            stmt = update(table).values({column.name: value})
            if sqlite_nan and column.nullable:
                with engine.connect() as conn:  # rolled back at the end of the block
                    conn.execute(stmt)
                    assert conn.execute(select(column)).scalars().all() == [None]
                continue
            with pytest.raises(IntegrityError, match="CHECK|check constraint|NOT NULL|not-null"):
                with engine.begin() as conn:
                    conn.execute(stmt)
            checked += 1
    total, not_null = _float_columns_in_database(engine)
    declared = sum(isinstance(c.type, Float) for t in Base.metadata.sorted_tables for c in t.columns)
    # every float column in the database (21 in schema 3)
    assert total == declared >= 20 and checked == (not_null if sqlite_nan else total)
    with engine.connect() as conn:  # nothing changed
        assert conn.execute(select(Dwell.dwell_angle)).scalar_one() == 0.5
        assert conn.execute(select(Build.lock_heartbeat)).scalar_one() is None


@pytest.mark.postgres
def test_postgresql_checks_reject_nan_and_infinity_literals(postgres_url):
    """PostgreSQL's own NaN (equal to itself, above every number) and ±Infinity, written as
    SQL literals, not through the driver: the constraints themselves must refuse them."""
    engine = open_atlas(postgres_url, create=True)
    try:
        with engine.begin() as conn:
            conn.execute(
                insert(Build),
                [
                    dict(
                        id=1,
                        spec_json="{}",
                        spec_digest="x",
                        code_version="0",
                        schema_version=SCHEMA_VERSION,
                        status="building",
                        n_shards=1,
                        created_at="t",
                    )
                ],
            )
        _one_row_per_table(engine)
        for literal in ("'NaN'::float8", "'Infinity'::float8", "'-Infinity'::float8"):
            for table, column in (
                ("dwell", "dwell_angle"),
                ("dwell", "radius"),
                ("segment", "phi_gen2"),
                ("linkage", "b"),
                ("build", "lock_heartbeat"),
                ("shard", "seconds"),
            ):
                with pytest.raises(IntegrityError, match=f"ck_{table}_{column}_finite"):
                    with engine.begin() as conn:
                        conn.execute(text(f"UPDATE {table} SET {column} = {literal}"))
        with engine.connect() as conn:
            assert conn.execute(text("SELECT count(*) FROM dwell WHERE dwell_angle = 'NaN'::float8")).scalar() == 0
    finally:
        engine.dispose()


@pytest.mark.parametrize(
    "version, message",
    [
        (
            SCHEMA_VERSION + 1,
            f"has schema version {SCHEMA_VERSION + 1}, newer than this dwell-atlas ({SCHEMA_VERSION}); upgrade",
        ),
        (
            SCHEMA_VERSION - 1,
            f"has schema version {SCHEMA_VERSION - 1}, older than {SCHEMA_VERSION}; rebuild the atlas",
        ),
        ("two", "has an unreadable schema version 'two'"),
    ],
)
def test_other_schema_versions_are_refused_and_untouched(atlas, version, message):
    target, engine = atlas
    with Session(engine) as s, s.begin():
        s.execute(update(Meta).where(Meta.key == "schema_version").values(value=str(version)))
    engine.dispose()
    before = atlas_snapshot(target)
    for create in (False, True):
        with pytest.raises(AtlasError, match=message.replace("(", r"\(").replace(")", r"\)")):
            open_atlas(target, create=create)
    assert atlas_snapshot(target) == before


def _make_foreign(target: str) -> None:
    """A database of another application: one table of its own, one row."""
    if "://" in target:
        engine = create_engine(target)
        with engine.begin() as conn:
            conn.execute(text("CREATE TABLE things (x integer)"))
            conn.execute(text("INSERT INTO things VALUES (1)"))
        engine.dispose()
    else:
        con = sqlite3.connect(target)
        con.execute("create table things(x)")
        con.execute("insert into things values (1)")
        con.commit()
        con.close()


def test_foreign_database_is_refused_and_untouched(atlas_url):
    _make_foreign(atlas_url)
    before = atlas_snapshot(atlas_url)
    for create in (False, True):
        with pytest.raises(AtlasError, match="is a database of another application"):
            open_atlas(atlas_url, create=create)
    assert atlas_snapshot(atlas_url) == before


def test_foreign_meta_table_is_refused(atlas):
    target, engine = atlas
    with engine.begin() as conn:
        conn.execute(update(Meta).where(Meta.key == "application").values(value="someone-else"))
    engine.dispose()
    with pytest.raises(AtlasError, match="another application \\(application='someone-else'\\)"):
        open_atlas(target)


@pytest.mark.postgres
def test_empty_postgresql_database_is_made_an_atlas_only_when_building(postgres_url):
    empty = atlas_snapshot(postgres_url)
    with pytest.raises(AtlasError, match="is an empty database, not an atlas"):
        open_atlas(postgres_url)
    with pytest.raises(AtlasError, match="is an empty database, not an atlas"):
        open_atlas(postgres_url, create=True, readonly=True)
    assert atlas_snapshot(postgres_url) == empty  # no table was created
    open_atlas(postgres_url, create=True).dispose()
    assert atlas_snapshot(postgres_url) != empty


@pytest.mark.parametrize("content", [b"not a database at all", b"SQLite format 3\x00" + b"\x00" * 50])
def test_corrupt_file_is_refused_and_untouched(tmp_path, content):
    path = tmp_path / "bad.sqlite"
    path.write_bytes(content)
    with pytest.raises(AtlasError):
        open_atlas(str(path), create=True)
    assert path.read_bytes() == content


def test_truncated_atlas_is_refused(tmp_path):
    path = tmp_path / "a.sqlite"
    open_atlas(str(path), create=True).dispose()
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(AtlasError):
        open_atlas(str(path))


def test_missing_folder_and_missing_file(tmp_path):
    with pytest.raises(AtlasError, match="no atlas at"):
        open_atlas(str(tmp_path / "none.sqlite"))
    with pytest.raises(AtlasError, match="does not exist"):
        open_atlas(str(tmp_path / "no" / "such" / "a.sqlite"), create=True)
    with pytest.raises(AtlasError, match="is a folder"):
        open_atlas(str(tmp_path))
    assert list(tmp_path.iterdir()) == []


def test_read_only_open_cannot_write(atlas):
    target, engine = atlas
    engine.dispose()
    ro = open_atlas(target, readonly=True)
    with pytest.raises(Exception, match="readonly|read-only"):
        with Session(ro) as s, s.begin():
            s.execute(update(Build).values(status="complete"))
    ro.dispose()
    check = open_atlas(target)
    with check.connect() as conn:
        assert conn.execute(select(Build.status)).scalar_one() == "building"
    check.dispose()


def test_bad_url():
    with pytest.raises(AtlasError, match="cannot open 'nosuchdialect://x/y'"):
        open_atlas("nosuchdialect://x/y")


def test_urls_and_what_messages_show(tmp_path):
    assert database_url("postgresql://u:pw@h:5/db") == "postgresql+psycopg://u:pw@h:5/db"
    assert database_url("postgres://u@h/db") == "postgresql+psycopg://u@h/db"
    assert database_url("postgresql+psycopg2://u@h/db") == "postgresql+psycopg2://u@h/db"  # an explicit driver stays
    assert database_url(str(tmp_path / "a.sqlite")) == f"sqlite:///{tmp_path / 'a.sqlite'}"
    assert (
        display_target("postgresql+psycopg://u:s3cret@h:5/db?sslmode=require")
        == "postgresql+psycopg://u:***@h:5/db?sslmode=require"
    )
    assert display_target("postgresql://u@h/db") == "postgresql://u@h/db"
    assert display_target("atlas.sqlite") == "atlas.sqlite"


def test_missing_driver_is_one_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "psycopg", None)  # as if the postgres extra were not installed
    with pytest.raises(AtlasError) as err:
        open_atlas("postgresql://u:s3cret@127.0.0.1:1/db")
    assert "database driver missing" in str(err.value) and "pip install 'dwell-atlas[postgres]'" in str(err.value)
    assert "s3cret" not in str(err.value) and "\n" not in str(err.value)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_unreachable_server_is_one_clear_error():  # needs the driver only, no server
    url = f"postgresql+psycopg://dwell:s3cret@127.0.0.1:{_free_port()}/atlas"
    for create in (False, True):
        with pytest.raises(AtlasError) as err:
            open_atlas(url, create=create)
        message = str(err.value)
        assert message.startswith("cannot connect to 'postgresql+psycopg://dwell:***@127.0.0.1:")
        assert "Connection refused" in message and "s3cret" not in message and "\n" not in message


@pytest.mark.postgres
def test_bad_credentials_and_missing_database_are_one_clear_error(postgres_server, postgres_url):
    url = make_url(postgres_url)
    wrong = url.set(password="wrong-" + (url.password or "")).render_as_string(hide_password=False)
    probe = create_engine(wrong)
    try:
        with probe.connect():
            pytest.skip(f"the server at {postgres_server.origin} accepts any password (trust authentication)")
    except Exception:  # noqa: BLE001 - refused, as it should be
        pass
    finally:
        probe.dispose()
    with pytest.raises(AtlasError, match="password authentication failed") as err:
        open_atlas(wrong)
    assert "wrong-" not in str(err.value) and ":***@" in str(err.value)

    nobody = url.set(username="dwell_no_such_role").render_as_string(hide_password=False)
    with pytest.raises(AtlasError, match="dwell_no_such_role"):
        open_atlas(nobody, create=True)

    missing = url.set(database="dwell_no_such_database").render_as_string(hide_password=False)
    with pytest.raises(AtlasError) as err:
        open_atlas(missing, create=True)
    assert 'database "dwell_no_such_database" does not exist; create it first (createdb dwell_no_such_database)' in str(
        err.value
    )
    assert "\n" not in str(err.value)


@pytest.mark.postgres
def test_two_builders_creating_one_postgresql_atlas(postgres_url):
    """Both see one complete schema: creation is serialised by an advisory lock."""
    barrier = threading.Barrier(2)
    outcomes: list[object] = []

    def create() -> None:
        barrier.wait()
        try:
            engine = open_atlas(postgres_url, create=True)
            engine.dispose()
            outcomes.append("ok")
        except Exception as exc:  # noqa: BLE001 - recorded for the assertion
            outcomes.append(exc)

    threads = [threading.Thread(target=create) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert outcomes == ["ok", "ok"]
    engine = open_atlas(postgres_url)
    with engine.connect() as conn:
        assert conn.execute(select(Meta.key).order_by(Meta.key)).scalars().all() == ["application", "schema_version"]
    engine.dispose()


# ------------------------------------------------------------- journal mode and -wal files


def _files(folder) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def _wal_of_another_database(folder, page_size: int) -> bytes:
    """The -wal of a fresh database with one committed change (never checkpointed)."""
    other = folder / "other" / "o.sqlite"
    other.parent.mkdir()
    con = sqlite3.connect(other)
    con.execute(f"PRAGMA page_size={page_size}")
    con.execute("PRAGMA journal_mode=WAL")
    con.execute("PRAGMA wal_autocheckpoint=0")
    con.execute("create table t (x)")
    con.execute("insert into t values (1)")
    con.commit()
    wal = other.with_name("o.sqlite-wal").read_bytes()
    con.close()
    return wal


def _settled_atlas(tmp_path):
    folder = tmp_path / "atlas"
    folder.mkdir()
    path = folder / "a.sqlite"
    engine = open_atlas(str(path), create=True)
    assert settle_sqlite(engine)
    return path


def test_a_settled_atlas_is_one_file_in_delete_mode_and_reading_creates_nothing(tmp_path):
    path = _settled_atlas(tmp_path)
    assert path.read_bytes()[18:20] == b"\x01\x01"  # file format versions 1: rollback journal
    before = _files(path.parent)
    engine = open_atlas(str(path), readonly=True)
    with engine.connect() as conn:
        assert conn.execute(select(Meta.value).where(Meta.key == "application")).scalar() == "dwell-atlas"
    engine.dispose()
    assert _files(path.parent) == before


def test_wal_header_page_size_and_checksum(tmp_path):
    wal = _wal_of_another_database(tmp_path, 1024)
    path = tmp_path / "x-wal"
    path.write_bytes(wal)
    assert wal_page_size(path) == 1024  # magic, page size, and the header checksum verified
    spoiled = bytearray(wal)
    spoiled[16] ^= 0x01  # salt-1: the stored checksum no longer matches
    path.write_bytes(bytes(spoiled))
    assert wal_page_size(path) is None  # SQLite would ignore it too
    path.write_bytes(wal[:31])
    assert wal_page_size(path) is None


@pytest.mark.parametrize("readonly", [True, False])
def test_any_wal_beside_a_complete_atlas_is_refused_untouched(tmp_path, readonly):
    path = _settled_atlas(tmp_path)
    path.with_name("a.sqlite-wal").write_bytes(_wal_of_another_database(tmp_path, SQLITE_PAGE_SIZE))  # same page size
    before = _files(path.parent)
    with pytest.raises(AtlasError, match="is a complete atlas .* but 'a.sqlite-wal' lies beside it"):
        open_atlas(str(path), readonly=readonly, create=not readonly)
    assert _files(path.parent) == before


def test_a_wal_of_another_page_size_beside_a_wal_mode_atlas_is_refused(tmp_path):
    folder = tmp_path / "atlas"
    folder.mkdir()
    path = folder / "a.sqlite"
    open_atlas(str(path), create=True).dispose()  # a new atlas: WAL mode, as during a build
    assert path.read_bytes()[18] == 2
    path.with_name("a.sqlite-wal").write_bytes(_wal_of_another_database(tmp_path, 1024))
    before = _files(folder)
    with pytest.raises(
        AtlasError,
        match=rf"not the atlas's own write-ahead log \(another database's: page size 1024, the atlas has {SQLITE_PAGE_SIZE}\)",
    ):
        open_atlas(str(path), readonly=True)
    assert _files(folder) == before


def test_a_changed_column_is_refused(atlas):
    target, engine = atlas
    with engine.begin() as conn:
        conn.execute(text("ALTER TABLE dwell RENAME COLUMN dwell_angle TO dwell_len"))
    with pytest.raises(
        AtlasError,
        match=r"table dwell does not match .*missing column dwell_angle; "
        r"unexpected column dwell_len\).*rebuild",
    ):
        open_atlas(target, readonly=True)


def test_a_missing_index_is_refused(atlas):
    target, engine = atlas
    with engine.begin() as conn:
        conn.execute(text("DROP INDEX ix_linkage_build_shard"))
    with pytest.raises(AtlasError, match=r"table linkage does not match .*no index ix_linkage_build_shard"):
        open_atlas(target, readonly=True)


def test_an_unreadable_spec_is_refused(atlas):
    target, engine = atlas
    with engine.begin() as conn:
        conn.execute(update(Build).values(spec_json='{"tolerances": [1e-3, "x"]}'))
    with pytest.raises(AtlasError, match=r"sweep spec of build 1 \(build.spec_json\) is not readable"):
        open_atlas(target, readonly=True)
