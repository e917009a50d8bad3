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


def test_a_worker_cut_off_while_sending_its_result_does_not_hang_the_driver():
    """A worker terminated half-way through sending a result left the pool's manager thread
    waiting for the rest, and the interpreter, which joins that thread at exit, hung (a
    random-seed run: ``dwell atlas build`` never exited after Ctrl-C). The driver process
    must stop the pool and exit within seconds."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(TESTS), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.run([sys.executable, "-c", CUT_OFF], capture_output=True, text=True, timeout=60, env=env)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "stopped\n"
    assert proc.stderr == ""
