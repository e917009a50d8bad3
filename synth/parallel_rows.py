"""The compiled kernels' batches split over the machine's cores: contiguous blocks of rows, one
per thread.

Every row kernel of :mod:`synth` (the six-bar's motion, the clearances, the band windows, the
dyad fits' swing solves) works row by row — a row reads and writes its own entries only — and
releases the GIL (``nogil=True``), so blocks of rows run at once on plain threads and give the
same numbers bit for bit, whatever the number of threads or the split. A hand-off to a thread
costs ~0.1 ms here (measured: 104 µs median on the 2-core machine): a batch whose estimated
work is under ``MIN_WORK_NS`` runs in the caller's thread. Each caller estimates its work from
its kernel's measured cost per element (3–85 ns on that machine).

The thread count is the CPUs this process may use, or ``DWELL_THREADS`` from the environment;
:func:`set_threads` changes it (the atlas and search worker processes share the cores among
them: each takes its count over the number of workers). The pool is made on first use and made again in a forked child (threads do not
survive a fork).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numba
import numpy as np

__all__ = ["MIN_WORK_NS", "one_signature", "over_rows", "set_threads", "threads"]

#: Estimated work (ns) below which a batch runs in the caller's thread: split, it would save
#: less than the ~0.1 ms a hand-off costs.
MIN_WORK_NS = 300_000


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


def over_rows(rows: int, work: Callable[[int, int], None], cost_ns: float) -> None:
    """Call ``work(lo, hi)`` on contiguous blocks of ``range(rows)`` that cover it once: on
    :func:`threads` threads at once if the whole batch is estimated at ``cost_ns`` ≥
    :data:`MIN_WORK_NS` nanoseconds and has more than one row, else as one block in this
    thread. ``work`` must touch only its rows' entries (the results are then the same for any
    split); its exceptions propagate once every block is done."""
    n = min(threads(), rows)
    if n <= 1 or cost_ns < MIN_WORK_NS:
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


_compile_lock = threading.Lock()
#: The (kernel, positions, argument kinds) :func:`one_signature` has seen compiled: a batch of
#: small blocks calls it thousands of times, and ``numba.typeof`` on every array of every call
#: was ~15 % of a complete RRR search's time (its dispatcher's own typing of the call is C).
_signed: set[tuple] = set()


def _type_key(value: Any) -> tuple:
    """What decides ``numba.typeof(value)`` for the kernels' arguments, cheaply: an array's
    dtype, dimensions, layout, writability and alignment; anything else's own numba type (a
    Python int's depends on its magnitude)."""
    if isinstance(value, np.ndarray):
        flags = value.flags
        return (value.dtype.str, value.ndim, flags.c_contiguous, flags.f_contiguous, flags.writeable, flags.aligned)
    return (numba.typeof(value),)


def one_signature(
    kernel: Any, args: tuple[Any, ...], *, any_layout: tuple[int, ...] = (), read_only: tuple[int, ...] = ()
) -> None:
    """Before ``kernel(*args)`` (a ``numba.njit`` dispatcher) is called, on whole arrays or on
    :func:`over_rows`'s blocks: compile it (or load it from numba's cache) for ``args``' types
    with the arrays at positions ``any_layout`` typed as any-layout ('A') and those at
    ``read_only`` as read-only, then forbid numba further compiles at call time, so that
    contiguous and strided blocks, writable and read-only inputs all call that one machine
    code (numba's dispatcher converts an argument to the wider type only when it may not
    compile; otherwise it compiles every layout and writability it meets, ~1–3 s of CPU
    each). The positions must be arrays the kernel only reads (``read_only``) or indexes
    (``any_layout``). A call whose types still differ (another dtype or number of
    dimensions) gets its own compile here."""
    seen = (kernel, any_layout, read_only, *map(_type_key, args))
    if seen in _signed:
        return
    types = [numba.typeof(a) for a in args]
    for i in any_layout:
        types[i] = types[i].copy(layout="A")
    for i in read_only:
        types[i] = types[i].copy(readonly=True)
    key = tuple(types)
    if key in kernel.overloads:
        _signed.add(seen)
        return
    with _compile_lock:
        if key not in kernel.overloads:
            kernel.disable_compile(False)
            try:
                kernel.compile(key)
            finally:
                kernel.disable_compile(True)
    _signed.add(seen)
