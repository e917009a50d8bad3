"""A ``dask.distributed`` cluster as dwell uses it: a function over a stream of items on the
cluster's workers, results in completion order. The atlas build runs its shards on it
(:class:`atlas.dask_engine.DaskRunner`) and the complete query its batches of segments
(``dwell query --complete --engine dask``).

How the cluster is used, and why:

* **connect first** — :meth:`DaskCluster.connect` reaches the scheduler before the caller
  opens its database, so a bad or unreachable address does nothing (no file, no row read).
* **scatter once** — what every task needs (``shared``: the build's spec and drawn sweep,
  27 MB for ``large``) is scattered to every worker once per :meth:`DaskCluster.map`
  (``broadcast=True``); each task carries only its own item. A worker that joins later
  fetches it from a peer.
* **bounded in flight** — at most :data:`IN_FLIGHT_PER_THREAD` items per worker thread are
  submitted at any time (re-read every :data:`CAPACITY_SECONDS` as workers come and go): a
  thread never idles while the driver takes a result, the items are read from their stream
  only as they are submitted, and the cluster never holds more than that many results. A
  result is released as soon as it is fetched.
* **same code everywhere** — a task refuses to run on a worker whose dwell-atlas version
  differs from the driver's (a build records one code version; a query's answer is one code's).
* **stop promptly** — closing the iterator (Ctrl-C, an error in the caller) cancels every
  pending task and the scattered data. A task already running finishes on its worker (Dask
  cannot interrupt a task) and is discarded. Ctrl-C is raised where the map waits, not in
  the middle of the caller's database work or of dask's bookkeeping: an SQLite transaction
  cut by KeyboardInterrupt keeps its write lock until garbage collection, and a build's lock
  release would then wait out the 30 s busy timeout.

``distributed`` is imported only here and only when used: the base install (without the
``dask`` extra) never imports it.
"""

from __future__ import annotations

import functools
import itertools
import signal
import threading
import time
import uuid
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from types import ModuleType
from typing import TYPE_CHECKING, Any, Self, TypeVar

from atlas.malloc import raise_malloc_thresholds
from atlas.pool import TICK_SECONDS

if TYPE_CHECKING:
    from distributed import Client, Future, as_completed

__all__ = [
    "CAPACITY_SECONDS",
    "INSTALL_HINT",
    "IN_FLIGHT_PER_THREAD",
    "POLL_SECONDS",
    "ClusterError",
    "DaskCluster",
    "Work",
    "import_distributed",
    "installed_version",
]

#: What a user without the ``dask`` extra is told to do.
INSTALL_HINT = "install the dask extra: pip install 'dwell-atlas[dask]'"
#: Items submitted per worker thread: one computing, one queued behind it.
IN_FLIGHT_PER_THREAD = 2
#: How often the cluster's thread count is re-read (seconds); workers come and go.
CAPACITY_SECONDS = 5.0
#: Poll interval while waiting for a result (seconds); ``as_completed`` itself polls at 0.1 s.
POLL_SECONDS = 0.05

T = TypeVar("T")
R = TypeVar("R")


class ClusterError(RuntimeError):
    """The cluster cannot be used as asked: dask is not installed, a bad or unreachable
    scheduler address, the scheduler lost or a task killed its workers, or a worker with
    another dwell-atlas version. The message is one line naming the problem."""


@dataclass(frozen=True, slots=True)
class Work:
    """How the cluster's errors name the work of one :meth:`DaskCluster.map`.

    Attributes
    ----------
    noun : str
        One task's item (``shard``, ``batch``).
    role : str
        This process, as a worker of another version is told (``builder``, ``query``).
    after : str
        What the user can do once the work failed (what is kept, what to run again).
    name : str
        Prefix of the task keys: the dashboard groups a map's tasks under it.
    """

    noun: str
    role: str
    after: str
    name: str


def import_distributed() -> ModuleType:
    """``distributed``, or a :class:`ClusterError` telling how to install it."""
    try:
        import distributed
    except ImportError as exc:
        raise ClusterError(f"the dask engine cannot import dask.distributed ({exc}); {INSTALL_HINT}") from None
    return distributed


@functools.cache
def installed_version() -> str:
    """The dwell-atlas version installed in this process (:func:`db.writes.code_version`)."""
    from db.writes import code_version

    return code_version()


def _run_checked(fn: Callable[..., R], item: object, version: str, role: str, *shared: object) -> R:
    """The task: ``fn(item, *shared)``, after checking this worker runs the driver's dwell-atlas
    ``version`` (and undoing dask's malloc setting, see :mod:`atlas.malloc`)."""
    mine = installed_version()
    if mine != version:
        from distributed import get_worker

        raise ClusterError(
            f"dask worker {get_worker().address} runs dwell-atlas {mine}, this {role} {version}: "
            "install the same version on every node"
        )
    raise_malloc_thresholds()
    return fn(item, *shared)


class DaskCluster:
    """A ``dask.distributed`` cluster that runs a function over a stream of items (:meth:`map`).

    Parameters
    ----------
    client : distributed.Client
        A connected client; it is not closed unless it was made by :meth:`connect` (then
        :meth:`close`, or ``with``).
    in_flight : int, optional
        Items submitted at a time. Default: :data:`IN_FLIGHT_PER_THREAD` × the cluster's
        worker threads (at least 2), re-read every :data:`CAPACITY_SECONDS`.
    log : callable, optional
        Receives one-line notes (the cluster's size, waiting for workers).
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
    def connect(cls, address: str, *, in_flight: int | None = None, log: Callable[[str], None] | None = None) -> Self:
        """Connect to the scheduler at ``address`` (``tcp://host:8786``; a bare ``host:port``
        means tcp). The wait is dask's ``distributed.comm.timeouts.connect`` (30 s unless
        configured, e.g. ``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=5s``).

        Raises :class:`ClusterError` when dask is missing or the address is malformed or
        unreachable.
        """
        distributed = import_distributed()
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
        cluster = cls(client, in_flight=in_flight, log=log)
        cluster._owns_client = True
        return cluster

    def close(self) -> None:
        """Close the client if :meth:`connect` made it."""
        if self._owns_client:
            self.client.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # ------------------------------------------------------------------ the map

    def map(
        self,
        fn: Callable[..., R],
        items: Iterable[T],
        *,
        work: Work,
        shared: tuple[Any, ...] = (),
        number: Callable[[T], int] | None = None,
        tick: Callable[[], None] | None = None,
        tick_seconds: float = TICK_SECONDS,
    ) -> Iterator[R]:
        """``fn(item, *shared)`` for every item, on the cluster, yielded in completion order
        (see the module notes). ``fn`` must be a module-level function of a module every worker
        has; ``items`` are read only as they are submitted. ``number(item)`` names an item in
        task keys and error messages (default: its place in the stream, from 0). ``tick`` is
        called at least every ``tick_seconds`` while waiting, also while no worker has joined yet.

        A task's own exception propagates as is (a bug, as with local processes); what the
        cluster did to a task is a :class:`ClusterError` naming ``work``.

        Ctrl-C (SIGINT, in the main thread) is deferred from the first ``next()`` until the
        iterator is closed: the first one raises KeyboardInterrupt at the next wait for a
        result, never inside the caller's code between two results or inside dask's own
        bookkeeping (either can be left holding a lock); a second one raises at once.
        """
        distributed = import_distributed()
        beat = tick if tick is not None else (lambda: None)
        todo = enumerate(items)
        first = next(todo, None)
        if first is None:
            return
        todo = itertools.chain([first], todo)  # read again: nothing is submitted before the cluster is up
        client = self.client
        pending: set[Future] = set()
        scattered: list[Future] = []
        ctrl_c = _DeferredInterrupt()
        try:
            ctrl_c.install()
            self._wait_for_workers(beat, ctrl_c, tick_seconds)
            version = installed_version()
            if shared:
                scattered = client.scatter(list(shared), broadcast=True, hash=False)
            # tuple keys (name, number): the dashboard groups them as one task group
            name = f"{work.name}-{uuid.uuid4().hex[:8]}"
            done: as_completed = distributed.as_completed(loop=client.loop)
            capacity = _Capacity(client, self.in_flight)

            def refill() -> None:
                while len(pending) < capacity():
                    place, item = next(todo, (None, _END))
                    if item is _END:
                        return
                    key = (name, number(item) if number is not None else place)
                    future = client.submit(_run_checked, fn, item, version, work.role, *scattered, key=key)
                    pending.add(future)
                    done.add(future)

            refill()
            while pending:
                for future in self._next_batch(done, beat, ctrl_c, work, tick_seconds):
                    ctrl_c.check()  # also between the results of one batch
                    pending.discard(future)
                    result = _result_of(future, work)
                    future.release()  # frees the result on the cluster now, not at garbage collection
                    refill()  # keep the workers busy while the caller takes the result
                    yield result
        finally:
            self._cancel([*pending, *scattered])
            ctrl_c.restore()

    def _wait_for_workers(self, beat: Callable[[], None], ctrl_c: _DeferredInterrupt, tick_seconds: float) -> None:
        """Block (ticking) until the scheduler has a worker; note the cluster's size."""
        waited = 0.0
        while not (threads := self.client.nthreads()):
            ctrl_c.check()
            if waited == 0.0:
                self._log(f"no dask workers at {self.client.scheduler.address} yet; waiting for one to join")
            if waited >= tick_seconds:
                beat()
                waited = 0.0
            time.sleep(1.0)
            waited += 1.0
        self._log(
            f"dask: {len(threads)} worker(s), {sum(threads.values())} thread(s) at {self.client.scheduler.address}"
        )

    def _next_batch(
        self, done: as_completed, beat: Callable[[], None], ctrl_c: _DeferredInterrupt, work: Work, tick_seconds: float
    ) -> list[Future]:
        """The futures finished since the last call, at least one; ticks while waiting, raises
        a deferred Ctrl-C, and fails if the client has lost its scheduler for good."""
        since = time.monotonic()
        ctrl_c.check()
        while not done.has_ready():
            ctrl_c.check()
            if self.client.status in ("closing", "closed"):
                raise ClusterError(f"lost the connection to the dask scheduler; {work.after}")
            if time.monotonic() - since >= tick_seconds:
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


_END = object()


class _DeferredInterrupt:
    """SIGINT noted instead of raised, so that KeyboardInterrupt surfaces only where the map
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
    """Items to keep in flight: fixed, or :data:`IN_FLIGHT_PER_THREAD` × the cluster's
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


def _result_of(future: Future, work: Work) -> object:
    """The task's result; its own exception propagates as is, what the cluster did to it
    becomes a :class:`ClusterError`."""
    from distributed import CancelledError, KilledWorker

    number = future.key[1]
    try:
        return future.result()
    except CancelledError as exc:
        raise ClusterError(f"{work.noun} {number} was cancelled on the cluster ({exc}); {work.after}") from None
    except KilledWorker as exc:
        raise ClusterError(f"{work.noun} {number} failed on the cluster: {exc}; {work.after}") from None
