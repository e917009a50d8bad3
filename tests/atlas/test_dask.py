"""The dask engine: same content as the local engine, resume, cancellation, and every way the
cluster cannot be used (one line, exit 2, nothing written).

One two-process ``LocalCluster`` serves the whole module (it takes a few seconds to start).
"""

from __future__ import annotations

import os
import platform
import re
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from atlas.malloc import raise_malloc_thresholds

pytest.importorskip("distributed")

import dask
from distributed import Client
from harness.dask_cluster import drained, free_port, local_cluster, tasks_on

from atlas import PRESETS, dask_cluster, sweep_linkages
from atlas.build import build_atlas, run_shards
from atlas.dask_engine import ClusterError, DaskRunner
from cli.main import main
from db import open_atlas
from db.digest import content_digest

#: the demo preset on a small sweep: ~80 linkages in 10 shards (a few seconds on 2 cores)
SPEC = PRESETS["demo"].replace(samples=64, shard_size=4)
SMALL = ["--preset", "demo", "--samples", "64", "--shard-size", "4", "--no-progress"]
N_SHARDS = sweep_linkages(SPEC).n_shards(SPEC.shard_size)


@pytest.fixture(scope="module")
def cluster():
    """Two single-threaded worker processes (:func:`harness.dask_cluster.local_cluster`)."""
    with local_cluster(2) as cluster:
        yield cluster


@pytest.fixture(scope="module")
def client(cluster):
    with Client(cluster, set_as_default=False) as client:
        yield client


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> tuple[Path, str]:
    """The same sweep built by the local engine through the CLI: (path, content digest)."""
    path = tmp_path_factory.mktemp("local") / "local.sqlite"
    assert main(["atlas", "build", "--db", str(path), *SMALL, "--workers", "2"]) == 0
    return path, digest_of(path)


def digest_of(path: Path) -> str:
    engine = open_atlas(str(path), readonly=True)
    try:
        return content_digest(engine)
    finally:
        engine.dispose()


def shard_indices(path: Path) -> list[int]:
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        return sorted(i for (i,) in con.execute("select shard_index from shard"))
    finally:
        con.close()


def dwell(capsys, *args: str) -> tuple[int, str, str]:
    rc = main(["atlas", *args])
    out, err = capsys.readouterr()
    return rc, out, err


def test_a_dask_build_equals_the_local_build(tmp_path, cluster, client, reference, capsys):
    path = tmp_path / "dask.sqlite"
    rc, out, err = dwell(
        capsys, "build", "--db", str(path), *SMALL, "--engine", "dask", "--scheduler", cluster.scheduler_address
    )
    assert rc == 0, err
    assert err == f"dwell: dask: 2 worker(s), 2 thread(s) at {cluster.scheduler_address}\n"
    assert re.fullmatch(
        rf"atlas {re.escape(str(path))} complete: \d+ linkages; segments: line \d+, arc \d+, "
        rf"double_line \d+; {N_SHARDS} shard\(s\) in [\d.]+ s \(\d+ linkages/s\)\n",
        out,
    )
    assert shard_indices(path) == list(range(N_SHARDS))
    assert digest_of(path) == reference[1]
    assert drained(client)


def stop_after(runner, k: int):
    """``runner`` delivering k shards, then behaving as if Ctrl-C were pressed."""

    def stopping(spec, sweep, indices, workers, *, tick=None):
        results = runner(spec, sweep, indices, workers, tick=tick)
        try:
            for n, result in enumerate(results):
                if n == k:
                    raise KeyboardInterrupt
                yield result
        finally:
            results.close()

    return stopping


def test_an_interrupted_build_resumes_on_the_cluster_to_the_same_content(tmp_path, cluster, client, reference, capsys):
    path = tmp_path / "resumed.sqlite"
    notes: list[str] = []
    with pytest.raises(KeyboardInterrupt):
        build_atlas(str(path), SPEC, runner=stop_after(DaskRunner(client, in_flight=4), 3), log=notes.append)
    assert notes == [f"interrupted: 3 of {N_SHARDS} shards are stored; run the same command again to resume"]
    assert len(shard_indices(path)) == 3
    assert drained(client), "pending shards were not cancelled"

    rc, out, err = dwell(
        capsys, "build", "--db", str(path), *SMALL, "--engine", "dask", "--scheduler", cluster.scheduler_address
    )
    assert rc == 0, err
    assert f"dwell: resuming: 3 of {N_SHARDS} shards already built\n" in err
    assert f"; {N_SHARDS - 3} shard(s) in " in out
    assert digest_of(path) == reference[1]


def test_a_local_build_interrupted_then_finished_on_the_cluster(tmp_path, cluster, client, reference, capsys):
    path = tmp_path / "mixed.sqlite"
    with pytest.raises(KeyboardInterrupt):
        build_atlas(str(path), SPEC, runner=stop_after(run_shards, 2))
    assert shard_indices(path) == [0, 1]  # one worker: in order
    summary = build_atlas(str(path), SPEC, runner=DaskRunner(client))
    assert summary.complete and summary.resumed and summary.shards_written == N_SHARDS - 2
    assert digest_of(path) == reference[1]


def close_the_results_after_one_shard(client: Client) -> float:
    """Seconds closing the results took after the first shard; the scheduler then drains."""
    sweep = sweep_linkages(SPEC)
    results = DaskRunner(client, in_flight=6)(SPEC, sweep, range(N_SHARDS), 1)
    first = next(results)
    assert first.shard_index in range(N_SHARDS) and first.linkages
    assert tasks_on(client) > 2  # more shards in flight, and the scattered spec and sweep
    t0 = time.perf_counter()
    results.close()
    seconds = time.perf_counter() - t0
    assert drained(client)
    return seconds


def test_closing_the_results_cancels_every_pending_shard(client):
    close_the_results_after_one_shard(client)


@pytest.mark.timing
def test_closing_the_results_returns_within_2_s(client):
    assert close_the_results_after_one_shard(client) < 2


def test_ctrl_c_while_the_caller_writes_is_raised_at_the_next_wait(client, monkeypatch):
    import atlas.build

    monkeypatch.setattr(atlas.build, "TICK_SECONDS", 0.01)
    ticks: list[float] = []
    runner = DaskRunner(client, in_flight=4)
    # shards of 32 linkages: a shard of 4 can come back before the runner first polls (~20 ms
    # since the segment search was compiled), and then nothing was waited for
    spec = SPEC.replace(shard_size=32)
    sweep = sweep_linkages(spec)
    results = runner(spec, sweep, range(sweep.n_shards(spec.shard_size)), 1, tick=lambda: ticks.append(1))
    assert next(results).shard_index in range(sweep.n_shards(spec.shard_size))
    assert ticks, "no heartbeat while waiting for the first shard"
    signal.raise_signal(signal.SIGINT)  # Ctrl-C while the caller writes: noted, not raised in its code
    with pytest.raises(KeyboardInterrupt):
        next(results)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # put back
    assert drained(client)


def test_a_second_ctrl_c_is_raised_at_once(client):
    results = DaskRunner(client, in_flight=2)(SPEC, sweep_linkages(SPEC), range(N_SHARDS), 1)
    next(results)
    signal.raise_signal(signal.SIGINT)
    with pytest.raises(KeyboardInterrupt):
        signal.raise_signal(signal.SIGINT)
    results.close()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert drained(client)


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="mallopt thresholds are glibc's")
def test_workers_get_glibcs_malloc_thresholds_back(client):
    # dask's nanny default; with it a shard costs 2.4x the CPU time (see atlas.malloc)
    assert set(client.run(lambda: os.environ.get("MALLOC_TRIM_THRESHOLD_")).values()) == {"65536"}
    assert list(client.run(raise_malloc_thresholds.__wrapped__).values()) == [True, True]


def test_a_worker_with_another_version_is_refused(tmp_path, client, monkeypatch):
    monkeypatch.setattr(dask_cluster, "installed_version", lambda: "0.0-other")  # the driver's view only
    path = tmp_path / "mixed-versions.sqlite"
    with pytest.raises(
        ClusterError,
        match=r"^dask worker tcp://\S+ runs dwell-atlas \S+, this builder 0\.0-other: "
        r"install the same version on every node$",
    ):
        build_atlas(str(path), SPEC, runner=DaskRunner(client))
    assert shard_indices(path) == []
    assert drained(client)


def build_on_an_unreachable_scheduler(folder: Path, capsys) -> float:
    """Seconds ``dwell atlas build`` took to refuse a scheduler nobody listens at (1 s connect
    timeout); one line on stderr, exit 2, nothing written."""
    port = free_port()
    t0 = time.perf_counter()
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        rc, out, err = dwell(
            capsys,
            "build",
            "--db",
            str(folder / "new.sqlite"),
            *SMALL,
            "--engine",
            "dask",
            "--scheduler",
            f"tcp://127.0.0.1:{port}",
        )
    seconds = time.perf_counter() - t0
    assert rc == 2 and out == ""
    assert err.count("\n") == 1, err
    assert err.startswith(
        f"dwell: error: cannot connect to the dask scheduler at tcp://127.0.0.1:{port}: "
        f"Timed out trying to connect to tcp://127.0.0.1:{port} after 1 s"
    )
    assert list(folder.iterdir()) == []
    return seconds


def test_an_unreachable_scheduler_writes_nothing(tmp_path, capsys):
    build_on_an_unreachable_scheduler(tmp_path, capsys)


@pytest.mark.timing
def test_an_unreachable_scheduler_is_refused_within_10_s(tmp_path, capsys):
    assert build_on_an_unreachable_scheduler(tmp_path, capsys) < 10


@pytest.mark.parametrize(
    "args, message",
    [
        (["--engine", "dask"], "dwell atlas build: --engine dask needs --scheduler ADDR"),
        (["--scheduler", "tcp://127.0.0.1:8786"], "dwell atlas build: --scheduler needs --engine dask"),
        (["--engine", "local", "--scheduler", "tcp://h:8786"], "dwell atlas build: --scheduler needs --engine dask"),
        (["--engine", "spark"], "Invalid value for '--engine': 'spark' is not one of 'local', 'dask'"),
        (
            ["--engine", "dask", "--scheduler", "scheduler"],
            "not a dask scheduler address: 'scheduler' (missing port number in address 'scheduler')",
        ),
        (
            ["--engine", "dask", "--scheduler", "udp://h:1"],
            "not a dask scheduler address: 'udp://h:1' (unknown address scheme 'udp'",
        ),
    ],
)
def test_bad_engine_options_write_nothing(tmp_path, capsys, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)  # the default --db lives in the cwd
    rc, out, err = dwell(capsys, "build", *SMALL, *args)
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("dwell: error: ") and message in err, err
    assert list(tmp_path.iterdir()) == []


def test_without_the_dask_extra_the_engine_says_how_to_install_it(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "distributed", None)  # what an install without the extra sees
    rc, out, err = dwell(capsys, "build", *SMALL, "--engine", "dask", "--scheduler", "tcp://127.0.0.1:8786")
    assert rc == 2 and out == ""
    assert err.count("\n") == 1
    assert err.startswith("dwell: error: the dask engine cannot import dask.distributed (")
    assert err.endswith("); install the dask extra: pip install 'dwell-atlas[dask]'\n")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_ctrl_c_cancels_the_cluster_work_and_exits_130(tmp_path, cluster, client):
    db = tmp_path / "atlas.sqlite"
    env = dict(os.environ)
    env.pop("DWELL_ATLAS", None)
    # the demo sweep in 80 shards of 16 linkages: still running when the first shard is stored
    n_shards = sweep_linkages(PRESETS["demo"]).n_shards(8)
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "cli.main",
            "atlas",
            "build",
            "--db",
            str(db),
            "--preset",
            "demo",
            "--shard-size",
            "8",
            "--no-progress",
            "--engine",
            "dask",
            "--scheduler",
            cluster.scheduler_address,
        ],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    deadline = time.monotonic() + 60
    while not (db.exists() and _shards_stored(db)):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "no shard was written in time"
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)  # what Ctrl-C in a terminal does
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert out == "" and "Traceback" not in err
    kept = len(shard_indices(db))
    assert 1 <= kept < n_shards
    assert f"dwell: interrupted: {kept} of {n_shards} shards are stored; run the same command again to resume\n" in err
    assert err.rstrip().endswith("dwell: interrupted")  # click puts a newline between them
    assert drained(client), "the builder's shards are still on the cluster"


def _shards_stored(db: Path) -> int:
    try:
        return len(shard_indices(db))
    except sqlite3.Error:  # not created yet, or the schema is being written
        return 0
