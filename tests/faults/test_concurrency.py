"""One builder at a time, readers any time: a second builder is refused at once (exit 2, one
line, nothing changed) and the first one completes unharmed; ``dwell atlas info`` and
``dwell query`` answer promptly while a build commits shards (SQLite in WAL mode; PostgreSQL).
"""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import pytest
from harness.processes import N_SHARDS, QUERY, SMALL, info, run, shard_rows, spawn, wait_for_shards

needs_proc = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc (Linux)")
#: "Promptly": far above a read's own time, far below being blocked by a writer (busy timeout 30 s).
PROMPT_SECONDS = 5.0


@needs_proc
def test_a_second_builder_is_refused_and_the_first_completes(tmp_path, capsys, reference, atlas_url):
    first = spawn(tmp_path, atlas_url, "--workers", "2", delay=0.2)
    wait_for_shards(atlas_url, first, 1)
    os.killpg(first.pid, signal.SIGSTOP)  # the first builder holds its lock, however fast the machine
    try:
        before = shard_rows(atlas_url)
        results = []
        for extra in ([], ["--samples", "12", "--replace"]):  # the same sweep, and replacing it
            t0 = time.perf_counter()
            results.append(
                (
                    *run(capsys, "atlas", "build", "--db", atlas_url, *SMALL, "--workers", "1", *extra),
                    time.perf_counter() - t0,
                )
            )
        after = shard_rows(atlas_url)
    finally:
        os.killpg(first.pid, signal.SIGCONT)
    for rc, out, err, seconds in results:
        assert rc == 2 and out == "", err
        assert err.count("\n") == 1 and err.startswith("dwell: error: atlas ") and "Traceback" not in err
        assert f"is being built by another process (pid {first.pid} on " in err
        assert seconds < PROMPT_SECONDS  # refused at once, not after waiting on the stopped builder
    assert after == before and 1 <= len(after) < N_SHARDS

    out, err = first.communicate(timeout=120)
    assert first.returncode == 0, err
    assert out.startswith("atlas ") and " complete: " in out
    doc = info(capsys, atlas_url)
    assert doc["build"]["status"] == "complete" and doc["content_digest"] == reference.digest


@needs_proc
def test_readers_are_not_blocked_while_a_build_writes(tmp_path, capsys, reference, atlas_url):
    build = spawn(tmp_path, atlas_url, "--workers", "1", delay=2.0)  # room for a few reads on a busy machine
    wait_for_shards(atlas_url, build, 1)
    latency: dict[str, list[float]] = {"info": [], "query": []}
    progress = []
    while build.poll() is None:
        t0 = time.perf_counter()
        rc, out, err = run(capsys, "atlas", "info", "--db", atlas_url, "--json")
        latency["info"].append(time.perf_counter() - t0)
        assert rc == 0, err
        progress.append(json.loads(out)["build"]["shards_done"])
        t0 = time.perf_counter()
        rc, out, err = run(capsys, "query", "--db", atlas_url, *QUERY, "--json")
        latency["query"].append(time.perf_counter() - t0)
        assert isinstance(json.loads(out)["candidates"], list)
        assert rc == (0 if json.loads(out)["candidates"] else 1), err  # 1: none found (yet), as grep
    out, err = build.communicate()
    assert build.returncode == 0, err
    # the reads ran between the builder's commits and saw them
    assert len(latency["info"]) >= 3 and len(set(progress)) >= 2 and progress == sorted(progress), progress
    worst = max(latency["info"] + latency["query"])
    assert worst < PROMPT_SECONDS, latency
    assert info(capsys, atlas_url)["content_digest"] == reference.digest
