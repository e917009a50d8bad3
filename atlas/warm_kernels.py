"""Imported by the atlas build's forkserver (:func:`atlas.build.run_shards` preloads it): the
import computes one small shard, so that a shard's compiled kernels are compiled — or loaded
from numba's cache — once, in the forkserver, before it forks the pool's workers, which
inherit them. Without it every worker compiles the same kernels from an empty cache at the
same moment (``docs/benchmarks-first-run.md``: ~25 s of CPU each on a first run); with a
filled cache it costs the loads a single worker would have made and a shard of
:data:`WARM_PROPORTIONS` proportions.

The forkserver imports its preload modules only; this one does its work on import, and
nothing else imports it.
"""

from __future__ import annotations

import dataclasses

__all__ = ["WARM_PROPORTIONS", "warm_shard_kernels"]

#: Proportions of the demo sweep computed to warm the kernels: its first four (on both
#: branches) reach every kernel of a shard, with arrays of the layouts the real shards pass.
WARM_PROPORTIONS = 4


def warm_shard_kernels() -> None:
    """Compute the first :data:`WARM_PROPORTIONS` proportions of the ``demo`` sweep on one
    thread (a pool worker's batches are not split either when the workers take every core),
    the thread count restored afterwards. Any error is dropped: the workers then compile
    what they need themselves, and a shard that fails for real fails there, with its own
    error."""
    from atlas.shard import compute_shard
    from atlas.sweep import PRESETS
    from synth.parallel_rows import set_threads, threads

    before = threads()
    try:
        set_threads(1)
        compute_shard(dataclasses.replace(PRESETS["demo"], shard_size=WARM_PROPORTIONS), 0)
    except Exception:  # noqa: BLE001 - a warm-up must never stop the forkserver
        pass
    finally:
        set_threads(before)


warm_shard_kernels()
