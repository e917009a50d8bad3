"""The Dask distributed engine of the atlas build: shards run on a cluster, the driver writes.

:class:`DaskRunner` is a :class:`~atlas.build.ShardRunner`: pass it to
:func:`~atlas.build.build_atlas` as ``runner``. Workers only call
:func:`atlas.shard.compute_shard` and return its result packed (:func:`atlas.shard.handed_over`,
picklable bytes); the driver (this process) alone touches the database, so
the content is the local engine's, byte for byte, whatever the cluster does.

The cluster is used as :class:`atlas.dask_cluster.DaskCluster` uses it (the complete query
runs on the same): it is reached before the builder opens the atlas (a bad or unreachable
address writes nothing); the spec and the drawn sweep (27 MB for ``large``) are scattered to
every worker once per run and each task carries only its shard index; at most
:data:`~atlas.dask_cluster.IN_FLIGHT_PER_THREAD` shards per worker thread are in flight, so a
3 000-shard ``large`` sweep never holds more results than that on the cluster; a worker of
another dwell-atlas version is refused (the build records one code version); closing the
iterator (Ctrl-C, an error in the writer) cancels every pending shard, and Ctrl-C is raised
where the runner waits, never in the middle of a database write.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence

import atlas.build as _build
import atlas.shard as _shard
from atlas.dask_cluster import IN_FLIGHT_PER_THREAD, INSTALL_HINT, ClusterError, DaskCluster, Work
from atlas.shard import ShardResult
from atlas.sweep import SweepLinkages, SweepSpec
from db.packed import PackedShard

__all__ = ["BUILD_WORK", "INSTALL_HINT", "IN_FLIGHT_PER_THREAD", "ClusterError", "DaskRunner"]

#: How the cluster's errors name a build's work.
BUILD_WORK = Work(
    noun="shard",
    role="builder",
    after="the shards written so far are kept: run the same command again to resume",
    name="dwell-shard",
)


def _compute_shard(index: int, spec: SweepSpec, sweep: SweepLinkages) -> ShardResult | PackedShard:
    """The task: shard ``index`` of ``spec``, packed for the driver."""
    return _shard.handed_over(_shard.compute_shard(spec, index, sweep))


class DaskRunner(DaskCluster):
    """A :class:`~atlas.build.ShardRunner` on a ``dask.distributed`` cluster.

    Parameters
    ----------
    client : distributed.Client
        A connected client; the runner does not close it unless it made it
        (:meth:`connect`, then :meth:`close` or ``with``).
    in_flight : int, optional
        Shards submitted at a time. Default: :data:`IN_FLIGHT_PER_THREAD` × the cluster's
        worker threads (at least 2), re-read every few seconds.
    log : callable, optional
        Receives one-line notes (the cluster's size, waiting for workers).

    The ``workers`` argument of :meth:`__call__` is ignored: the cluster's workers decide.
    """

    def __call__(
        self,
        spec: SweepSpec,
        sweep: SweepLinkages,
        indices: Sequence[int],
        workers: int = 1,
        *,
        tick: Callable[[], None] | None = None,
    ) -> Iterator[ShardResult | PackedShard]:
        """Yield the result of every shard in ``indices`` in completion order. ``tick`` is
        called at least every :data:`atlas.build.TICK_SECONDS` while waiting, also while no
        worker has joined yet. Ctrl-C is deferred to the runner's waits
        (:meth:`~atlas.dask_cluster.DaskCluster.map`)."""
        return self.map(
            _compute_shard,
            list(indices),
            work=BUILD_WORK,
            shared=(spec, sweep),
            number=int,
            tick=tick,
            tick_seconds=_build.TICK_SECONDS,
        )
