"""The compiled kernels' batches split over the machine's cores: contiguous blocks of rows, one
per thread.

Every row kernel of :mod:`synth` (the six-bar's motion, the clearances, the band windows, the
dyad fits' swing solves) works row by row — a row reads and writes its own entries only — and
releases the GIL (``nogil=True``), so blocks of rows run at once on plain threads and give the
same numbers bit for bit, whatever the number of threads or the split. A hand-off costs tens of
microseconds: batches of fewer than ``MIN_WORK`` elements run in the caller's thread.

The thread count is the CPUs this process may use, or ``DWELL_THREADS`` from the environment;
:func:`set_threads` changes it (the atlas and search workers set 1: their processes already fill
the cores). The pool is made on first use and made again in a forked child (threads do not
survive a fork).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

__all__ = ["MIN_WORK", "over_rows", "set_threads", "threads"]

#: Elements (rows × samples, or another unit of about 50 ns of work) below which a batch runs in
#: the caller's thread: a thread hand-off costs ~30–60 µs.
MIN_WORK = 5_000


def _default_threads() -> int:
    env = os.environ.get("DWELL_THREADS", "").strip()
    if env:
        try:
            n = int(env)
        except ValueError:
            n = 0
        if n < 1:
            raise ValueError(f"$DWELL_THREADS must be a whole number of threads (>= 1), not {env!r}")
        return n
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


_threads: int | None = None
_pool: ThreadPoolExecutor | None = None
_lock = threading.Lock()


def threads() -> int:
    """How many threads a large batch is split over."""
    global _threads
    if _threads is None:
        _threads = _default_threads()
    return _threads


def set_threads(n: int) -> None:
    """Split large batches over ``n`` threads from now on (1: never split)."""
    global _threads, _pool
    if n < 1:
        raise ValueError(f"threads must be >= 1, not {n!r}")
    with _lock:
        _threads = int(n)
        if _pool is not None:
            _pool.shutdown(wait=False)
            _pool = None


def _forget_pool() -> None:  # in a forked child: the parent's threads are not there
    global _pool, _lock
    _pool, _lock = None, threading.Lock()


os.register_at_fork(after_in_child=_forget_pool)


def _executor(n: int) -> ThreadPoolExecutor:
    global _pool
    with _lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(max_workers=n, thread_name_prefix="dwell-rows")
        return _pool


def over_rows(rows: int, work: Callable[[int, int], None], size: int) -> None:
    """Call ``work(lo, hi)`` on contiguous blocks of ``range(rows)`` that cover it once: on
    :func:`threads` threads at once if the batch has ``size`` ≥ :data:`MIN_WORK` elements and
    more than one row, else as one block in this thread. ``work`` must touch only its rows'
    entries (the results are then the same for any split); its exceptions propagate."""
    n = min(threads(), rows)
    if n <= 1 or size < MIN_WORK:
        work(0, rows)
        return
    edges = [rows * k // n for k in range(n + 1)]
    pool = _executor(threads())
    futures = [pool.submit(work, lo, hi) for lo, hi in zip(edges[1:-1], edges[2:])]
    try:
        work(edges[0], edges[1])  # the first block in this thread
    finally:
        for f in futures:  # every block done (or failed) before anything is returned or raised
            f.exception()
    for f in futures:
        f.result()
