"""Work items that fail the way a worker of :func:`atlas.pool.pool_map` can (run in the
workers of ``tests/atlas/test_pool.py``, whose driver process gets ``tests/`` on its
``PYTHONPATH``, as pytest has it)."""

from __future__ import annotations

import os
import struct
import sys
import time


def send_half_a_result(_item: object) -> None:
    """Write the first bytes of a result message into the pool's result pipe — a length
    header for 1 MiB, then 10 bytes — and hang, as a worker terminated while it sends a large
    result leaves the pipe. The pipe is a local of the pool's worker loop, which calls this."""
    frame = sys._getframe(1)
    while "result_queue" not in frame.f_locals:
        frame = frame.f_back
    frame.f_locals["result_queue"]._writer._send(struct.pack("!i", 1 << 20) + b"x" * 10)
    time.sleep(120)


def worker_pid(_item: object) -> int:
    """The worker's process id (which processes a pool's maps ran on), after a short wait that
    lets every worker take items."""
    time.sleep(0.05)
    return os.getpid()


def fail_on_two(item: int) -> int:
    """``item``, or a ValueError for 2: a work item that fails."""
    if item == 2:
        raise ValueError("item 2 fails")
    return item
