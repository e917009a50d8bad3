"""``dwell atlas build`` / ``info``: kill and resume, Ctrl-C, concurrent builders, another
sweep and --replace, bad input (exit 2, one line, nothing written), info consistent with the db.

Subprocess tests slow every shard down with a ``sitecustomize`` hook on PYTHONPATH (it also
reaches the worker processes), so that a build can be caught half-way whatever the machine.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import signal
import sqlite3
import time
from pathlib import Path

import pytest
from harness.processes import N_SHARDS, SMALL, SPEC, shard_rows, spawn, wait_for_shards

from atlas.build import build_atlas
from cli.main import main
from db import SCHEMA_VERSION, open_atlas
from db.digest import content_digest


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """An uninterrupted in-process build of the same sweep: (path, content digest)."""
    path = tmp_path_factory.mktemp("ref") / "ref.sqlite"
    build_atlas(str(path), SPEC, workers=1)
    engine = open_atlas(str(path), readonly=True)
    digest = content_digest(engine)
    engine.dispose()
    return path, digest


def dwell(capsys, *args: str) -> tuple[int, str, str]:
    rc = main(["atlas", *args])
    out, err = capsys.readouterr()
    return rc, out, err


def info_json(capsys, db: Path) -> dict:
    rc, out, err = dwell(capsys, "info", "--db", str(db), "--json")
    assert rc == 0, err
    return json.loads(out)


def query(db: Path, sql: str):
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        return con.execute(sql).fetchall()
    finally:
        con.close()


def processes_of(tmp_path: Path) -> list[int]:
    """Live processes started with our hook on their path (the builder, forkserver, workers)."""
    marker = str(tmp_path / "hook").encode()
    pids = []
    for d in Path("/proc").glob("[0-9]*"):
        try:
            if marker in (d / "cmdline").read_bytes() or marker in (d / "environ").read_bytes():
                stat = (d / "stat").read_bytes().rsplit(b")", 1)[1].split()[0]
                if stat != b"Z":
                    pids.append(int(d.name))
        except OSError:
            pass
    return pids


def no_orphans(tmp_path: Path, timeout: float = 10) -> bool:
    deadline = time.monotonic() + timeout
    while processes_of(tmp_path):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.1)
    return True


def shard_table(db: Path) -> dict[int, tuple]:
    return {r[0]: r for r in query(db, "select shard_index, n_linkages, n_segments, skipped_json, seconds from shard")}


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_killed_build_resumes_to_the_same_content(tmp_path, reference, capsys):
    db = tmp_path / "atlas.sqlite"
    proc = spawn(tmp_path, str(db), "--workers", "2", delay=1.0)
    wait_for_shards(str(db), proc, 1)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert no_orphans(tmp_path), "workers outlived the killed builder"
    kept = shard_table(db)
    assert 1 <= len(kept) < N_SHARDS
    status, pid = query(db, "select status, lock_pid from build")[0]
    assert (status, pid) == ("building", proc.pid)  # the dead builder's lock is still there

    again = spawn(tmp_path, str(db), "--workers", "2")
    out, err = again.communicate(timeout=120)
    assert again.returncode == 0, err
    assert f"resuming: {len(kept)} of {N_SHARDS} shards already built" in err
    assert re.fullmatch(
        rf"atlas {re.escape(str(db))} complete: \d+ linkages; segments: line \d+, arc \d+, double_line \d+; "
        rf"{N_SHARDS - len(kept)} shard\(s\) in [\d.]+ s \(\d+ linkages/s\)\n",
        out,
    )
    after = shard_table(db)
    assert {i: after[i] for i in kept} == kept  # what was committed was kept, not recomputed
    doc = info_json(capsys, db)
    assert doc["content_digest"] == reference[1]
    assert doc["build"]["status"] == "complete" and doc["build"]["builder"] is None


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_ctrl_c_and_a_concurrent_builder(tmp_path, reference, capsys):
    db = tmp_path / "atlas.sqlite"
    # 2 s a shard: a few seconds in which the build is surely still running
    proc = spawn(tmp_path, str(db), "--workers", "2", delay=2.0)
    wait_for_shards(str(db), proc, 1)

    # a second builder is refused while the first one runs; nothing changes
    before = shard_table(db)
    rc, out, err = dwell(capsys, "build", "--db", str(db), *SMALL, "--workers", "1")
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith(
        f"dwell: error: atlas {str(db)!r} is being built by another process (pid {proc.pid} on "
    )
    assert set(shard_table(db)) >= set(before)
    # info works while it builds
    doc = info_json(capsys, db)
    assert doc["build"]["status"] == "building" and doc["build"]["builder"]["pid"] == proc.pid

    os.killpg(proc.pid, signal.SIGINT)  # what Ctrl-C in a terminal does: the whole process group
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "interrupted:" in err and "run the same command again to resume" in err
    assert err.rstrip().endswith("dwell: interrupted")
    assert "Traceback" not in err
    assert no_orphans(tmp_path)
    kept = shard_table(db)
    assert 1 <= len(kept) < N_SHARDS
    assert query(db, "select status, lock_token from build") == [("building", None)]  # lock released

    rc, out, err = dwell(capsys, "build", "--db", str(db), *SMALL, "--workers", "1")
    assert rc == 0 and "resuming" in err
    assert info_json(capsys, db)["content_digest"] == reference[1]


def test_info_json_is_consistent_with_the_database(reference, capsys):
    db, digest = reference
    doc = info_json(capsys, db)
    assert doc["linkages"] == query(db, "select count(*) from linkage")[0][0] > 0
    by_kind = dict(query(db, "select kind, count(*) from segment group by kind"))
    assert doc["segments"] == {k: by_kind.get(k, 0) for k in ("line", "arc", "double_line")}
    dwells = dict(query(db, "select kind, count(*) from dwell group by kind"))  # kind: its code
    assert doc["dwells"] == {k: dwells.get(code, 0) for code, k in enumerate(("line", "arc", "double_line"))}
    hist = doc["dwell_histogram"]
    assert hist["bin_deg"] == 10 and len(hist["edges_deg"]) == 37 and hist["edges_deg"][-1] == 360
    assert set(hist["kinds"]) == {"line", "arc", "double_line"}
    per_level = dict(
        ((("line", "arc", "double_line")[k], lvl), n)
        for k, lvl, n in query(db, "select kind, level, count(*) from dwell group by kind, level")
    )
    for kind, levels in hist["kinds"].items():
        assert [lv["level"] for lv in levels] == [0, 1, 2]
        assert [lv["tolerance"] for lv in levels] == list(SPEC.tolerances)
        for lv in levels:
            assert len(lv["counts"]) == 36 and sum(lv["counts"]) == per_level.get((kind, lv["level"]), 0)
    skipped: dict[str, int] = {}
    for (text,) in query(db, "select skipped_json from shard"):
        for reason, n in json.loads(text).items():
            skipped[reason] = skipped.get(reason, 0) + n
    assert doc["skipped"] == skipped
    build = doc["build"]
    assert build["spec"] == json.loads(SPEC.to_json()) and build["spec_digest"] == SPEC.digest
    assert (build["status"], build["shards_done"], build["n_shards"], build["schema_version"]) == (
        "complete",
        N_SHARDS,
        N_SHARDS,
        SCHEMA_VERSION,
    )
    assert build["code_version"] and doc["builds"] == 1
    assert doc["content_digest"] == digest and re.fullmatch(r"[0-9a-f]{64}", digest)
    # storage: the file's pages (no -wal beside a complete atlas), per linkage
    assert doc["storage_bytes"] == db.stat().st_size
    assert doc["bytes_per_linkage"] == round(db.stat().st_size / doc["linkages"], 1)

    rc, out, err = dwell(capsys, "info", "--db", str(db))
    assert rc == 0 and err == ""
    assert (
        f"linkages: {doc['linkages']}\n" in out
        and f"content digest (stored, unchecked; --verify recomputes it): {digest}" in out
    )
    assert f"build 1: complete, {N_SHARDS}/{N_SHARDS} shards" in out
    assert (
        f"storage: {db.stat().st_size / 2**20:.1f} MiB ({db.stat().st_size / doc['linkages'] / 1024:.1f} KiB per linkage)"
        in out
    )


def test_another_sweep_is_refused_then_replaced(tmp_path, capsys):
    db = tmp_path / "a.sqlite"
    tiny = ["--samples", "12", "--shard-size", "8"]
    rc, out, err = dwell(capsys, "build", "--db", str(db), *tiny, "--workers", "1")
    assert rc == 0, err
    old = info_json(capsys, db)
    before = hashlib.sha256(db.read_bytes()).hexdigest()

    rc, out, err = dwell(capsys, "build", "--db", str(db), *tiny, "--seed", "1", "--workers", "1")
    spec_digest = old["build"]["spec_digest"]
    assert rc == 2 and out == ""
    assert err == (
        f"dwell: error: atlas {str(db)!r} was built with a different sweep (preset demo+custom, digest "
        f"{spec_digest[:8]}…); use --replace to rebuild it\n"
    )
    assert hashlib.sha256(db.read_bytes()).hexdigest() == before

    rc, out, err = dwell(capsys, "build", "--db", str(db), *tiny, "--seed", "1", "--workers", "1", "--replace")
    assert rc == 0, err
    assert f"replacing the previous build of {db} (preset demo+custom, digest {spec_digest[:8]}…)" in err
    new = info_json(capsys, db)
    assert new["builds"] == 1 and new["build"]["spec"]["seed"] == 1 and new["build"]["status"] == "complete"
    assert new["content_digest"] != old["content_digest"]
    # every row belongs to the new build
    assert query(db, "select count(*) from linkage where build_id != (select id from build)") == [(0,)]
    assert query(db, "select count(*) from shard where build_id != (select id from build)") == [(0,)]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--preset", "nope"], "Invalid value for '--preset': 'nope' is not one of 'demo', 'large', 'standard'"),
        (["--samples", "-5"], "Invalid value for '--samples': must be a whole number from 1 to 2147483648"),
        (["--b", "3", "2"], "range b must satisfy 0.001 <= low <= high <= 1000 (crank = 1), got (3, 2)"),
        (["--c", "-1", "2"], "Invalid value for '--c': must be 0.001 <= x <= 1000 (a length in cranks), got -1"),
        (["--d", "nan", "2"], "Invalid value for '--d': must be a finite number"),
        (["--crank-step", "0"], "Invalid value for '--crank-step': must be 0.05 <= x <= 30"),
        (["--crank-step", "1e-320"], "Invalid value for '--crank-step': must be 0.05 <= x <= 30"),
        (["--samples", "2147483648"], "would need about 460 GiB of memory"),
        (["--tolerances", "0.01,abc"], "--tolerances must be comma-separated numbers"),
        (["--tolerances", "0.01,0.001"], "tolerances must be in increasing order"),
        (["--min-dwell", "400"], "Invalid value for '--min-dwell': must be 0 < x < 360"),
        (["--shard-size", "0"], "Invalid value for '--shard-size': must be a whole number from 1 to 1000000"),
        (["--workers", "0"], "Invalid value for '--workers'"),
        (["--samples", "many"], "Invalid value for '--samples'"),
    ],
)
def test_bad_sweep_options_write_nothing(tmp_path, capsys, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)  # the default --db lives in the cwd
    rc, out, err = dwell(capsys, "build", *args)
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("dwell: error: ") and message in err
    assert list(tmp_path.iterdir()) == []


def _foreign(path: Path) -> None:
    con = sqlite3.connect(path)
    con.execute("create table things(x)")
    con.execute("insert into things values (1)")
    con.commit()
    con.close()


@pytest.mark.parametrize(
    "case, message",
    [
        ("foreign", "is a database of another application"),
        ("text", "is not an SQLite database"),
        ("folder", "is a folder, not an atlas file"),
        ("no-folder", "does not exist"),
        ("unwritable", "cannot be written"),  # said before SQLite's "unable to open database file"
    ],
)
@pytest.mark.parametrize("command", ["build", "info"])
def test_bad_atlas_paths_are_refused_untouched(tmp_path, capsys, case, message, command):
    target = {
        "foreign": tmp_path / "other.sqlite",
        "text": tmp_path / "notes.txt",
        "folder": tmp_path,
        "no-folder": tmp_path / "none" / "a.sqlite",
        "unwritable": Path("/proc/dwell-atlas-test.sqlite"),
    }[case]
    if case == "foreign":
        _foreign(target)
    elif case == "text":
        target.write_text("not an atlas\n")
    if case == "unwritable" and not Path("/proc").is_dir():
        pytest.skip("no /proc (a folder where nobody, not even root, can create a file)")
    if command == "info" and case in ("no-folder", "unwritable"):
        message = "no atlas at"
    listing = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    extra = ["--samples", "8"] if command == "build" else []
    rc, out, err = dwell(capsys, command, "--db", str(target), *extra)
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("dwell: error: ") and message in err, err
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == listing  # byte-identical, nothing new
    assert not Path("/proc/dwell-atlas-test.sqlite").exists()


def test_default_db_is_atlas_sqlite_in_the_cwd(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("DWELL_ATLAS", raising=False)
    rc, out, err = dwell(capsys, "build", "--samples", "12", "--shard-size", "8", "--workers", "1")
    assert rc == 0, err
    assert out.startswith("atlas atlas.sqlite complete: ")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["atlas.sqlite"]
    rc, out, err = dwell(capsys, "build", "--samples", "12", "--shard-size", "8")
    assert rc == 0 and out.startswith("atlas atlas.sqlite is already complete: ")
    monkeypatch.setenv("DWELL_ATLAS", str(tmp_path / "env.sqlite"))
    assert info_json(capsys, tmp_path / "atlas.sqlite")["build"]["status"] == "complete"
    rc, out, err = dwell(capsys, "info")
    assert rc == 2 and "no atlas at" in err and "env.sqlite" in err


# --------------------------------------------------------------- PostgreSQL (tests/postgres.py)


def shown(url: str) -> str:
    from db.engine import display_target

    return display_target(url)


@pytest.mark.postgres
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_killed_build_on_postgresql_resumes_to_the_same_content(tmp_path, reference, capsys, postgres_url):
    from sqlalchemy.engine import make_url

    proc = spawn(tmp_path, postgres_url, "--workers", "2", delay=0.5)
    wait_for_shards(postgres_url, proc, 1)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert no_orphans(tmp_path), "workers outlived the killed builder"
    kept = len(shard_rows(postgres_url))
    assert 1 <= kept < N_SHARDS

    rc, out, err = dwell(capsys, "build", "--db", postgres_url, *SMALL, "--workers", "1")
    assert rc == 0, err
    assert f"resuming: {kept} of {N_SHARDS} shards already built" in err  # the dead builder's lock was taken over
    assert out.startswith(f"atlas {shown(postgres_url)} complete: ")
    doc = info_json(capsys, postgres_url)
    assert doc["content_digest"] == reference[1]  # the SQLite reference build of the same sweep
    assert doc["build"]["status"] == "complete" and doc["build"]["builder"] is None
    assert doc["build"]["schema_version"] == SCHEMA_VERSION

    rc, text_out, err = dwell(capsys, "info", "--db", postgres_url)
    assert rc == 0 and err == ""
    assert (
        text_out.startswith(f"atlas {shown(postgres_url)}\n")
        and f"content digest (stored, unchecked; --verify recomputes it): {reference[1]}" in text_out
    )
    rc, again, err = dwell(capsys, "build", "--db", postgres_url, *SMALL)
    assert rc == 0 and again.startswith(f"atlas {shown(postgres_url)} is already complete: ")
    password = make_url(postgres_url).password
    if password:
        assert not any(password in s for s in (out, text_out, again, err))


@pytest.mark.postgres
@pytest.mark.parametrize(
    "case, message",
    [
        ("unreachable", "cannot connect to 'postgresql+psycopg://"),
        ("missing", 'database "dwell_no_such_database" does not exist; create it first'),
        ("foreign", "is a database of another application"),
    ],
)
@pytest.mark.parametrize("command", ["build", "info"])
def test_bad_postgresql_targets_exit_2_with_one_line(capsys, postgres_url, case, message, command):
    import socket

    from postgres import atlas_snapshot
    from sqlalchemy import create_engine, text
    from sqlalchemy.engine import make_url

    url = make_url(postgres_url)
    if case == "unreachable":
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]  # nobody listens on it once the socket is closed
        target = f"postgresql+psycopg://dwell:s3cret@127.0.0.1:{port}/atlas"
    elif case == "missing":
        target = url.set(database="dwell_no_such_database").render_as_string(hide_password=False)
    else:
        target = postgres_url
        engine = create_engine(target)
        with engine.begin() as conn:
            conn.execute(text("CREATE TABLE things (x integer)"))
        engine.dispose()
    before = atlas_snapshot(postgres_url)
    extra = ["--samples", "8", "--workers", "1"] if command == "build" else []
    rc, out, err = dwell(capsys, command, "--db", target, *extra)
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("dwell: error: ") and message in err, err
    assert "s3cret" not in err and (url.password is None or url.password not in err)
    assert atlas_snapshot(postgres_url) == before
