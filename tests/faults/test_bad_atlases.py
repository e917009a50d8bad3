"""Damaged, foreign, newer and read-only atlases under ``dwell atlas info``, ``dwell atlas
build``, ``dwell query`` and ``dwell report``: one error line, exit status 2, no traceback,
and the file byte-identical with nothing new beside it.

Read-only: the tests run as root, for whom ``chmod 444`` stops nothing, and no unprivileged
user can run this interpreter. ``chattr +i`` (the immutable flag) stops root too: an immutable
file is a read-only atlas (readers work, a build that must write is refused), an immutable
folder a read-only location: a complete atlas (DELETE journal mode) is read there ``mode=ro``,
an atlas in WAL mode with no ``-wal`` beside it ``immutable=1``. Those tests skip where the flag cannot be set (not root, or a file system without it).
"""

from __future__ import annotations

import hashlib
import json
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from harness.processes import N_SHARDS, QUERY, SMALL, info, run

from db import SCHEMA_VERSION

COMMANDS = ("info", "build", "query", "report")


def argv(command: str, target: str, tmp_path: Path, candidate: str) -> list[str]:
    return {
        "info": ["atlas", "info", "--db", target],
        "build": ["atlas", "build", "--db", target, *SMALL, "--workers", "1"],
        "query": ["query", "--db", target, *QUERY],
        "report": ["report", "--db", target, "--candidates", candidate, "--out", str(tmp_path / "report")],
    }[command]


def snapshot(folder: Path) -> dict[str, str]:
    """Every file under ``folder``: relative name → sha256."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _overwrite(path: Path, start: int, stop: int) -> None:
    data = bytearray(path.read_bytes())
    data[start:stop] = bytes((37 * i + 11) % 256 for i in range(stop - start))
    path.write_bytes(bytes(data))


def _truncated(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _foreign(path: Path) -> None:
    path.unlink()
    con = sqlite3.connect(path)
    con.execute("create table things(x)")
    con.execute("insert into things values (1)")
    con.commit()
    con.close()


def _newer(path: Path) -> None:
    con = sqlite3.connect(path)
    con.execute("update meta set value = ? where key = 'schema_version'", (str(SCHEMA_VERSION + 1),))
    con.commit()
    con.close()


#: case → (how to spoil a copy of the reference atlas, what the error line must say)
CASES = {
    "truncated": (_truncated, "database disk image is malformed"),
    "middle-overwritten": (
        lambda p: _overwrite(p, p.stat().st_size // 3, 2 * p.stat().st_size // 3),
        "restore a copy",
    ),  # info's quick check names the page; the others SQLite's error
    "header-overwritten": (lambda p: _overwrite(p, 16, 100), "file is not a database"),
    "magic-overwritten": (lambda p: _overwrite(p, 0, 16), "is not an SQLite database"),
    "foreign": (_foreign, "is a database of another application"),
    "newer-schema": (
        _newer,
        f"has schema version {SCHEMA_VERSION + 1}, newer than this dwell-atlas ({SCHEMA_VERSION})",
    ),
}


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("case", CASES)
def test_a_bad_atlas_is_refused_untouched(tmp_path, capsys, reference, case, command):
    spoil, message = CASES[case]
    db = tmp_path / "atlas.sqlite"
    shutil.copyfile(reference.path, db)
    spoil(db)
    before = snapshot(tmp_path)
    rc, out, err = run(capsys, *argv(command, str(db), tmp_path, reference.candidate))
    assert rc == 2 and out == "", err
    assert err.count("\n") == 1 and err.startswith("dwell: error: ") and message in err, err
    after = snapshot(tmp_path)
    assert after[db.name] == before[db.name]  # byte-identical
    # refused before SQLite touched anything; even the damage found only while reading rows
    # leaves nothing beside a complete atlas (DELETE journal mode: readers make no -wal, -shm)
    assert set(after) == set(before), set(after) ^ set(before)
    assert ("restore" in err and "rebuild" in err) or case in ("foreign", "newer-schema", "magic-overwritten")


@pytest.mark.postgres
def test_a_foreign_or_newer_postgresql_database_is_refused(tmp_path, capsys, reference, postgres_url):
    from sqlalchemy import create_engine, text

    engine = create_engine(postgres_url)
    with engine.begin() as conn:
        conn.execute(text("create table things (x integer)"))
    for command in COMMANDS:
        rc, out, err = run(capsys, *argv(command, postgres_url, tmp_path, reference.candidate))
        assert rc == 2 and out == "" and err.count("\n") == 1, err
        assert "is a database of another application" in err
    with engine.begin() as conn:
        conn.execute(text("drop table things"))
    rc, out, err = run(capsys, "atlas", "build", "--db", postgres_url, "--samples", "8", "--workers", "1")
    assert rc == 0, err
    with engine.begin() as conn:
        conn.execute(text("update meta set value = :v where key = 'schema_version'"), {"v": str(SCHEMA_VERSION + 1)})
    engine.dispose()
    for command in COMMANDS:
        rc, out, err = run(capsys, *argv(command, postgres_url, tmp_path, reference.candidate))
        assert rc == 2 and out == "" and err.count("\n") == 1, err
        assert f"has schema version {SCHEMA_VERSION + 1}, newer than this dwell-atlas" in err
    assert list(tmp_path.iterdir()) == []  # no report folder


# ---------------------------------------------------------------------------------- read-only


def _chattr(flag: str, *paths: Path) -> bool:
    try:
        return subprocess.run(["chattr", flag, *map(str, paths)], capture_output=True).returncode == 0
    except OSError:
        return False


@pytest.fixture
def immutable(tmp_path):
    """``immutable(path, ...)`` sets the immutable flag (skips where it cannot); undone after."""
    flagged: list[Path] = []
    probe = tmp_path / "probe"
    probe.write_text("")
    if not _chattr("+i", probe):
        probe.unlink()
        pytest.skip("chattr +i is not possible here (needs root and a file system with the flag)")
    _chattr("-i", probe)
    probe.unlink()

    def flag(*paths: Path) -> None:
        assert _chattr("+i", *paths)
        flagged.extend(paths)

    yield flag
    _chattr("-i", *flagged)


def unfinished(path: Path) -> None:
    """Make the atlas at ``path`` look killed before its last shard (what a resume completes)."""
    con = sqlite3.connect(path)
    last = N_SHARDS - 1
    links = "select id from linkage where shard_index = ?"
    con.execute(
        f"delete from dwell where segment_id in (select id from segment where linkage_id in ({links}))", (last,)
    )
    con.execute(f"delete from segment where linkage_id in ({links})", (last,))
    con.execute("delete from linkage where shard_index = ?", (last,))
    con.execute("delete from shard where shard_index = ?", (last,))
    con.execute("update build set status = 'building', content_digest = null, finished_at = null")
    con.commit()
    con.close()


def test_a_read_only_atlas_is_read_but_not_written(tmp_path, capsys, reference, immutable):
    folder = tmp_path / "atlas"
    folder.mkdir()
    db = folder / "atlas.sqlite"
    shutil.copyfile(reference.path, db)
    unfinished(db)
    immutable(db)
    digest = hashlib.sha256(db.read_bytes()).hexdigest()

    doc = info(capsys, str(db))  # reading needs no write
    assert doc["build"]["status"] == "building" and doc["build"]["shards_done"] == N_SHARDS - 1
    rc, out, err = run(capsys, "query", "--db", str(db), *QUERY, "--json")
    assert rc == (0 if json.loads(out)["candidates"] else 1), err  # 1: none found, as grep
    rc, out, err = run(capsys, *argv("build", str(db), tmp_path, reference.candidate))
    assert rc == 2 and out == "", err
    assert err == (
        "dwell: error: atlas database error: attempt to write a readonly database "
        "(the file or its folder is read-only)\n"
    )
    assert hashlib.sha256(db.read_bytes()).hexdigest() == digest
    assert {p.name for p in folder.iterdir()} <= {db.name, f"{db.name}-wal", f"{db.name}-shm"}


def wal_mode(path: Path) -> None:
    """Switch a copy to WAL mode, as an atlas being built (or made by an older dwell-atlas) is."""
    con = sqlite3.connect(path)
    assert con.execute("PRAGMA journal_mode=WAL").fetchone()[0] == "wal"
    con.close()  # the last connection folds the WAL in and deletes it: no -wal beside it


@pytest.mark.parametrize("mode", ["delete", "wal"])
@pytest.mark.parametrize("command", COMMANDS)
def test_an_atlas_in_a_read_only_folder_is_read_untouched(tmp_path, capsys, reference, immutable, command, mode):
    folder = tmp_path / "atlas"
    folder.mkdir()
    db = folder / "atlas.sqlite"
    shutil.copyfile(reference.path, db)
    if mode == "wal":
        wal_mode(db)
    assert db.read_bytes()[18] == {"delete": 1, "wal": 2}[mode]  # a complete build ends in DELETE mode
    immutable(db, folder)
    before = snapshot(folder)
    # a complete atlas is one file, read mode=ro; a WAL-mode one with nothing to apply, immutable=1
    rc, out, err = run(capsys, *argv(command, str(db), tmp_path, reference.candidate))
    if command == "build" and mode == "wal":
        # a writer of a WAL-mode file needs its -shm index, which it cannot make here
        assert rc == 2 and out == "" and err.count("\n") == 1 and "unable to open database file" in err, err
    else:
        # build: the same sweep, complete: nothing to write (a query at the default band may
        # add the one line naming a tighter band that also answers)
        rest = [line for line in err.splitlines() if not line.startswith("dwell: a stiller rest exists: ")]
        assert rc == 0 and rest == [], err
    assert snapshot(folder) == before


def test_a_killed_write_that_journaled_no_first_page_is_refused_by_every_command(tmp_path, capsys, reference):
    """A write by another program killed half-way (changed pages spilled into the file) leaves a
    hot ``-journal`` that holds no copy of page 1, so nothing in it shows it is this atlas's:
    every command refuses it untouched, ``atlas build`` included (rolling back a foreign journal
    would overwrite the atlas). The atlas's own writers always journal page 1 (db.sidefiles);
    their journals are rolled back by a build (tests/faults/test_side_files.py)."""
    folder = tmp_path / "atlas"
    folder.mkdir()
    db = folder / "atlas.sqlite"
    shutil.copyfile(reference.path, db)
    writer = (
        "import os, signal, sqlite3, sys\n"
        "con = sqlite3.connect(sys.argv[1], isolation_level=None)\n"
        "con.execute('PRAGMA cache_size=1')\n"  # changed pages spill into the file itself
        "con.execute('BEGIN')\n"
        "con.execute('UPDATE dwell SET x = x + 1')\n"
        "os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    proc = subprocess.run([sys.executable, "-c", writer, str(db)])
    assert proc.returncode == -9
    assert Path(f"{db}-journal").stat().st_size > 0
    before = snapshot(folder)
    for command in COMMANDS:
        rc, out, err = run(capsys, *argv(command, str(db), tmp_path, reference.candidate))
        assert rc == 2 and out == "" and err.count("\n") == 1, err
        assert "holds no copy of the atlas's first page" in err and "move that file away" in err, err
        assert snapshot(folder) == before
