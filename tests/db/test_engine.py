"""Atlas engine: creation, refusal of foreign/corrupt/newer files (untouched), NaN/inf guards."""

from __future__ import annotations

import hashlib
import sqlite3

import pytest
from sqlalchemy import insert, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from db import SCHEMA_VERSION, AtlasError, Build, Linkage, Meta, open_atlas


def digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def atlas(tmp_path):
    path = tmp_path / "a.sqlite"
    engine = open_atlas(str(path), create=True)
    with Session(engine) as s, s.begin():
        s.execute(insert(Build), [dict(id=1, spec_json="{}", spec_digest="x", code_version="0",
                                       schema_version=SCHEMA_VERSION, status="building", n_shards=1, created_at="t")])
    yield path, engine
    engine.dispose()


def test_create_then_reopen_in_wal_mode(atlas):
    path, engine = atlas
    with engine.connect() as conn:
        assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
        assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
    open_atlas(str(path)).dispose()


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), float("-inf"), 1e301])
def test_nan_and_inf_never_stored(atlas, bad):
    _, engine = atlas
    row = dict(id=1, build_id=1, shard_index=0, sweep_index=0, b=bad, c=1.0, d=1.0, branch=1, grashof=1,
               transmission_min=0.1, transmission_max=1.0)
    with pytest.raises(IntegrityError):
        with Session(engine) as s, s.begin():
            s.execute(insert(Linkage), [row])
    with Session(engine) as s:
        assert s.execute(Linkage.__table__.select()).first() is None


def test_newer_schema_is_refused_and_untouched(atlas):
    path, engine = atlas
    with Session(engine) as s, s.begin():
        s.execute(update(Meta).where(Meta.key == "schema_version").values(value=str(SCHEMA_VERSION + 1)))
    engine.dispose()
    before = digest(path)
    with pytest.raises(AtlasError, match=f"schema version {SCHEMA_VERSION + 1}, newer"):
        open_atlas(str(path))
    assert digest(path) == before


def test_foreign_sqlite_file_is_refused_and_untouched(tmp_path):
    path = tmp_path / "other.sqlite"
    con = sqlite3.connect(path)
    con.execute("create table things(x)")
    con.commit()
    con.close()
    before = digest(path)
    for create in (False, True):
        with pytest.raises(AtlasError, match="another application"):
            open_atlas(str(path), create=create)
    assert digest(path) == before


@pytest.mark.parametrize("content", [b"not a database at all", b"SQLite format 3\x00" + b"\x00" * 50])
def test_corrupt_file_is_refused_and_untouched(tmp_path, content):
    path = tmp_path / "bad.sqlite"
    path.write_bytes(content)
    with pytest.raises(AtlasError):
        open_atlas(str(path), create=True)
    assert path.read_bytes() == content


def test_truncated_atlas_is_refused(atlas):
    path, engine = atlas
    engine.dispose()
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
    path, engine = atlas
    engine.dispose()
    ro = open_atlas(str(path), readonly=True)
    with pytest.raises(Exception, match="readonly|read-only"):
        with Session(ro) as s, s.begin():
            s.execute(update(Build).values(status="complete"))
    ro.dispose()


def test_bad_url():
    with pytest.raises(AtlasError):
        open_atlas("nosuchdialect://x/y")
