"""Where a report's candidates are drawn (:func:`report.export.write_report`'s
``map_candidates``): on worker processes once there are :data:`PARALLEL_FROM` of them and more
than one core, else in this process.

A worker pays ~1.5 s of imports (matplotlib, ezdxf, the report's modules) before its first
candidate, about what one candidate's files cost (~1.8 s: three figures drawn twice each and a
drawing, on one core), so a pool pays from four candidates on: ``dwell query --report`` with
its default ``--top 10`` on two cores writes the ten in about half the time.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator
from contextlib import contextmanager

__all__ = ["PARALLEL_FROM", "report_pool", "reports_pool"]

#: Candidates from which a report is drawn on worker processes.
PARALLEL_FROM = 4

#: What the workers import before their first candidate (their forkserver preloads it).
PRELOAD = ("report.candidate_files",)


def report_pool(count: int, workers: int | None = None) -> Callable | None:
    """``map_candidates`` for a report of ``count`` candidates: :func:`atlas.pool.pool_map` on
    min(``count``, ``workers`` or every CPU) processes, or None (in this process) below
    :data:`PARALLEL_FROM` candidates or with one CPU."""
    from atlas.pool import pool_map

    n = _processes(count, workers)
    return None if n is None else functools.partial(pool_map, workers=n, preload=PRELOAD)


def _processes(count: int, workers: int | None) -> int | None:
    """Processes to draw ``count`` candidates on: min(``count``, ``workers`` or every CPU), or
    None (in this process) below :data:`PARALLEL_FROM` candidates or with one."""
    from atlas.pool import default_workers

    n = min(count, workers or default_workers())
    return None if count < PARALLEL_FROM or n < 2 else n


@contextmanager
def reports_pool(count: int, workers: int | None = None) -> Iterator[Callable | None]:
    """One ``map_candidates`` for several reports of ``count`` candidates in all (``dwell demo``'s
    three of three): the map of one :class:`atlas.pool.WorkerPool` of min(``count``, ``workers``
    or every CPU) processes, started once for all of them (their imports are paid once, and
    every report's candidates are drawn side by side), or None (in this process) as
    :func:`report_pool` decides for ``count`` candidates."""
    from atlas.pool import WorkerPool

    n = _processes(count, workers)
    if n is None:
        yield None
        return
    with WorkerPool(n, preload=PRELOAD) as pool:
        yield pool.map
