"""The complete search's batches on a Dask cluster (``dwell query --complete --engine dask``).

:func:`search_map` is the ``map_batches`` of :func:`synth.query.search`: the driver reads the
atlas in batches of :data:`synth.query.BATCH` rows, as the local search does, and each batch —
the rows themselves, with the requests — is submitted to the cluster, which runs
:func:`synth.query.search_batch` on it; a cluster never needs the database file. The cluster
is used as the build uses it (:class:`atlas.dask_cluster.DaskCluster`: connect first, the same
dwell-atlas version on every worker, a few batches per worker thread in flight, Ctrl-C
cancels what is pending). The results come back in completion order; the answer does not
depend on it (the search's six-bars are ranked by Pareto layer, score and id, ids unique), so
it is the local search's, six-bar for six-bar.
"""

from __future__ import annotations

import functools

from atlas.dask_cluster import DaskCluster, Work
from synth.query.contract import BatchMap

__all__ = ["SEARCH_WORK", "search_map"]

#: How the cluster's errors name a complete search's work.
SEARCH_WORK = Work(
    noun="batch",
    role="query",
    after="the search stopped without an answer: run the query again",
    name="dwell-search",
)


def search_map(cluster: DaskCluster) -> BatchMap:
    """The ``map_batches`` of :func:`synth.query.search` that runs each batch on ``cluster``."""
    return functools.partial(cluster.map, work=SEARCH_WORK)
