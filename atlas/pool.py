"""A bounded process pool: a function over a stream of items on worker processes, results in
completion order, with the few items in flight that keep the workers busy.

The atlas build runs its shards on it (:func:`atlas.build.run_shards`), the complete query
its batches of segments (``dwell query --complete --workers N``) and a report its candidates;
:class:`WorkerPool` keeps the workers for several maps (``dwell demo``'s three reports). Items
are read lazily, so memory stays bounded whatever the stream's length.

Processes start from a forkserver where there is one (no fork of a driver that holds
threads or database connections), preloaded with the modules the work needs. Workers ignore
Ctrl-C (the whole process group gets it; only the driver reacts: it cancels what has not
started, terminates the workers and re-raises), and exit at once when the driver dies (a pool
worker otherwise waits forever on a task queue every worker holds open).
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from multiprocessing.connection import Connection
from typing import Any, TypeVar

__all__ = ["MAX_WORKERS", "TICK_SECONDS", "WorkerPool", "default_workers", "pool_map"]

#: While waiting on workers, ``tick`` is called at least this often (seconds).
TICK_SECONDS = 10.0

T = TypeVar("T")
R = TypeVar("R")


#: The most worker processes a pool takes (``--workers``): far beyond any machine's cores, and
#: within what the pool's queues can count (``--workers 99999999999999999999`` overflowed the
#: size of the pool's call queue, a C int, found by a random-seed run of the CLI fuzz test).
MAX_WORKERS = 256


def default_workers() -> int:
    """The CPUs this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _exit_with_driver(lifeline: Connection) -> None:
    """Block until the driver is gone (its end of the pipe closes), then exit at once."""
    try:
        lifeline.recv()
    except (EOFError, OSError):
        pass
    os._exit(1)


def _init_worker(lifeline: Connection, initializer: Callable[..., None] | None, initargs: tuple, workers: int) -> None:
    from synth.parallel_rows import set_threads, threads

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_exit_with_driver, args=(lifeline,), name="driver-watch", daemon=True).start()
    set_threads(max(1, threads() // workers))  # the workers share the cores: no more threads than cores
    if initializer is not None:
        initializer(*initargs)


def _mp_context(preload: Sequence[str]) -> multiprocessing.context.BaseContext:
    """forkserver where available (the server preloads ``preload``, so workers start fast),
    else spawn."""
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(list(preload))
        return ctx
    return multiprocessing.get_context("spawn")


def _stop(executor: ProcessPoolExecutor) -> None:
    """Cancel what has not started and terminate the workers (do not wait for a task).

    A worker terminated while it sends a result leaves part of a message in the pool's result
    pipe; the pool's manager thread then waits for the rest forever, and so does the
    interpreter, which joins that thread at exit (found by a random-seed run: ``dwell atlas
    build`` hung after Ctrl-C). The driver holds the pipe's last writing end; once every
    worker is gone, closing it ends that read (end of file): the pool counts itself broken,
    fails the futures nobody waits for, and its thread ends. The futures are cancelled by the
    pool's own thread (``cancel_futures``), never here: a broken pool fails every future it
    still holds, and failing one cancelled from outside would raise in that thread.

    That thread is joined here before returning: it closes its wake-up pipe as it ends, and
    the interpreter's exit hook (``concurrent.futures.process._python_exit``, Python 3.11)
    writes to that pipe after checking, without a lock, that it is open — a thread closing it
    at the same moment made the exit print an ignored "Bad file descriptor" (found by a
    random-seed run of ``tests/atlas/test_pool.py``)."""
    processes = list((getattr(executor, "_processes", None) or {}).values())
    # shutdown() drops these references
    results = getattr(executor, "_result_queue", None)
    manager = getattr(executor, "_executor_manager_thread", None)
    executor.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        if p.is_alive():
            p.terminate()
    for p in processes:
        p.join(timeout=5)
        if p.is_alive():  # SIGTERM not taken within 5 s
            p.kill()
            p.join(timeout=5)
    if results is not None and not any(p.is_alive() for p in processes):
        results._writer.close()
    if manager is not None and manager is not threading.current_thread():
        manager.join(timeout=5)


def pool_map(
    fn: Callable[[T], R],
    items: Iterable[T],
    workers: int,
    *,
    initializer: Callable[..., None] | None = None,
    initargs: tuple[Any, ...] = (),
    preload: Sequence[str] = (),
    tick: Callable[[], None] | None = None,
) -> Iterator[R]:
    """``fn(item)`` for every item, on ``workers`` processes, yielded in completion order
    with at most ``2 · workers`` items in flight. ``fn`` and the items must pickle (``fn`` a
    module-level function); ``initializer(*initargs)`` runs once in each worker. ``tick`` is
    called at least every :data:`TICK_SECONDS` while waiting. Closing the iterator (or an
    exception, Ctrl-C included) stops the workers."""
    with WorkerPool(workers, initializer=initializer, initargs=initargs, preload=preload) as pool:
        yield from pool.map(fn, items, tick=tick)


class WorkerPool:
    """Worker processes that outlive one :meth:`map`: several maps (three reports of three
    candidates each) pay the workers' start and imports once. A context manager; its
    :meth:`map` is :func:`pool_map`'s, and a map that ends early (an error, Ctrl-C, an
    iterator closed) stops the workers, after which the pool takes no more work."""

    def __init__(
        self,
        workers: int,
        *,
        initializer: Callable[..., None] | None = None,
        initargs: tuple[Any, ...] = (),
        preload: Sequence[str] = (),
    ) -> None:
        ctx = _mp_context(preload)
        # only the driver ever holds the sending end: it closes when the driver dies, however
        self._lifeline_r, self._lifeline_w = ctx.Pipe(duplex=False)
        self.workers = workers
        self._executor = ProcessPoolExecutor(
            max_workers=workers,
            mp_context=ctx,
            initializer=_init_worker,
            initargs=(self._lifeline_r, initializer, initargs, workers),
        )
        self._stopped = False

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, kind, value, traceback) -> None:
        try:
            if kind is None and not self._stopped:
                self._executor.shutdown(wait=True)
            elif not self._stopped:
                _stop(self._executor)
        finally:
            self._stopped = True
            self._lifeline_w.close()
            self._lifeline_r.close()

    def map(self, fn: Callable[[T], R], items: Iterable[T], tick: Callable[[], None] | None = None) -> Iterator[R]:
        """:func:`pool_map` on these workers (see there)."""
        if self._stopped:
            raise RuntimeError("the worker pool was stopped")
        todo = iter(items)
        executor, workers = self._executor, self.workers
        pending: set[Future] = set()
        clean = False
        try:
            for item in todo:
                pending.add(executor.submit(fn, item))
                if len(pending) >= 2 * workers:
                    break
            while pending:
                done, pending = wait(pending, timeout=TICK_SECONDS, return_when=FIRST_COMPLETED)
                if not done:
                    if tick is not None:
                        tick()
                    continue
                for future in done:
                    result = future.result()
                    nxt = next(todo, _END)
                    if nxt is not _END:  # keep the workers busy while the driver takes the result
                        pending.add(executor.submit(fn, nxt))
                    yield result
            clean = True
        finally:
            if not clean:  # what is in flight must not run on: stop now, not at the pool's exit
                self._stopped = True
                _stop(executor)


_END = object()
