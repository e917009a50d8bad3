"""The Dask distributed engine of the atlas build: shards run on a cluster, the driver writes.

:class:`DaskRunner` is a :class:`~atlas.build.ShardRunner`: pass it to
:func:`~atlas.build.build_atlas` as ``runner``. Workers only call
:func:`atlas.shard.compute_shard` and return its result packed (:func:`atlas.shard.handed_over`,
picklable bytes); the driver (this process) alone touches the database, so
the content is the local engine's, byte for byte, whatever the cluster does.

How the cluster is used, and why:

* **connect first** — :meth:`DaskRunner.connect` reaches the scheduler before the builder
  opens the atlas, so a bad or unreachable address writes nothing (no new file, no build row).
* **scatter once** — the spec and the drawn sweep (27 MB for ``large``) are scattered to every
  worker once per run (``broadcast=True``); each task carries only its shard index. A worker
  that joins later fetches them from a peer.
* **bounded in flight** — at most :data:`IN_FLIGHT_PER_THREAD` shards per worker thread are
  submitted at any time (re-read every few seconds as workers come and go): a thread never
  idles while the driver writes, and a 3 000-shard ``large`` sweep never holds more than that
  many results on the cluster. A result is released as soon as it is fetched.
* **same code everywhere** — a task refuses to run on a worker whose dwell-atlas version
  differs from the driver's (the build records one code version; mixed versions would mix
  contents).
* **stop promptly** — closing the iterator (Ctrl-C, an error in the writer) cancels every
  pending shard and the scattered data. A shard already running finishes on its worker (Dask
  cannot interrupt a task) and is discarded. Ctrl-C is raised where the runner waits, not in
  the middle of a database write or of dask's bookkeeping: an SQLite transaction cut by
  KeyboardInterrupt keeps its write lock until garbage collection, and the builder's lock
  release would then wait out the 30 s busy timeout.

``distributed`` is imported only here and only when used: the base install (without the
``dask`` extra) never imports it.
"""

from __future__ import annotations

import functools
import signal
import threading
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from types import ModuleType
from typing import TYPE_CHECKING, Self

import atlas.build as _build
import atlas.shard as _shard
from atlas.malloc import raise_malloc_thresholds
from atlas.shard import ShardResult
from atlas.sweep import SweepLinkages, SweepSpec
from db.packed import PackedShard

if TYPE_CHECKING:
    from distributed import Client, Future, as_completed

__all__ = ["INSTALL_HINT", "IN_FLIGHT_PER_THREAD", "ClusterError", "DaskRunner"]

#: What a user without the ``dask`` extra is told to do.
INSTALL_HINT = "install the dask extra: pip install 'dwell-atlas[dask]'"
#: Shards submitted per worker thread: one computing, one queued behind it.
IN_FLIGHT_PER_THREAD = 2
#: How often the cluster's thread count is re-read (seconds); workers come and go.
CAPACITY_SECONDS = 5.0
#: Poll interval while waiting for a shard (seconds); ``as_completed`` itself polls at 0.1 s.
POLL_SECONDS = 0.05


class ClusterError(RuntimeError):
    """The cluster cannot be used as asked: dask is not installed, a bad or unreachable
    scheduler address, the scheduler lost or a shard killed its workers mid-build, or a worker
    with another dwell-atlas version. The message is one line naming the problem; shards
    committed before are kept."""


def _distributed() -> ModuleType:
    """``distributed``, or a :class:`ClusterError` telling how to install it."""
    try:
        import distributed
    except ImportError as exc:
        raise ClusterError(f"the dask engine cannot import dask.distributed ({exc}); {INSTALL_HINT}") from None
    return distributed


@functools.cache
def _installed_version() -> str:
    from db.writes import code_version

    return code_version()


def _compute_on_worker(spec: SweepSpec, index: int, sweep: SweepLinkages, version: str) -> ShardResult | PackedShard:
    """The task: shard ``index`` of ``spec``, after checking this worker runs the driver's
    dwell-atlas ``version`` (and undoing dask's malloc setting, see :mod:`atlas.malloc`)."""
    mine = _installed_version()
    if mine != version:
        from distributed import get_worker

        raise ClusterError(
            f"dask worker {get_worker().address} runs dwell-atlas {mine}, this builder {version}: "
            "install the same version on every node"
        )
    raise_malloc_thresholds()
    return _shard.handed_over(_shard.compute_shard(spec, index, sweep))


class DaskRunner:
    """A :class:`~atlas.build.ShardRunner` on a ``dask.distributed`` cluster.

    Parameters
    ----------
    client : distributed.Client
        A connected client; the runner does not close it unless it made it
        (:meth:`connect`, then :meth:`close` or ``with``).
    in_flight : int, optional
        Shards submitted at a time. Default: :data:`IN_FLIGHT_PER_THREAD` × the cluster's
        worker threads (at least 2), re-read every :data:`CAPACITY_SECONDS`.
    log : callable, optional
        Receives one-line notes (the cluster's size, waiting for workers).

    The ``workers`` argument of :meth:`__call__` is ignored: the cluster's workers decide.
    """

    def __init__(
        self, client: Client, *, in_flight: int | None = None, log: Callable[[str], None] | None = None
    ) -> None:
        if in_flight is not None and in_flight < 1:
            raise ValueError(f"in_flight must be >= 1, got {in_flight}")
        self.client = client
        self.in_flight = in_flight
        self._log = log if log is not None else (lambda _msg: None)
        self._owns_client = False

    @classmethod
    def connect(
        cls, address: str, *, in_flight: int | None = None, log: Callable[[str], None] | None = None
    ) -> DaskRunner:
        """Connect to the scheduler at ``address`` (``tcp://host:8786``; a bare ``host:port``
        means tcp). The wait is dask's ``distributed.comm.timeouts.connect`` (30 s unless
        configured, e.g. ``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=5s``).

        Raises :class:`ClusterError` when dask is missing or the address is malformed or
        unreachable.
        """
        distributed = _distributed()
        from distributed.comm import get_address_host_port, normalize_address

        try:
            get_address_host_port(normalize_address(address))  # a known scheme, a host and a port
        except ValueError as exc:
            # checked here: a Client given a malformed address is left half-made and prints
            # a traceback when it is garbage-collected
            raise ClusterError(f"not a dask scheduler address: {address!r} ({exc})") from None
        try:
            client = distributed.Client(address, set_as_default=False)
        except (OSError, ImportError) as exc:  # ImportError: the scheduler refused our versions
            raise ClusterError(f"cannot connect to the dask scheduler at {address}: {exc}") from None
        runner = cls(client, in_flight=in_flight, log=log)
        runner._owns_client = True
        return runner

    def close(self) -> None:
        """Close the client if :meth:`connect` made it."""
        if self._owns_client:
            self.client.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # ------------------------------------------------------------------ the runner

    def __call__(
        self,
        spec: SweepSpec,
        sweep: SweepLinkages,
        indices: Sequence[int],
        workers: int = 1,
        *,
        tick: Callable[[], None] | None = None,
    ) -> Iterator[ShardResult | PackedShard]:
        """Yield the result of every shard in ``indices`` in completion order (see the module
        notes). ``tick`` is called at least every :data:`atlas.build.TICK_SECONDS` while
        waiting, also while no worker has joined yet.

        Ctrl-C (SIGINT, in the main thread) is deferred from the first ``next()`` until the
        iterator is closed: the first one raises KeyboardInterrupt at the next wait for a shard,
        never inside a database write of the caller or inside dask's own bookkeeping (either
        can be left holding a lock); a second one raises at once.
        """
        distributed = _distributed()
        indices = list(indices)
        if not indices:
            return
        beat = tick if tick is not None else (lambda: None)
        client = self.client
        todo = iter(indices)
        pending: set[Future] = set()
        scattered: list[Future] = []
        ctrl_c = _DeferredInterrupt()
        try:
            ctrl_c.install()
            self._wait_for_workers(beat, ctrl_c)
            version = _installed_version()
            scattered = client.scatter([spec, sweep], broadcast=True, hash=False)
            spec_f, sweep_f = scattered
            # tuple keys (name, index): the dashboard groups them as one "dwell-shard" task group
            name = f"dwell-shard-{uuid.uuid4().hex[:8]}"
            done: as_completed = distributed.as_completed(loop=client.loop)
            capacity = _Capacity(client, self.in_flight)

            def refill() -> None:
                while len(pending) < capacity():
                    index = next(todo, None)
                    if index is None:
                        return
                    future = client.submit(_compute_on_worker, spec_f, index, sweep_f, version, key=(name, index))
                    pending.add(future)
                    done.add(future)

            refill()
            while pending:
                for future in self._next_batch(done, beat, ctrl_c):
                    ctrl_c.check()  # also between the results of one batch
                    pending.discard(future)
                    result = _result_of(future)
                    future.release()  # frees the result on the cluster now, not at garbage collection
                    refill()  # keep the workers busy while the driver writes
                    yield result
        finally:
            self._cancel([*pending, *scattered])
            ctrl_c.restore()

    def _wait_for_workers(self, beat: Callable[[], None], ctrl_c: _DeferredInterrupt) -> None:
        """Block (ticking) until the scheduler has a worker; note the cluster's size."""
        waited = 0.0
        while not (threads := self.client.nthreads()):
            ctrl_c.check()
            if waited == 0.0:
                self._log(f"no dask workers at {self.client.scheduler.address} yet; waiting for one to join")
            if waited >= _build.TICK_SECONDS:
                beat()
                waited = 0.0
            time.sleep(1.0)
            waited += 1.0
        self._log(
            f"dask: {len(threads)} worker(s), {sum(threads.values())} thread(s) at {self.client.scheduler.address}"
        )

    def _next_batch(self, done: as_completed, beat: Callable[[], None], ctrl_c: _DeferredInterrupt) -> list[Future]:
        """The futures finished since the last call, at least one; ticks while waiting, raises
        a deferred Ctrl-C, and fails if the client has lost its scheduler for good."""
        since = time.monotonic()
        ctrl_c.check()
        while not done.has_ready():
            ctrl_c.check()
            if self.client.status in ("closing", "closed"):
                raise ClusterError(
                    "lost the connection to the dask scheduler; "
                    "the shards written so far are kept: run the same command again to resume"
                )
            if time.monotonic() - since >= _build.TICK_SECONDS:
                beat()
                since = time.monotonic()
            time.sleep(POLL_SECONDS)
        return done.next_batch(block=False)

    def _cancel(self, futures: list[Future]) -> None:
        """Cancel what is pending and drop the scattered data (best effort: the scheduler may
        be gone, and this runs while an error or Ctrl-C propagates)."""
        if not futures or self.client.status != "running":
            return
        try:
            self.client.cancel(futures)
        except Exception:  # noqa: BLE001 - never mask the error that got us here
            pass


class _DeferredInterrupt:
    """SIGINT noted instead of raised, so that KeyboardInterrupt surfaces only where the runner
    checks for it (:meth:`check`); a second SIGINT, or one after :meth:`restore`, raises at
    once. Installed only in the main thread and only over Python's default handler (a caller's
    own handler is left alone)."""

    def __init__(self) -> None:
        self.requested = False
        self._active = False
        self._previous: object = None

    def install(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
            return
        self._previous = signal.signal(signal.SIGINT, self._note)
        self._active = True

    def _note(self, _signum: int, _frame: object) -> None:
        if self.requested or not self._active:
            raise KeyboardInterrupt
        self.requested = True

    def check(self) -> None:
        """Raise the deferred KeyboardInterrupt, if there is one."""
        if self.requested:
            self.requested = False
            raise KeyboardInterrupt

    def restore(self) -> None:
        """Put the previous handler back. An iterator closed by garbage collection may run
        this in another thread, where handlers cannot be set: then this one stays but
        behaves like the default (raises at once)."""
        self._active = False
        if self._previous is not None and threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None


class _Capacity:
    """Shards to keep in flight: fixed, or :data:`IN_FLIGHT_PER_THREAD` × the cluster's
    threads, re-read at most every :data:`CAPACITY_SECONDS`."""

    def __init__(self, client: Client, fixed: int | None) -> None:
        self._client = client
        self._fixed = fixed
        self._value = 2
        self._read_at = -float("inf")

    def __call__(self) -> int:
        if self._fixed is not None:
            return self._fixed
        now = time.monotonic()
        if now - self._read_at >= CAPACITY_SECONDS:
            threads = sum(self._client.nthreads().values())
            self._value = max(2, IN_FLIGHT_PER_THREAD * threads)
            self._read_at = now
        return self._value


def _result_of(future: Future) -> ShardResult | PackedShard:
    """The shard's result; a shard's own exception propagates as is (a bug, like in the local
    engine), what the cluster did to it becomes a :class:`ClusterError`."""
    from distributed import CancelledError, KilledWorker

    index = future.key[1]
    try:
        return future.result()
    except CancelledError as exc:
        raise ClusterError(
            f"shard {index} was cancelled on the cluster ({exc}); "
            "the shards written so far are kept: run the same command again to resume"
        ) from None
    except KilledWorker as exc:
        raise ClusterError(
            f"shard {index} failed on the cluster: {exc}; "
            "the shards written so far are kept: run the same command again to resume"
        ) from None
