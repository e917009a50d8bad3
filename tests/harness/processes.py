"""``dwell atlas build`` in subprocesses for the fault tests: start it, slow it down, stop or
kill its whole process group (builder, forkserver, pool workers) and watch what it stored;
and ``dwell`` run in this process (:func:`run`, :func:`info`).

The builds run the small sweep ``SMALL`` (the demo preset's search settings on 32 Sobol
points, shards of 4 proportions) and are slowed by a ``sitecustomize`` hook on PYTHONPATH
(it reaches the worker processes too), so that a build can be caught in the middle on any
machine. The hook can also SIGKILL the builder right after it created the atlas schema,
inside the transaction that creates it.
"""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

from atlas import SweepSpec, sweep_linkages
from cli.bench.faults import group_alive
from cli.main import main

#: The sweep every build here runs, as ``dwell atlas build`` options and as the same spec.
SMALL = ["--b", "1.5", "4.5", "--c", "1.5", "4.5", "--d", "1.5", "4.5", "--samples", "32", "--shard-size", "4"]
SPEC = SweepSpec(
    name="faults", b=(1.5, 4.5), c=(1.5, 4.5), d=(1.5, 4.5), samples=32, crank_step_deg=3.0, rays=24, shard_size=4
)
N_SHARDS = sweep_linkages(SPEC).n_shards(SPEC.shard_size)

#: A request the small sweep answers (generous tolerances): its candidates name real segments.
QUERY = ["--dwell", "40", "--swing", "20", "--dwell-tol", "10", "--swing-tol", "5"]

#: ``python -c`` rather than ``-m cli.main``, which warns on stderr (``cli`` imports ``cli.main``).
DWELL = [sys.executable, "-c", "import sys; from cli.main import main; sys.exit(main())"]

HOOK = """
import os
_delay = float(os.environ.get("DWELL_TEST_SHARD_DELAY") or 0)
if _delay > 0:
    import time
    import atlas.shard as _shard
    _compute = _shard.compute_shard
    def _slow(*args, **kwargs):
        time.sleep(_delay)
        return _compute(*args, **kwargs)
    _shard.compute_shard = _slow
_after = int(os.environ.get("DWELL_TEST_KILL_AFTER_SHARDS") or 0)
if _after > 0:
    import signal
    import db.writes as _writes  # atlas.build imports it from here when it runs
    _write = _writes.write_shard
    _written = []
    def _write_then_die(*args, **kwargs):
        _write(*args, **kwargs)
        _written.append(1)
        if len(_written) >= _after:  # committed, in the -wal, not yet folded into the file
            os.killpg(0, signal.SIGKILL)
    _writes.write_shard = _write_then_die
if os.environ.get("DWELL_TEST_KILL_IN_SCHEMA"):
    import signal
    import db.engine as _engine
    _create = _engine._create_schema
    def _die(conn):
        _create(conn)  # the tables and meta rows are written, not yet committed
        os.killpg(0, signal.SIGKILL)
    _engine._create_schema = _die
"""


def spawn(
    folder: Path, target: str, *extra: str, delay: float = 0.0, kill_in_schema: bool = False, kill_after_shards: int = 0
) -> subprocess.Popen:
    """``dwell atlas build --db TARGET SMALL EXTRA`` in a session of its own (one process group);
    ``kill_after_shards``: the builder SIGKILLs its group right after that many shard commits."""
    hook = folder / "hook"
    hook.mkdir(exist_ok=True)
    (hook / "sitecustomize.py").write_text(HOOK)
    env = dict(
        os.environ,
        DWELL_TEST_SHARD_DELAY=str(delay),
        PYTHONPATH=os.pathsep.join([str(hook), *filter(None, [os.environ.get("PYTHONPATH")])]),
    )
    env.pop("DWELL_ATLAS", None)
    if kill_in_schema:
        env["DWELL_TEST_KILL_IN_SCHEMA"] = "1"
    if kill_after_shards:
        env["DWELL_TEST_KILL_AFTER_SHARDS"] = str(kill_after_shards)
    return subprocess.Popen(
        [*DWELL, "atlas", "build", "--db", target, *SMALL, "--no-progress", *extra],
        cwd=folder,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def shard_rows(target: str) -> dict[int, tuple] | None:
    """Stored shard rows by index (compute seconds included: a recomputed shard differs), or
    None while there is no readable atlas."""
    sql = "select shard_index, n_linkages, n_segments, skipped_json, seconds from shard"
    if "://" not in target:
        if not Path(target).exists():
            return None
        try:
            con = sqlite3.connect(f"file:{target}?mode=ro", uri=True, timeout=30)
            try:
                return {r[0]: tuple(r) for r in con.execute(sql)}
            finally:
                con.close()
        except sqlite3.Error:
            return None
    from sqlalchemy import create_engine, text
    from sqlalchemy.exc import SQLAlchemyError

    engine = create_engine(target)
    try:
        with engine.connect() as conn:
            return {r[0]: tuple(r) for r in conn.execute(text(sql))}
    except SQLAlchemyError:
        return None
    finally:
        engine.dispose()


def wait_for_shards(target: str, proc: subprocess.Popen, at_least: int, timeout: float = 90) -> int:
    """Wait until ``at_least`` shards are stored (the build must still run); their count."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, f"the build ended early: {proc.communicate()}"
        n = len(shard_rows(target) or {})
        if n >= at_least:
            return n
        time.sleep(0.02)
    raise AssertionError(f"{at_least} shard(s) were not stored in {timeout} s")


def kill_group(proc: subprocess.Popen, timeout: float = 10) -> tuple[list[int], str]:
    """SIGKILL ``proc``'s whole group and reap it: (pids still alive after ``timeout``, its stderr)."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    _, err = proc.communicate()
    deadline = time.monotonic() + timeout
    while (alive := group_alive(proc.pid)) and time.monotonic() < deadline:
        time.sleep(0.05)
    return alive, err


def run(capsys, *argv: str) -> tuple[int, str, str]:
    """``dwell ARGV`` in this process: (exit status, stdout, stderr)."""
    capsys.readouterr()
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def info(capsys, target: str) -> dict:
    """``dwell atlas info --json`` of ``target`` (it must succeed)."""
    rc, out, err = run(capsys, "atlas", "info", "--db", target, "--json")
    assert rc == 0, err
    doc = json.loads(out)
    # SQLite and PostgreSQL both say how many bytes the atlas takes
    assert isinstance(doc["storage_bytes"], int) and doc["storage_bytes"] > 0, doc["storage_bytes"]
    return doc
