"""kill -9 of the whole builder (driver, forkserver, workers) at random moments, then resume:
the atlas ends identical to an uninterrupted build and no committed shard is lost or redone.

Moments are drawn from a seed (fixed under CI, random otherwise; it is in every failure
message): a number of stored shards to wait for plus a fraction of a shard, or a time in the
start-up (start-up, schema, lock take-over). One kill lands inside the schema-creating
transaction on purpose: a half-made atlas must not lock the user out.
"""

from __future__ import annotations

import os
import random
import sqlite3
import time
from pathlib import Path

import pytest
from harness.processes import N_SHARDS, SMALL, info, kill_group, run, shard_rows, spawn, wait_for_shards

needs_proc = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc (Linux)")
#: Seconds each shard is slowed by in the killed runs (compute is on top).
DELAY = 0.4
SEED = 0 if os.environ.get("CI") else random.randrange(2**32)


def _target(backend: str, tmp_path: Path, request) -> str:
    return str(tmp_path / "atlas.sqlite") if backend == "sqlite" else request.getfixturevalue("postgres_url")


def _assert_kept(before: dict[int, tuple] | None, after: dict[int, tuple] | None, why: str) -> None:
    """Every shard of ``before`` is in ``after``, unchanged (None: no atlas yet, both kills
    came before the schema — seen with seed 1367704411 on PostgreSQL)."""
    before = before or {}
    assert {i: (after or {}).get(i) for i in before} == before, f"committed shards lost or redone: {why}"


@needs_proc
@pytest.mark.parametrize(
    "backend, trial",
    [("sqlite", 0), ("sqlite", 1), ("sqlite", 2), pytest.param("postgresql", 0, marks=pytest.mark.postgres)],
)
def test_killed_twice_at_random_moments_resumes_to_the_same_content(
    tmp_path, request, capsys, reference, backend, trial
):
    rng = random.Random(f"{SEED}:{backend}:{trial}")
    why = f"seed {SEED}, {backend} trial {trial}"
    target = _target(backend, tmp_path, request)
    assert N_SHARDS >= 4

    # kill 1: after k stored shards (k = 0: anywhere in the start-up) and part of the next one
    k = rng.randint(0, N_SHARDS - 2)
    proc = spawn(tmp_path, target, "--workers", "2", delay=DELAY)
    if k:
        wait_for_shards(target, proc, k)
        time.sleep(rng.uniform(0.0, DELAY))
    else:
        time.sleep(rng.uniform(0.0, 2.0))
    assert proc.poll() is None, f"the build ended before the kill ({why})"
    alive, err = kill_group(proc)
    assert alive == [], f"processes outlived the kill ({why})"
    assert proc.returncode == -9, err
    first = shard_rows(target) or {}
    assert k <= len(first) < N_SHARDS, why

    # kill 2: the resuming run, at a random time of its start-up or first shards
    proc = spawn(tmp_path, target, "--workers", "2", delay=DELAY)
    time.sleep(rng.uniform(0.0, 2.5))
    killed = proc.poll() is None
    alive, err = kill_group(proc)
    assert alive == [], f"processes outlived the second kill ({why})"
    # polled alive, it may already have been in its exit (past SIGKILL: the kernel tears down its
    # memory first) and end with 0 — seen once on a clean-clone CI run, seed 0, trial 2
    assert proc.returncode in ((-9, 0) if killed else (0,)), f"{why}: {err}"
    second = shard_rows(target)
    _assert_kept(first, second, why)

    # the resume: completes, redoes nothing stored, same content as the uninterrupted build
    rc, out, err = run(capsys, "atlas", "build", "--db", target, *SMALL, "--workers", "1")
    assert rc == 0, f"{why}: {err}"
    assert "Traceback" not in err
    if second and len(second) < N_SHARDS:
        assert f"resuming: {len(second)} of {N_SHARDS} shards already built" in err, why
    _assert_kept(second, shard_rows(target), why)
    doc = info(capsys, target)
    assert doc["build"]["status"] == "complete" and doc["build"]["builder"] is None, why
    assert doc["content_digest"] == reference.digest, why


@needs_proc
def test_a_kill_inside_the_schema_transaction_leaves_a_buildable_atlas(tmp_path, capsys, reference, atlas_url):
    proc = spawn(tmp_path, atlas_url, "--workers", "1", kill_in_schema=True)
    proc.communicate(timeout=120)
    assert proc.returncode == -9  # the hook killed it with the schema written, not committed
    assert shard_rows(atlas_url) is None  # no atlas tables: the creation was rolled back
    rc, out, err = run(capsys, "atlas", "build", "--db", atlas_url, *SMALL, "--workers", "1")
    assert rc == 0, err
    assert info(capsys, atlas_url)["content_digest"] == reference.digest


def test_an_empty_sqlite_database_is_built_in(tmp_path, capsys, reference):
    # what a build killed after its first connection (WAL mode set, no table yet) leaves
    db = tmp_path / "atlas.sqlite"
    con = sqlite3.connect(db)
    assert con.execute("PRAGMA journal_mode=WAL").fetchone() == ("wal",)
    con.close()
    assert db.stat().st_size > 0
    rc, out, err = run(capsys, "atlas", "info", "--db", str(db))
    assert rc == 2 and err == f"dwell: error: {str(db)!r} is an empty database, not an atlas\n"
    rc, out, err = run(capsys, "atlas", "build", "--db", str(db), *SMALL, "--workers", "1")
    assert rc == 0, err
    assert info(capsys, str(db))["content_digest"] == reference.digest
