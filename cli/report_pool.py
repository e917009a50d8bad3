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
from collections.abc import Callable

__all__ = ["PARALLEL_FROM", "report_pool"]

#: Candidates from which a report is drawn on worker processes.
PARALLEL_FROM = 4


def report_pool(count: int, workers: int | None = None) -> Callable | None:
    """``map_candidates`` for a report of ``count`` candidates: :func:`atlas.pool.pool_map` on
    min(``count``, ``workers`` or every CPU) processes, or None (in this process) below
    :data:`PARALLEL_FROM` candidates or with one CPU."""
    from atlas.pool import default_workers, pool_map

    n = min(count, workers or default_workers())
    if count < PARALLEL_FROM or n < 2:
        return None
    return functools.partial(pool_map, workers=n, preload=("report.candidate_files",))
