"""The files beside an atlas (``-journal``, ``-wal``, ``-shm``): another database's are refused
by every command — ``dwell atlas build`` included — in one line with every file in the folder
byte-identical; the atlas's own, left by a kill, are recovered and the build resumes to the
content of an uninterrupted one (docs/atlas-files.md).

Two kinds of atlas: a complete one (rollback mode, one file) and an interrupted build (WAL
mode, the last shard missing). Foreign side files come from another database with the same
page size, or from another atlas of the same schema (another atlas id), made by a real
SQLite writer that is SIGKILLed in the middle of a write.
"""

from __future__ import annotations

import json
import os
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from harness.processes import N_SHARDS, QUERY, SMALL, info, kill_group, run, spawn
from test_bad_atlases import snapshot, unfinished, wal_mode

from db.engine import SQLITE_PAGE_SIZE
from db.sidefiles import ATLAS_ID_OFFSET

COMMANDS = {
    "info": ["atlas", "info"],
    "verify": ["atlas", "info", "--verify"],
    "query": ["query", *QUERY],
    "report": ["report"],
    "bench coverage": ["bench", "coverage", "--family", "rpr", "--no-refine"],
    "build": ["atlas", "build", *SMALL, "--workers", "1", "--no-progress"],
}


def _argv(name: str, db: Path, out: Path, candidate: str) -> list[str]:
    argv = COMMANDS[name] + ["--db", str(db)]
    if name == "report":
        argv += ["--candidates", candidate, "--out", str(out / "report")]
    return argv


def _atlas_id(path: Path) -> int:
    return int.from_bytes(path.read_bytes()[ATLAS_ID_OFFSET : ATLAS_ID_OFFSET + 4], "big")


def _killed_write(path: Path, *statements: str, page_one: bool = True) -> None:
    """SIGKILL a rollback-mode SQLite writer of ``path`` in the middle of a transaction that
    spilled changed pages into the file (``cache_size=1``): a hot ``-journal`` is left. With
    ``page_one`` the transaction writes page 1 first (``user_version`` rewritten with its own
    value, as the atlas's writers do), so the journal holds a copy of it."""
    script = (
        "import os, signal, sqlite3, sys\n"
        "con = sqlite3.connect(sys.argv[1], isolation_level=None)\n"
        "con.execute('PRAGMA cache_size=1')\n"
        "con.execute('BEGIN')\n"
        + (
            "v = con.execute('PRAGMA user_version').fetchone()[0]\ncon.execute(f'PRAGMA user_version={v}')\n"
            if page_one
            else ""
        )
        + "".join(f"con.execute({s!r})\n" for s in statements)
        + "os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    proc = subprocess.run([sys.executable, "-c", script, str(path)])
    assert proc.returncode == -9
    assert Path(f"{path}-journal").stat().st_size > 0


def _other_database(folder: Path) -> Path:
    """A database of another application, with the atlas's page size and some rows."""
    other = folder / "other.sqlite"
    con = sqlite3.connect(other)
    con.execute(f"PRAGMA page_size={SQLITE_PAGE_SIZE}")
    con.execute("PRAGMA user_version=7")
    con.execute("create table t (x, y)")
    con.executemany("insert into t values (?, ?)", [(i, "y" * 500) for i in range(2000)])
    con.commit()
    con.close()
    return other


def _other_atlas(reference: Path, folder: Path, *, wal: bool = False) -> Path:
    """Another atlas of the same schema and sweep: a copy of the reference with another atlas
    id and one more shard missing (so its content differs)."""
    other = folder / "other.sqlite"
    shutil.copyfile(reference, other)
    unfinished(other)
    con = sqlite3.connect(other)
    con.execute(f"PRAGMA user_version={_atlas_id(reference) ^ 0x5A5A5A}")
    con.commit()
    con.close()
    if wal:
        wal_mode(other)
    return other


def _journal_of(make, folder: Path, *statements: str, page_one: bool = True) -> bytes:
    work = folder / "work"
    work.mkdir()
    other = make(work)
    _killed_write(other, *statements, page_one=page_one)
    data = Path(f"{other}-journal").read_bytes()
    shutil.rmtree(work)
    return data


def _wal_of(make, folder: Path, *statements: str) -> bytes:
    """The -wal of a WAL-mode database made by ``make`` after one committed transaction that
    writes page 1 (as the atlas's writers do), taken while its writer still had it open."""
    work = folder / "work"
    work.mkdir()
    other = make(work)
    con = sqlite3.connect(other, isolation_level=None)
    assert con.execute("PRAGMA journal_mode=WAL").fetchone()[0] == "wal"
    con.execute("PRAGMA wal_autocheckpoint=0")
    con.execute("BEGIN")
    v = con.execute("PRAGMA user_version").fetchone()[0]
    con.execute(f"PRAGMA user_version={v}")
    for s in statements:
        con.execute(s)
    con.execute("COMMIT")
    data = Path(f"{other}-wal").read_bytes()
    con.close()
    shutil.rmtree(work)
    return data


def _interrupted(path: Path) -> None:
    """An interrupted build: the last shard missing, WAL mode, no log beside it."""
    unfinished(path)
    wal_mode(path)


DELETE_OTHER = "delete from shard where shard_index = 0"
UPDATE_OTHER = "update t set y = 'z' || y"

#: case → (make the atlas from a copy of the reference, the side file's suffix, its bytes from
#: (reference, scratch folder), the words the refusal must hold)
CASES = {
    "complete + journal of another database": (
        None,
        "-journal",
        lambda ref, tmp: _journal_of(_other_database, tmp, UPDATE_OTHER),
        "not the atlas's own rollback journal",
    ),
    "complete + journal of another database, no page 1": (
        None,
        "-journal",
        lambda ref, tmp: _journal_of(_other_database, tmp, UPDATE_OTHER, page_one=False),
        "holds no copy of the atlas's first page",
    ),
    "complete + journal of another atlas": (
        None,
        "-journal",
        lambda ref, tmp: _journal_of(lambda w: _other_atlas(ref, w), tmp, "update dwell set x = x + 1"),
        "its copy of the first page is another database's",
    ),
    "interrupted + journal of another database": (
        _interrupted,
        "-journal",
        lambda ref, tmp: _journal_of(_other_database, tmp, UPDATE_OTHER),
        "not the atlas's own rollback journal",
    ),
    "interrupted + journal of another atlas": (
        _interrupted,
        "-journal",
        lambda ref, tmp: _journal_of(lambda w: _other_atlas(ref, w), tmp, "update dwell set x = x + 1"),
        "not the atlas's own rollback journal",
    ),
    "interrupted + wal of another database": (
        _interrupted,
        "-wal",
        lambda ref, tmp: _wal_of(_other_database, tmp, UPDATE_OTHER),
        "not the atlas's own write-ahead log",
    ),
    "interrupted + wal of another interrupted atlas": (
        _interrupted,
        "-wal",
        lambda ref, tmp: _wal_of(lambda w: _other_atlas(ref, w, wal=True), tmp, DELETE_OTHER),
        "not the atlas's own write-ahead log",
    ),
    "complete + wal of another atlas": (
        None,
        "-wal",
        lambda ref, tmp: _wal_of(lambda w: _other_atlas(ref, w, wal=True), tmp, DELETE_OTHER),
        "is a complete atlas",
    ),
}


@pytest.mark.parametrize("case", CASES)
def test_a_side_file_of_another_database_is_refused_by_every_command_untouched(tmp_path, capsys, reference, case):
    make, suffix, side, words = CASES[case]
    folder = tmp_path / "atlas"
    folder.mkdir()
    db = folder / "atlas.sqlite"
    shutil.copyfile(reference.path, db)
    if make is not None:
        make(db)
    Path(f"{db}{suffix}").write_bytes(side(reference.path, tmp_path))
    before = snapshot(folder)
    for name in COMMANDS:
        rc, out, err = run(capsys, *_argv(name, db, tmp_path, reference.candidate))
        assert rc == 2 and out == "", (name, err)
        assert err.startswith("dwell: error: ") and err.count("\n") == 1 and words in err, (name, err)
        assert "move that file away" in err, (name, err)
        assert snapshot(folder) == before, (name, "files changed on the way to an error")
    assert not (tmp_path / "report").exists()
    # the atlas is whole: the refused file moved away, it reads as before
    Path(f"{db}{suffix}").unlink()
    doc = info(capsys, str(db))
    assert doc["build"]["shards_done"] == (N_SHARDS if make is None else N_SHARDS - 1)


def test_the_atlass_own_journal_after_a_kill_is_rolled_back_by_a_build(tmp_path, capsys, reference):
    """A write killed half-way in rollback mode — as the switch of a complete atlas to WAL
    mode at the start of ``--replace`` or a resume could be — leaves the atlas's own hot
    journal: readers refuse it untouched (they may not write), the next build rolls it back
    and finds the atlas complete, with the reference's content."""
    folder = tmp_path / "atlas"
    folder.mkdir()
    db = folder / "atlas.sqlite"
    shutil.copyfile(reference.path, db)
    _killed_write(db, "UPDATE dwell SET x = x + 1")
    before = snapshot(folder)
    for name in ("info", "query", "report"):
        rc, out, err = run(capsys, *_argv(name, db, tmp_path, reference.candidate))
        assert rc == 2 and out == "" and err.count("\n") == 1 and "has an unfinished write" in err, err
        assert snapshot(folder) == before
    rc, out, err = run(capsys, *_argv("build", db, tmp_path, reference.candidate))
    assert rc == 0 and "already complete" in out, err
    assert not Path(f"{db}-journal").exists()
    rc, out, err = run(capsys, "atlas", "info", "--db", str(db), "--verify", "--json")
    assert rc == 0, err
    assert json.loads(out)["verify"]["ok"] and json.loads(out)["content_digest"] == reference.digest


def test_the_atlass_own_journal_beside_an_interrupted_build_is_rolled_back_and_the_build_resumes(
    tmp_path, capsys, reference
):
    folder = tmp_path / "atlas"
    folder.mkdir()
    db = folder / "atlas.sqlite"
    shutil.copyfile(reference.path, db)
    unfinished(db)  # rollback mode: as an interrupted build is just before its switch to WAL mode
    _killed_write(db, "UPDATE dwell SET x = x + 1")
    rc, out, err = run(capsys, *_argv("build", db, tmp_path, reference.candidate))
    assert rc == 0 and "complete" in out and " 1 shard(s) in" in out, (out, err)
    doc = info(capsys, str(db))
    assert doc["build"]["status"] == "complete" and doc["content_digest"] == reference.digest


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc (Linux)")
def test_the_atlass_own_wal_after_a_kill_is_read_and_the_build_resumes(tmp_path, capsys, reference):
    """A build SIGKILLed right after its second shard commit: the shards are in its ``-wal``
    only. Every reader takes the log as the atlas's own (its first transaction names the
    atlas), a foreign ``-shm`` beside it changes nothing, and the build resumes from there to
    the reference's content."""
    folder = tmp_path / "atlas"
    folder.mkdir()
    db = folder / "atlas.sqlite"
    proc = spawn(folder, str(db), "--workers", "1", kill_after_shards=2)
    proc.wait(timeout=300)  # it kills itself
    alive, err = kill_group(proc, timeout=60)
    assert proc.returncode == -9 and alive == [], err
    wal = Path(f"{db}-wal")
    assert wal.stat().st_size > 0 and _atlas_id(db) != 0
    shm = Path(f"{db}-shm")
    if shm.exists():  # another process's index in its place: SQLite rebuilds it from the log
        shm.write_bytes(os.urandom(shm.stat().st_size))
    doc = info(capsys, str(db))
    assert doc["build"]["status"] == "building" and doc["build"]["shards_done"] == 2
    rc, out, err = run(capsys, "query", "--db", str(db), *QUERY, "--json")
    assert rc in (0, 1, 2) and "Traceback" not in err, err  # 1: nothing found in a partial atlas
    rc, out, err = run(capsys, *_argv("build", db, tmp_path, reference.candidate))
    assert rc == 0 and f" {N_SHARDS - 2} shard(s) in" in out, (out, err)
    doc = info(capsys, str(db))
    assert doc["build"]["status"] == "complete" and doc["content_digest"] == reference.digest


def test_a_log_or_journal_that_applies_nothing_is_harmless(tmp_path, capsys, reference):
    """A ``-wal`` of the atlas's page size holding no complete transaction, and a ``-journal``
    whose header SQLite would not replay (first byte 0), are left to SQLite: nothing of them
    reaches the atlas."""
    folder = tmp_path / "atlas"
    folder.mkdir()
    db = folder / "atlas.sqlite"
    shutil.copyfile(reference.path, db)
    _interrupted(db)
    wal = bytearray(_wal_of(_other_database, tmp_path, UPDATE_OTHER))
    frame = 24 + SQLITE_PAGE_SIZE
    for at in range(32, len(wal), frame):  # no frame is a commit frame any more
        wal[at + 4 : at + 8] = bytes(4)
    Path(f"{db}-wal").write_bytes(bytes(wal))
    Path(f"{db}-journal").write_bytes(bytes(600))
    doc = info(capsys, str(db))
    assert doc["build"]["shards_done"] == N_SHARDS - 1
