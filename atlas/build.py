"""The atlas build driver: draw the sweep once, run the missing shards, write each result.

Two parts with a narrow seam between them, so that another engine (Dask distributed,
issue #8) can be added without touching the writer:

* a **shard runner** — any callable shaped like :func:`run_shards`: given the spec, the drawn
  sweep and the shard indices to compute, it yields :class:`~atlas.shard.ShardResult` objects
  in any order (ids are deterministic, so completion order does not matter). The local
  runner uses the driver's process (``workers=1``) or a ``ProcessPoolExecutor``.
* the **writer** — :func:`build_atlas`, the only code that touches the database: it takes the
  builder lock (``db.writes``), writes every result as it arrives in its own transaction,
  reports progress to a callback (:class:`ShardDone`; the CLI draws the bar) and marks the
  build complete.

Interrupts: Ctrl-C (KeyboardInterrupt) cancels the pending shards, stops the workers and
propagates (the CLI exits 130); every shard committed before is kept and the next run of the
same command resumes. A kill (SIGKILL) loses at most the shards in flight: a half-written
shard is rolled back by the database, and the dead builder's lock is taken over.
"""

from __future__ import annotations

import sys
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import atlas.shard as _shard
from atlas.malloc import raise_malloc_thresholds
from atlas.pool import TICK_SECONDS, pool_map
from atlas.shard import ShardResult
from atlas.sweep import SweepLinkages, SweepSpec, sweep_linkages
from db.packed import PackedShard

# TICK_SECONDS: how often a runner calls its tick while waiting (the Dask engine reads it here)
__all__ = ["TICK_SECONDS", "BuildSummary", "ShardDone", "ShardRunner", "build_atlas", "run_shards"]


@dataclass(frozen=True, slots=True)
class ShardDone:
    """Progress of a build run, for a display (the CLI's progress bar).

    Reported once before the first shard is computed (``shard_index`` None: the run starts,
    nothing is done yet — a display starts its clock and learns the total), then once after
    each shard is written, in completion order. A run with nothing to compute reports nothing.

    Attributes
    ----------
    shard_index : int or None
        The shard just written (None for the opening report).
    linkages : int
        Linkages (proportions × branches) of that shard; 0 in the opening report.
    linkages_done, linkages_total : int
        Linkages written so far in this run, and all this run computes (the missing shards').
    segments_done : int
        Segments written so far in this run.
    shards_left : int
        Shards of this run still to come (0 after the last one).
    """

    shard_index: int | None
    linkages: int
    linkages_done: int
    linkages_total: int
    segments_done: int
    shards_left: int


class ShardRunner(Protocol):
    """An engine that computes shards. It must not touch the database."""

    def __call__(
        self,
        spec: SweepSpec,
        sweep: SweepLinkages,
        indices: Sequence[int],
        workers: int,
        *,
        tick: Callable[[], None] | None = None,
    ) -> Iterator[ShardResult | PackedShard]:
        """Yield the result of every shard in ``indices`` (any order). Call ``tick`` at least
        every few seconds while waiting. Closing the iterator must stop all work promptly."""
        ...


# ---------------------------------------------------------------------------- local engine

#: (spec, sweep) of a worker process, set once by :func:`_init_worker`.
_WORKER_STATE: tuple[SweepSpec, SweepLinkages] | None = None


def _init_worker(spec: SweepSpec, sweep: SweepLinkages) -> None:
    global _WORKER_STATE
    raise_malloc_thresholds()
    _WORKER_STATE = (spec, sweep)


def _compute_in_worker(index: int) -> ShardResult | PackedShard:
    assert _WORKER_STATE is not None, "worker not initialised"
    spec, sweep = _WORKER_STATE
    return _shard.handed_over(_shard.compute_shard(spec, index, sweep))


def run_shards(
    spec: SweepSpec,
    sweep: SweepLinkages,
    indices: Sequence[int],
    workers: int = 1,
    *,
    tick: Callable[[], None] | None = None,
) -> Iterator[ShardResult | PackedShard]:
    """The local engine: ``workers == 1`` computes in this process, in order; more runs a
    process pool (:func:`atlas.pool.pool_map`) with at most ``2 · workers`` shards in flight
    (results are written as they come, so memory stays bounded whatever the sweep size), each
    worker handing its shard over packed (:func:`atlas.shard.handed_over`)."""
    indices = list(indices)
    if workers <= 1 or len(indices) <= 1:
        raise_malloc_thresholds()
        for index in indices:
            yield _shard.compute_shard(spec, index, sweep)
        return
    yield from pool_map(
        _compute_in_worker,
        indices,
        min(workers, len(indices)),
        initializer=_init_worker,
        initargs=(spec, sweep),
        # the forkserver computes a small shard first: the workers inherit the compiled kernels
        preload=("atlas.build", "atlas.warm_kernels"),
        tick=tick,
    )


# ---------------------------------------------------------------------------- the writer


@dataclass(frozen=True, slots=True)
class BuildSummary:
    """The outcome of :func:`build_atlas`.

    ``linkages``, ``segments`` (kind → count) and ``dwells`` count the whole build in the
    database; ``shards_written``, ``linkages_computed`` and ``seconds`` (wall clock) this run
    only. ``linkages_computed`` counts (proportion, branch) pairs attempted, stored or skipped.
    """

    target: str
    build_id: int
    complete: bool
    resumed: bool
    replaced: str | None
    n_shards: int
    shards_done: int
    shards_written: int
    linkages: int
    segments: dict[str, int]
    dwells: int
    linkages_computed: int
    seconds: float

    @property
    def rate(self) -> float:
        """Linkages computed per second of this run (0 when nothing was computed)."""
        return self.linkages_computed / self.seconds if self.seconds > 0 and self.linkages_computed else 0.0

    def line(self) -> str:
        """The one-line report printed at the end of ``dwell atlas build``."""
        segs = ", ".join(f"{k} {n}" for k, n in self.segments.items())
        state = "complete" if self.complete else f"{self.shards_done}/{self.n_shards} shards"
        if self.shards_written == 0 and self.complete:
            return f"atlas {self.target} is already complete: {self.linkages} linkages; segments: {segs}"
        return (
            f"atlas {self.target} {state}: {self.linkages} linkages; segments: {segs}; "
            f"{self.shards_written} shard(s) in {self.seconds:.1f} s ({self.rate:.0f} linkages/s)"
        )


def _remove_new_file(path: Path | None) -> None:
    """Remove an empty SQLite file (and side files) that this run created but could not make
    an atlas of: bad input leaves no file behind. A file with content is left alone, since
    another builder that started at the same moment may be writing it."""
    if path is None:
        return
    try:
        if path.stat().st_size > 0:
            return
    except OSError:
        pass
    for p in (path, *(path.with_name(path.name + s) for s in ("-wal", "-shm", "-journal"))):
        try:
            p.unlink()
        except OSError:
            pass


def build_atlas(
    target: str,
    spec: SweepSpec,
    *,
    workers: int = 1,
    replace: bool = False,
    on_shard: Callable[[ShardDone], None] | None = None,
    runner: ShardRunner = run_shards,
    log: Callable[[str], None] | None = None,
) -> BuildSummary:
    """Build (or resume) the atlas of ``spec`` at ``target`` (SQLite path or SQLAlchemy URL).

    ``on_shard`` receives the run's progress (:class:`ShardDone`: once at the start, then
    after each written shard); it must not raise. ``log`` receives one-line notes (resuming, replacing,
    interrupted). Errors: :class:`db.AtlasError` for an unusable atlas, a different sweep
    without ``replace`` or a concurrent builder — then nothing was written, and a file this
    call created but could not open as an atlas is removed again.

    With ``workers > 1`` the pool starts its workers by forkserver (spawn where there is no
    forkserver): a script calling this must guard its entry point with
    ``if __name__ == "__main__":``, as for any multiprocessing code.
    """
    from db.engine import display_target, open_atlas, settle_sqlite, sqlite_path
    from db.summary import row_counts
    from db.writes import (
        BuildLock,
        finish_build,
        heartbeat,
        open_build,
        release_lock,
        write_shard,
    )

    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    note = log if log is not None else (lambda _msg: None)
    t0 = time.perf_counter()
    path = sqlite_path(target)
    created = path is not None and not path.exists()
    sweep = sweep_linkages(spec)
    n_shards = sweep.n_shards(spec.shard_size)
    lock = BuildLock.mine()
    try:
        engine = open_atlas(target, create=True)
    except BaseException:
        if created:
            _remove_new_file(path)
        raise
    try:
        handle = open_build(
            engine,
            target=target,
            spec_json=spec.to_json(),
            spec_digest=spec.digest,
            n_shards=n_shards,
            lock=lock,
            replace=replace,
        )
    except BaseException:
        # not removed even if this call created the file: on a new atlas this only fails when
        # another builder got there first, and the file is now that builder's
        engine.dispose()
        raise

    holding = not handle.complete
    written = computed = 0
    complete = handle.complete
    try:
        if handle.replaced:
            note(f"replacing the previous build of {display_target(target)} ({handle.replaced})")
        missing = [i for i in range(n_shards) if i not in handle.done]
        if handle.resumed and missing:
            note(f"resuming: {len(handle.done)} of {n_shards} shards already built")
        per_shard = {i: len(sweep.shard(i, spec.shard_size)) * len(spec.branches) for i in missing}
        report = on_shard if on_shard is not None and missing else (lambda _event: None)
        total = sum(per_shard.values())
        report(ShardDone(None, 0, 0, total, 0, len(missing)))
        results = runner(spec, sweep, missing, workers, tick=lambda: heartbeat(engine, handle.build_id, lock.token))
        segments = 0
        try:
            for result in results:
                if result.shard_index not in per_shard:
                    raise RuntimeError(f"shard runner returned shard {result.shard_index}, which was not asked for")
                write_shard(engine, handle.build_id, result, lock_token=lock.token)
                n = per_shard.pop(result.shard_index)
                written += 1
                computed += n
                segments += result.n_segments
                report(ShardDone(result.shard_index, n, computed, total, segments, len(per_shard)))
        except KeyboardInterrupt:
            note(
                f"interrupted: {len(handle.done) + written} of {n_shards} shards are stored; "
                "run the same command again to resume"
            )
            raise
        finally:
            close = getattr(results, "close", None)
            if close is not None:
                close()
        if not complete:
            complete = finish_build(engine, handle.build_id, lock.token)
            holding = not complete
            if not complete:  # an engine that silently dropped shards: a bug, not input
                raise RuntimeError(f"build {handle.build_id}: shards missing after the run: {sorted(per_shard)[:10]}")
        linkages, segs, dwells = row_counts(engine, handle.build_id)
        if complete and not settle_sqlite(engine):
            note(
                "the atlas stays in WAL mode (another process had it open); "
                "run the same command again to fold its write-ahead log in"
            )
        return BuildSummary(
            target=display_target(target),  # printed by line(): a URL's password is not
            build_id=handle.build_id,
            complete=complete,
            resumed=handle.resumed,
            replaced=handle.replaced,
            n_shards=n_shards,
            shards_done=len(handle.done) + written,
            shards_written=written,
            linkages=linkages,
            segments=segs,
            dwells=dwells,
            linkages_computed=computed,
            seconds=time.perf_counter() - t0,
        )
    finally:
        if holding:
            in_flight = sys.exc_info()[1]
            if in_flight is not None:
                # A Ctrl-C that lands inside the SQLite driver (its executemany, say) leaves the
                # statement it ran, and with it the connection's write transaction, alive for
                # as long as the traceback's frames hold the cursor: SQLAlchemy has closed that
                # connection, but SQLite finishes closing it only once the statement is
                # finalized, and until then this write waits out the busy timeout (30 s; found
                # by a random-seed run). Dropping the finished frames' locals finalizes it; the
                # traceback's lines are kept.
                traceback.clear_frames(in_flight.__traceback__)
            try:
                release_lock(engine, handle.build_id, lock.token)
            except Exception:  # noqa: BLE001 - never mask the error that got us here
                pass
        engine.dispose()
