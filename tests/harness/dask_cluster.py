"""A local dask cluster for the tests of the dask engine (the build's and the complete
query's), and what they ask its scheduler."""

from __future__ import annotations

import os
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager

from distributed import Client, LocalCluster

__all__ = ["drained", "free_port", "local_cluster", "tasks_on"]


@contextmanager
def local_cluster(n_workers: int) -> Iterator[LocalCluster]:
    """``n_workers`` single-threaded worker processes with dask's default settings. Their
    nannies run in this process and put the workers' environment (MALLOC_TRIM_THRESHOLD_,
    OMP_NUM_THREADS …) into ``os.environ`` too: it is put back, or every process the later
    tests start would inherit it."""
    saved = dict(os.environ)
    try:
        with LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            _restore_environ(saved)
            yield cluster
    finally:
        _restore_environ(saved)


def _restore_environ(saved: dict[str, str]) -> None:
    for key in set(os.environ) - set(saved):
        del os.environ[key]
    os.environ.update(saved)


def tasks_on(client: Client) -> int:
    """Tasks the scheduler holds (results and scattered data included)."""
    return client.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks))


def drained(client: Client, timeout: float = 10.0) -> bool:
    """True once the scheduler holds no task at all (the work and its scattered data are gone)."""
    deadline = time.monotonic() + timeout
    while tasks_on(client):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def free_port() -> int:
    """A local TCP port nobody listens on (connections are refused)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]
