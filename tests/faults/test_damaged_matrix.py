"""The damaged-atlas matrix: every way of spoiling a copy of the reference atlas (a column
dropped or renamed in each table, orphaned rows, an unreadable sweep spec, a deleted build
row, seeded single-bit flips in page data, truncation, foreign and stale ``-wal`` files) under
``atlas info``, ``atlas info --verify``, ``query``, ``report`` and ``atlas build`` (a resume):
exit status 0 or 2, at most one line on stderr, never a traceback, and after an error every
file in the atlas's folder byte-identical (nothing created). ``--verify`` must refuse every
bit flip that changed the atlas's content (its digest) or its b-tree structure.
"""

from __future__ import annotations

import random
import shutil
import sqlite3
from pathlib import Path

import pytest
from harness.processes import QUERY, SMALL, run
from test_bad_atlases import snapshot

from db import open_atlas
from db.digest import content_digest

#: table → the column dropped or renamed in it
COLUMNS = {
    "dwell": "phi_start",
    "segment": "phi_gen2",
    "linkage": "grashof",
    "build": "finished_at",
    "shard": "seconds",
    "meta": "value",
}
#: seeded single-bit flips in page data (past the 100-byte file header)
N_FLIPS = 24
FLIP_SEED = 17


def _sql(path: Path, *statements: str) -> None:
    con = sqlite3.connect(path)  # the sqlite3 module leaves foreign keys off: damage is possible
    con.execute("PRAGMA legacy_alter_table=ON")  # other tables' references stay as they were
    for sql in statements:
        con.execute(sql)
    con.commit()
    con.close()


def _columns(path: Path, table: str) -> list[str]:
    con = sqlite3.connect(path)
    try:
        return [r[1] for r in con.execute(f"PRAGMA table_info({table})")]
    finally:
        con.close()


def _drop(table: str, column: str):
    def spoil(path: Path) -> None:
        keep = ", ".join(c for c in _columns(path, table) if c != column)
        _sql(
            path,
            f"ALTER TABLE {table} RENAME TO {table}_old",
            f"CREATE TABLE {table} AS SELECT {keep} FROM {table}_old",
            f"DROP TABLE {table}_old",
        )

    return spoil


def _rename(table: str, column: str):
    return lambda path: _sql(path, f"ALTER TABLE {table} RENAME COLUMN {column} TO {column}_renamed")


def _flip(seed: int):
    def spoil(path: Path) -> None:
        data = bytearray(path.read_bytes())
        rng = random.Random(f"{FLIP_SEED}:{seed}")
        offset = rng.randrange(100, len(data))
        data[offset] ^= 1 << rng.randrange(8)
        path.write_bytes(bytes(data))

    return spoil


def _wal_of(path: Path, change: str, **pragmas: int) -> bytes:
    """The -wal of a copy of ``path`` (or of a fresh database if ``change`` is "foreign") after one change."""
    other = path.with_name("other.sqlite")
    if change == "foreign":
        con = sqlite3.connect(other)
        for k, v in pragmas.items():
            con.execute(f"PRAGMA {k}={v}")
        con.execute("PRAGMA journal_mode=WAL")
        con.execute("PRAGMA wal_autocheckpoint=0")
        con.execute("create table t(x)")
        con.execute("insert into t values (1)")
    else:  # the same atlas, later: a stale log from a copy
        shutil.copyfile(path, other)
        con = sqlite3.connect(other)
        con.execute("PRAGMA journal_mode=WAL")
        con.execute("PRAGMA wal_autocheckpoint=0")
        con.execute("update dwell set x = x + 1")
    con.commit()
    wal = Path(f"{other}-wal").read_bytes()
    con.close()
    for p in other.parent.glob("other.sqlite*"):
        p.unlink()
    return wal


def _beside(change: str, *, wal_mode: bool = False, **pragmas: int):
    def spoil(path: Path) -> None:
        wal = _wal_of(path, change, **pragmas)
        if wal_mode:
            con = sqlite3.connect(path)
            con.execute("PRAGMA journal_mode=WAL")
            con.close()
        Path(f"{path}-wal").write_bytes(wal)

    return spoil


CASES = {
    **{f"drop-{t}.{c}": _drop(t, c) for t, c in COLUMNS.items()},
    **{f"rename-{t}.{c}": _rename(t, c) for t, c in COLUMNS.items()},
    "orphaned-dwells": lambda p: _sql(p, "DELETE FROM segment WHERE id % 2 = 0"),
    "orphaned-segments": lambda p: _sql(p, "DELETE FROM linkage WHERE id % 2 = 0"),
    "garbage-spec": lambda p: _sql(p, "UPDATE build SET spec_json = '{\"tolerances\": [0.01,'"),
    "garbage-skipped": lambda p: _sql(p, "UPDATE shard SET skipped_json = 'nope' WHERE shard_index = 1"),
    "deleted-build-row": lambda p: _sql(p, "DELETE FROM build"),
    "truncated": lambda p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]),
    "truncated-to-a-page": lambda p: p.write_bytes(p.read_bytes()[:4096]),
    "foreign-wal": _beside("foreign"),
    "stale-wal-of-the-same-atlas": _beside("later"),
    "foreign-wal-other-page-size-beside-wal-mode": _beside("foreign", wal_mode=True, page_size=1024),
    **{f"bit-flip-{i}": _flip(i) for i in range(N_FLIPS)},
}

COMMANDS = {
    "info": ["atlas", "info"],
    "verify": ["atlas", "info", "--verify"],
    "query": ["query", *QUERY],
    "report": ["report", *QUERY[:4]],
    "build": ["atlas", "build", *SMALL, "--workers", "1", "--no-progress"],
}


def _content(path: Path) -> str | None:
    """The content digest of a scratch copy of ``path`` (None if its rows cannot be read)."""
    scratch = path.with_name("scratch.sqlite")
    shutil.copyfile(path, scratch)
    try:
        engine = open_atlas(str(scratch), readonly=True)
        try:
            return content_digest(engine)
        finally:
            engine.dispose()
    except Exception:  # noqa: BLE001 - any failure to read counts as changed content
        return None
    finally:
        for p in path.parent.glob("scratch.sqlite*"):
            p.unlink()


def _quick_check(path: Path) -> str:
    """SQLite's read-only ``quick_check`` of ``path``: "ok" or its first complaint."""
    try:
        con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
        try:
            return con.execute("PRAGMA quick_check(1)").fetchone()[0]
        finally:
            con.close()
    except sqlite3.Error as exc:
        return str(exc)


#: (case → verify's exit status, content changed) — filled by the bit-flip cases, summed at the end
FLIPS: dict[str, tuple[int, bool]] = {}


@pytest.mark.parametrize("case", CASES)
def test_a_damaged_atlas_is_refused_in_one_line_untouched(tmp_path, capsys, reference, case):
    folder = tmp_path / "atlas"
    folder.mkdir()
    db = folder / "atlas.sqlite"
    shutil.copyfile(reference.path, db)
    CASES[case](db)
    changed = malformed = None
    if case.startswith("bit-flip"):
        work = tmp_path / "work"
        work.mkdir()
        shutil.copyfile(db, work / "atlas.sqlite")
        changed = _content(work / "atlas.sqlite") != reference.digest
        malformed = _quick_check(work / "atlas.sqlite") != "ok"
    out_dir = tmp_path / "out"
    out_dir.mkdir()  # the report's folder is fine: the atlas is what gets refused
    for name, argv in COMMANDS.items():
        extra = ["--out", str(out_dir / name)] if name == "report" else []
        if name == "report":
            argv = ["report", "--candidates", reference.candidate]
        before = snapshot(folder)
        rc, out, err = run(capsys, *argv, "--db", str(db), *extra)
        assert rc in (0, 1, 2) and (rc != 1 or name == "query"), (name, rc, err)  # 1: a query found none
        assert "Traceback" not in err and err.count("\n") <= {0: 2, 1: 4, 2: 1}[rc], (name, err)
        if rc == 2:
            assert err.startswith("dwell: error: ") and err.count("\n") == 1, (name, err)
            assert snapshot(folder) == before, (name, "files changed on the way to an error")
        if malformed:  # every command runs the structure check a small atlas can afford
            assert rc == 2 and "damaged" in err, (name, "answered from an atlas whose structure check fails", err)
        if name == "verify" and changed is not None:
            FLIPS[case] = (rc, changed)
            if changed:
                assert rc == 2, f"--verify missed a bit flip that changed the content ({case})"
        if case == "deleted-build-row":  # every command: not a "no six-bar" answer from a gutted atlas
            assert rc == 2 and "build 1, which has no row" in err, (name, err)
        if name == "verify" and not case.startswith("bit-flip"):
            assert rc == 2, (case, "--verify passed a damaged atlas")


def test_bit_flip_tally(capsys):
    """Runs after the matrix (same module): how many flips changed content, how many --verify refused."""
    flips = {k: v for k, v in FLIPS.items()}
    if not flips:
        pytest.skip("the bit-flip cases did not run")
    changed = sum(c for _, c in flips.values())
    refused = sum(rc == 2 for rc, _ in flips.values())
    refused_changed = sum(rc == 2 and c for rc, c in flips.values())
    with capsys.disabled():
        print(
            f"\nbit flips: {len(flips)}; content changed: {changed}; --verify refused {refused_changed}/{changed} "
            f"of those, {refused}/{len(flips)} in all"
        )
    assert refused_changed == changed


# ---------------------------------------------------------------------------------------------
# Damage a plain read may miss: each command's answer, with the whole structure check (a small
# atlas) and with the bounded one of a big atlas (WHOLE_CHECK_BYTES = 0)
# ---------------------------------------------------------------------------------------------


def _unchecked(path: Path, *statements: str) -> None:
    """``statements`` with CHECK constraints off: damage a bit flip could do."""
    _sql(path, "PRAGMA ignore_check_constraints=ON", *statements)


def _numeric_kind(path: Path) -> None:
    """An integer stored in the text column ``segment.kind`` (what one flipped bit in a record
    header does): the column declared INTEGER for the update, then as it was."""
    con = sqlite3.connect(path)
    sql = con.execute("SELECT sql FROM sqlite_master WHERE name = 'segment'").fetchone()[0]
    con.execute("PRAGMA writable_schema=ON")
    con.execute(
        "UPDATE sqlite_master SET sql = ? WHERE name = 'segment'", (sql.replace("kind VARCHAR(12)", "kind INTEGER", 1),)
    )
    con.commit()
    con.close()
    con = sqlite3.connect(path)
    con.execute("PRAGMA ignore_check_constraints=ON")
    con.execute("UPDATE segment SET kind = 7 WHERE id = (SELECT min(id) FROM segment)")
    con.commit()
    con.execute("PRAGMA writable_schema=ON")
    con.execute("UPDATE sqlite_master SET sql = ? WHERE name = 'segment'", (sql,))
    con.commit()
    con.close()
    assert sqlite3.connect(path).execute("SELECT count(*) FROM segment WHERE typeof(kind) = 'integer'").fetchone() == (
        1,
    )


ALL = frozenset(COMMANDS)
#: case → (spoil, the commands that must refuse it with either check, the words of --verify's refusal)
SUBTLE = {
    "numeric-segment-kind": (_numeric_kind, {"verify"}, "segment.kind"),
    "invalid-utf8-segment-kind": (
        lambda p: _unchecked(
            p, "UPDATE segment SET kind = CAST(x'fffe1b5b32' AS TEXT) WHERE id = (SELECT min(id) FROM segment)"
        ),
        {"info", "verify"},
        "Could not decode to UTF-8",
    ),
    "deleted-shard-row": (
        lambda p: _sql(p, "DELETE FROM shard WHERE shard_index = 1"),
        ALL,
        "build 1 is complete with",
    ),
    "spec-samples-many": (
        lambda p: _sql(p, "UPDATE build SET spec_json = json_set(spec_json, '$.samples', 'many')"),
        ALL,
        "samples is 'many'",
    ),
    "spec-samples-1e308": (
        lambda p: _sql(p, "UPDATE build SET spec_json = json_set(spec_json, '$.samples', 1e308)"),
        ALL,
        "samples is 1e+308",
    ),
    "spec-tolerance-text": (
        lambda p: _sql(p, "UPDATE build SET spec_json = json_set(spec_json, '$.tolerances[0]', 'x')"),
        ALL,
        "tolerances is 'x'",
    ),
    "unknown-build-status": (
        lambda p: _unchecked(p, "UPDATE build SET status = 'paused'"),
        ALL,
        "unknown status 'paused'",
    ),
    "altered-shard-digest": (
        lambda p: _sql(p, f"UPDATE shard SET digest = '{'0' * 64}' WHERE shard_index = 2"),
        {"verify"},
        "rows of shard(s) 2 do not give the digest stored",
    ),
    "orphaned-dwell-rows": (
        lambda p: _sql(p, "DELETE FROM segment WHERE id % 2 = 0"),
        {"verify", "query"},
        "dwell row(s) name a segment that does not exist",
    ),
}


@pytest.mark.parametrize("whole", [True, False], ids=["whole-check", "bounded-check"])
@pytest.mark.parametrize("case", SUBTLE)
def test_damage_a_plain_read_may_miss_is_refused_where_it_matters(
    tmp_path, capsys, reference, monkeypatch, case, whole
):
    import db.engine

    if not whole:
        monkeypatch.setattr(db.engine, "WHOLE_CHECK_BYTES", 0)
    spoil, refusers, words = SUBTLE[case]
    folder = tmp_path / "atlas"
    folder.mkdir()
    db_path = folder / "atlas.sqlite"
    shutil.copyfile(reference.path, db_path)
    spoil(db_path)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    for name, argv in COMMANDS.items():
        extra = ["--out", str(out_dir / name)] if name == "report" else []
        if name == "report":
            argv = ["report", "--candidates", reference.candidate]
        before = snapshot(folder)
        rc, out, err = run(capsys, *argv, "--db", str(db_path), *extra)
        assert rc in (0, 1, 2) and (rc != 1 or name == "query") and "Traceback" not in err, (name, rc, err)
        assert err.isprintable() or err.endswith("\n") and err[:-1].isprintable(), (name, err)  # no raw bytes
        if rc == 2:
            assert err.startswith("dwell: error: ") and err.count("\n") == 1, (name, err)
            assert snapshot(folder) == before, (name, "files changed on the way to an error")
        if name in refusers:
            assert rc == 2 and "damaged" in err, (name, err)
        if name == "verify":
            assert words in err, err
        if name == "build" and rc == 2:
            assert "another builder" not in err and "taken over" not in err, err


def test_a_symlink_loop_as_db_is_one_line(tmp_path, capsys):
    loop = tmp_path / "loop.sqlite"
    loop.symlink_to(tmp_path / "other.sqlite")
    (tmp_path / "other.sqlite").symlink_to(loop)
    for argv in (["atlas", "info"], ["atlas", "info", "--verify"], ["query", *QUERY], ["atlas", "build", *SMALL]):
        rc, out, err = run(capsys, *argv, "--db", str(loop))
        assert rc == 2 and out == "" and err.count("\n") == 1 and "symlink loop" in err, (argv, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["loop.sqlite", "other.sqlite"]
