"""The bounded process pool (:mod:`atlas.pool`) that the atlas build and the complete query run on."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

#: The folder that makes :mod:`harness` importable, for the driver and the workers it starts.
TESTS = Path(__file__).resolve().parents[1]

# Stops the pool (a tick that raises) while the pool's manager thread waits for the rest of a
# result message that will never come; the process must still exit.
CUT_OFF = """
import atlas.pool as pool
from harness.pool_faults import send_half_a_result

pool.TICK_SECONDS = 0.5


class Stop(Exception):
    pass


def stop():
    raise Stop


try:
    for _ in pool.pool_map(send_half_a_result, [0], 1, tick=stop):
        pass
except Stop:
    print("stopped", flush=True)
"""


# The same stop, with the pool's manager thread slowed as it closes its pipes (as a loaded
# machine slows it): when pool_map has raised, that thread must have ended.
CUT_OFF_SLOW_MANAGER = """
import threading
import time
import concurrent.futures.process as futures_process

closing = futures_process._ExecutorManagerThread.join_executor_internals


def slowly(self):
    time.sleep(0.5)
    closing(self)


futures_process._ExecutorManagerThread.join_executor_internals = slowly
""" + CUT_OFF.replace(
    'print("stopped", flush=True)',
    'print("stopped", [t.name for t in threading.enumerate() if t is not threading.main_thread()], flush=True)',
)


def _driver(code: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(TESTS), os.environ.get("PYTHONPATH")]))}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=env)


def test_a_worker_cut_off_while_sending_its_result_does_not_hang_the_driver():
    """A worker terminated half-way through sending a result left the pool's manager thread
    waiting for the rest, and the interpreter, which joins that thread at exit, hung (a
    random-seed run: ``dwell atlas build`` never exited after Ctrl-C). The driver process
    must stop the pool and exit within seconds."""
    proc = _driver(CUT_OFF)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "stopped\n"
    assert proc.stderr == ""


def test_the_stopped_pool_s_manager_thread_has_ended():
    """The interpreter's exit hook (concurrent.futures.process._python_exit, Python 3.11)
    writes to the manager thread's wake-up pipe after an unlocked check that it is open; the
    thread closing it at that moment printed an ignored "Bad file descriptor" at exit (a
    random-seed run of the test above, on a loaded machine). A stopped pool joins its manager
    thread, so nothing is left to close it at exit, however slowly it ends."""
    proc = _driver(CUT_OFF_SLOW_MANAGER)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "stopped []\n"
    assert proc.stderr == ""


# Two maps on one WorkerPool: the same processes; a map whose item fails stops the pool.
REUSED = """
import atlas.pool as pool
from harness.pool_faults import fail_on_two, worker_pid

with pool.WorkerPool(2) as workers:
    first = set(workers.map(worker_pid, range(8)))
    second = set(workers.map(worker_pid, range(8)))
    print(1 <= len(first) <= 2, second <= first, flush=True)
    try:
        list(workers.map(fail_on_two, range(4)))
    except ValueError as exc:
        print("failed:", exc, flush=True)
    try:
        list(workers.map(worker_pid, range(2)))
    except RuntimeError as exc:
        print("then:", exc, flush=True)
print(sorted(pool.pool_map(fail_on_two, [0, 1, 3], 2)), flush=True)
"""


def test_a_worker_pool_runs_several_maps_on_the_same_processes_until_one_fails():
    """``dwell demo`` draws its three reports on one WorkerPool: the second map runs on the
    processes of the first (no second start-up); a map whose item raises re-raises it in the
    driver and stops the workers, and the pool then refuses work in one clear error;
    ``pool_map`` is one map on a pool of its own."""
    proc = _driver(REUSED)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == [
        "True True",
        "failed: item 2 fails",
        "then: the worker pool was stopped",
        "[0, 1, 3]",
    ]
    assert proc.stderr == ""
