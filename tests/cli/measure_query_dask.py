"""Measurements behind docs/query.md "On a cluster" (not a test: run by hand on a built atlas and
a running dask cluster).

    .venv/bin/python tests/cli/measure_query_dask.py ATLAS SCHEDULER|read rpr|rrr [DWELL SWING]

The complete search of the request (default 60°/30°, the query's other defaults, no
refinement: the search alone) with its batches on the cluster at SCHEDULER
(:func:`atlas.dask_search.search_map`), and where its time goes:

* the driver: seconds reading the atlas (the batches' stream, timed between the search asking
  for a batch and getting it), pickling each batch and each result (``pickle`` at protocol 5,
  as dask's), bytes either way, the driver's CPU seconds and the wall time;
* the workers: each batch's compute time from dask's task stream, rows/s per worker thread,
  and the worker processes' CPU seconds over the search (``getrusage``, all their threads: the
  row kernels split a batch over every core, :mod:`synth.parallel_rows`) — on a loaded machine
  the rows per worker CPU second are the steadier figure.

With ``read`` instead of a scheduler: the driver's part alone — the same batches read and
pickled, nothing computed (the rate that bounds a cluster of any size).

Prints one JSON document.
"""

from __future__ import annotations

import json
import math
import pickle
import resource
import sys
import time
from collections.abc import Callable, Iterator

from distributed import get_task_stream

from atlas.dask_cluster import DaskCluster
from atlas.dask_search import search_map
from db.engine import open_atlas
from db.queries import AtlasSource
from synth import query as Q
from synth.query.candidates import Request


class Timed:
    """The batches' stream with the driver's cost of each batch: reading, pickling, bytes."""

    def __init__(self) -> None:
        self.read = self.dumped = self.loaded = 0.0
        self.sent = self.received = 0
        self.rows: list[int] = []

    def items(self, batches: Iterator[tuple]) -> Iterator[tuple]:
        while True:
            t = time.perf_counter()
            batch = next(batches, None)
            self.read += time.perf_counter() - t
            if batch is None:
                return
            t = time.perf_counter()
            self.sent += len(pickle.dumps(batch, protocol=5))
            self.dumped += time.perf_counter() - t
            self.rows.append(len(batch[2]))
            yield batch

    def results(self, results: Iterator[tuple]) -> Iterator[tuple]:
        for result in results:
            t = time.perf_counter()
            self.received += len(pickle.dumps(result, protocol=5))
            self.loaded += time.perf_counter() - t
            yield result

    def map(self, inner: Callable) -> Callable:
        return lambda fn, batches: self.results(inner(fn, self.items(batches)))


def _cpu_seconds() -> float:
    """User + system CPU seconds of this (worker) process so far."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def read_only(path: str, output: str, dwell: float, swing: float) -> dict:
    """The driver's read of the search's batches, with nothing computed."""
    request = Request(dwell=math.radians(dwell), swing=math.radians(swing), output=output, refine=False, complete=True)
    source = AtlasSource(open_atlas(path, readonly=True))
    timed = Timed()

    def nothing(_fn: Callable, batches: Iterator[tuple]) -> Iterator[tuple]:
        for requests, _kind, rows in timed.items(batches):
            yield [[] for _ in requests], len(rows), 0, [0 for _ in requests]

    wall, cpu = time.perf_counter(), time.process_time()
    Q.search(request, source, map_batches=nothing)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    source.engine.dispose()
    rows = sum(timed.rows)
    return {
        "request": f"{output} {dwell:g}°/{swing:g}°",
        "rows": rows,
        "wall_s": round(wall, 2),
        "driver_cpu_s": round(cpu, 2),
        "driver_pickle_s": round(timed.dumped, 3),
        "bytes_per_row_sent": round(timed.sent / max(rows, 1), 1),
        "read_rows_per_cpu_s": round(rows / cpu),
        "read_rows_per_s": round(rows / wall),
    }


def main(path: str, scheduler: str, output: str, dwell: float = 60.0, swing: float = 30.0) -> dict:
    request = Request(dwell=math.radians(dwell), swing=math.radians(swing), output=output, refine=False, complete=True)
    source = AtlasSource(open_atlas(path, readonly=True))
    timed = Timed()
    with DaskCluster.connect(scheduler) as cluster:
        threads = sum(cluster.client.nthreads().values())
        worker_cpu = sum(cluster.client.run(_cpu_seconds).values())
        with get_task_stream(client=cluster.client) as stream:
            wall, cpu = time.perf_counter(), time.process_time()
            found, count = Q.search(request, source, map_batches=timed.map(search_map(cluster)))
            wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        worker_cpu = sum(cluster.client.run(_cpu_seconds).values()) - worker_cpu
        tasks = [t for t in stream.data if str(t["key"]).startswith("('dwell-search")]
    source.engine.dispose()
    computed = [sum(s["stop"] - s["start"] for s in t["startstops"] if s["action"] == "compute") for t in tasks]
    busy = sum(computed)
    rows = sum(timed.rows)
    return {
        "request": f"{output} {dwell:g}°/{swing:g}°",
        "worker_threads": threads,
        "met": len(found),
        "rows": rows,
        "batches": len(timed.rows),
        "wall_s": round(wall, 2),
        "driver_cpu_s": round(cpu, 2),
        "driver_read_s": round(timed.read, 2),
        "driver_pickle_s": round(timed.dumped + timed.loaded, 3),
        "bytes_per_row_sent": round(timed.sent / max(rows, 1), 1),
        "bytes_received": timed.received,
        "worker_compute_s": round(busy, 2),
        "batch_compute_s_median": round(sorted(computed)[len(computed) // 2], 3) if computed else None,
        "rows_per_s_per_worker_thread": round(rows / busy) if busy else None,
        "worker_cpu_s": round(worker_cpu, 2),
        "rows_per_worker_cpu_s": round(rows / worker_cpu) if worker_cpu else None,
        "driver_read_rows_per_s": round(rows / timed.read) if timed.read else None,
        "simulated": count.simulated,
    }


if __name__ == "__main__":
    args = sys.argv[1:]
    angles = [float(a) for a in args[3:5]] or [60.0, 30.0]
    if args[1] == "read":
        print(json.dumps(read_only(args[0], args[2], *angles), indent=2))
    else:
        print(json.dumps(main(args[0], args[1], args[2], *angles), indent=2))
