"""db.sidefiles: whose a rollback journal or write-ahead log is, read as SQLite would apply it.

Real journals and logs, made by SQLite writers SIGKILLed in the middle of a write (journals)
or stopped with their log open (WAL), against the page 1 of the atlas beside them.
"""

from __future__ import annotations

import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from db import open_atlas
from db.engine import SQLITE_PAGE_SIZE
from db.sidefiles import Ownership, atlas_id, journal_verdict, read_page_one, wal_verdict


def _database(path: Path, user_version: int) -> Path:
    con = sqlite3.connect(path)
    con.execute(f"PRAGMA page_size={SQLITE_PAGE_SIZE}")
    con.execute(f"PRAGMA user_version={user_version}")
    con.execute("create table t (x)")
    con.executemany("insert into t values (?)", [("x" * 300,)] * 400)
    con.commit()
    con.close()
    return path


def _killed(path: Path, *, page_one: bool) -> bytes:
    """The hot journal of a write to ``path`` killed after it spilled pages into the file."""
    script = (
        "import os, signal, sqlite3, sys\n"
        "con = sqlite3.connect(sys.argv[1], isolation_level=None)\n"
        "con.execute('PRAGMA cache_size=1'); con.execute('BEGIN')\n"
        + (
            "v = con.execute('PRAGMA user_version').fetchone()[0]; con.execute(f'PRAGMA user_version={v}')\n"
            if page_one
            else ""
        )
        + "con.execute('update t set x = upper(x)')\n"  # same sizes: page 1 untouched by the rows
        "os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    assert subprocess.run([sys.executable, "-c", script, str(path)]).returncode == -9
    return Path(f"{path}-journal").read_bytes()


def test_a_new_atlas_is_named_in_its_file(tmp_path):
    path = tmp_path / "a.sqlite"
    open_atlas(str(path), create=True).dispose()
    first = atlas_id(read_page_one(path))
    assert 0 < first < 2**31
    other = tmp_path / "b.sqlite"
    open_atlas(str(other), create=True).dispose()
    assert atlas_id(read_page_one(other)) not in (0, first)  # 1 in 2^31 to fail
    open_atlas(str(path), create=True).dispose()
    assert atlas_id(read_page_one(path)) == first  # kept when opened again


@pytest.mark.parametrize("page_one", [True, False])
def test_a_journal_is_its_databases_only_with_a_copy_of_page_one(tmp_path, page_one):
    mine = _database(tmp_path / "mine.sqlite", 11)
    copy = tmp_path / "copy.sqlite"
    shutil.copyfile(mine, copy)
    journal = tmp_path / "j"
    journal.write_bytes(_killed(mine, page_one=page_one))
    page, size = read_page_one(mine), mine.stat().st_size
    want = Ownership.OWN if page_one else Ownership.FOREIGN
    assert journal_verdict(journal, page, size).ownership is want
    # beside another database (another id, same page size and schema): never its own
    other = _database(tmp_path / "other.sqlite", 12)
    verdict = journal_verdict(journal, read_page_one(other), other.stat().st_size)
    assert verdict.ownership is Ownership.FOREIGN and verdict.why
    # a journal whose first byte is 0 is not hot; a missing one absent
    journal.write_bytes(bytes(100))
    assert journal_verdict(journal, page, size).ownership is Ownership.ABSENT
    assert journal_verdict(tmp_path / "none", page, size).ownership is Ownership.ABSENT


def test_a_journal_that_replays_nothing_is_harmless_only_if_it_keeps_the_size(tmp_path):
    mine = _database(tmp_path / "mine.sqlite", 11)
    data = bytearray(_killed(mine, page_one=True))
    data[8:12] = bytes(4)  # nRec 0: the header was written, no record synced
    journal = tmp_path / "j"
    journal.write_bytes(bytes(data))
    page = read_page_one(mine)
    pages = int.from_bytes(data[16:20], "big")
    assert journal_verdict(journal, page, pages * SQLITE_PAGE_SIZE).ownership is Ownership.HARMLESS
    assert journal_verdict(journal, page, (pages + 3) * SQLITE_PAGE_SIZE).ownership is Ownership.FOREIGN


def _wal(path: Path) -> bytes:
    con = sqlite3.connect(path, isolation_level=None)
    con.execute("PRAGMA journal_mode=WAL")
    con.execute("PRAGMA wal_autocheckpoint=0")
    con.execute("BEGIN")
    v = con.execute("PRAGMA user_version").fetchone()[0]
    con.execute(f"PRAGMA user_version={v}")
    con.execute("insert into t values ('z')")
    con.execute("COMMIT")
    data = Path(f"{path}-wal").read_bytes()
    con.close()
    return data


def test_a_wal_is_its_databases_when_its_first_transaction_names_it(tmp_path):
    mine = _database(tmp_path / "mine.sqlite", 11)
    other = _database(tmp_path / "other.sqlite", 12)
    wal = tmp_path / "w"
    wal.write_bytes(_wal(mine))
    assert wal_verdict(wal, read_page_one(mine)).ownership is Ownership.OWN
    verdict = wal_verdict(wal, read_page_one(other))
    assert verdict.ownership is Ownership.FOREIGN and "not the atlas's" in verdict.why
    data = bytearray(wal.read_bytes())
    data[32 + 4 : 32 + 8] = bytes(4)  # the first frame no commit frame: with one frame, nothing is applied
    frames = (len(data) - 32) // (24 + SQLITE_PAGE_SIZE)
    for i in range(frames):
        at = 32 + i * (24 + SQLITE_PAGE_SIZE)
        data[at + 4 : at + 8] = bytes(4)
    wal.write_bytes(bytes(data))
    assert wal_verdict(wal, read_page_one(other)).ownership is Ownership.HARMLESS
    wal.write_bytes(b"not a log at all" * 4)
    assert wal_verdict(wal, read_page_one(other)).ownership is Ownership.ABSENT
