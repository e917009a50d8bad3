"""Progress on stderr, fed by the library's callbacks: the atlas build's
(:class:`atlas.build.ShardDone` events), the complete query's (rows searched) and the report's
(candidates written).

The library reports progress and never imports a bar; the commands own it here. What a command
shows depends on where its stderr goes:

* a terminal: a tqdm line, drawn once the job has run :data:`DELAY` seconds (a quick answer
  draws nothing) — a bar when the job reports a count, else the time elapsed;
* anything else (a log, a pipe), for the long jobs (``dwell atlas build``, ``dwell demo``,
  ``dwell query --complete``): one status line every :func:`status_interval` seconds, so that a
  log is never silent for minutes; nothing for the others.
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Self

if TYPE_CHECKING:
    from atlas.build import ShardDone

__all__ = ["DELAY", "STATUS_INTERVAL", "BuildBar", "Progress", "SearchBar", "status_interval"]

#: Seconds a job runs before its line is drawn on a terminal.
DELAY = 1.0
#: Seconds between two status lines when stderr is not a terminal; ``$DWELL_STATUS_INTERVAL``
#: overrides it (the tests take a fraction of a second).
STATUS_INTERVAL = 10.0
#: Seconds between two redraws of a terminal line (its clock moves even when no count does).
_REDRAW = 0.25


def status_interval() -> float:
    """:data:`STATUS_INTERVAL`, or ``$DWELL_STATUS_INTERVAL`` when it holds a positive number of
    seconds (anything else is ignored: a progress display never stops a job)."""
    try:
        value = float(os.environ.get("DWELL_STATUS_INTERVAL", ""))
    except ValueError:
        return STATUS_INTERVAL
    return value if math.isfinite(value) and value > 0 else STATUS_INTERVAL


class Progress:
    """The progress of one command on stderr; a context manager (a daemon thread draws it, so
    that the clock moves while the work holds the main thread).

    Parameters
    ----------
    job : str
        The command's name, first on every status line (``atlas``, ``demo``, ``query``).
    terminal : bool or None
        Draw a tqdm line (True), or not (False); None: if stderr is a terminal.
    log : bool
        When not drawing a line: print a status line every :func:`status_interval` seconds
        (the long jobs). False: show nothing.

    The work calls :meth:`stage` when it starts a part (with its count, if it has one) and
    :meth:`advance` as the count grows.
    """

    def __init__(self, job: str, *, terminal: bool | None = None, log: bool = False) -> None:
        self.job = job
        self.terminal = sys.stderr.isatty() if terminal is None else bool(terminal)
        self.log = bool(log) and not self.terminal
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._bar = None
        self._start = self._stage_start = time.monotonic()
        self._text, self._total, self._unit, self._done, self._postfix = "", None, "", 0, ""

    @property
    def active(self) -> bool:
        """Whether anything is shown at all."""
        return self.terminal or self.log

    def stage(self, text: str, total: int | None = None, unit: str = "") -> None:
        """Start a part of the job: ``text`` names it ('' between two parts: no line on a
        terminal); ``total`` counts its steps (in ``unit``), None when it reports none. A
        terminal's line of the previous part is closed."""
        with self._lock:
            self._close_bar()
            self._text, self._total, self._unit, self._done, self._postfix = text, total, unit, 0, ""
            self._stage_start = time.monotonic()

    def advance(self, done: int, postfix: str = "") -> None:
        """``done`` steps of the current part are done (a count, not an increment); ``postfix``
        adds a figure to the line (e.g. ``12 345 segments``)."""
        with self._lock:
            self._done, self._postfix = int(done), postfix
            if self._bar is not None:
                self._draw()

    def counter(self, text: str, unit: str) -> Callable[[int, int], None]:
        """Start the part ``text`` (counted in ``unit``, its total not yet known) and return
        the library's ``(done, total)`` callback that advances it."""
        self.stage(text, None, unit)

        def report(done: int, total: int) -> None:
            with self._lock:
                if self._bar is not None and self._total != total:  # the line becomes a bar
                    self._bar.total, self._bar.bar_format = total, None
                self._total = total
            self.advance(done)

        return report

    def _status_line(self) -> str:
        """The line a log gets: ``dwell: atlas: building the atlas, 1,024/2,548 linkages (40 %),
        812 segments; 23 s`` (the seconds since the job started)."""
        count = ""
        if self._total:
            count = f", {self._done:,}/{self._total:,} {self._unit} ({100 * self._done / self._total:.0f} %)"
        postfix = f", {self._postfix}" if self._postfix else ""
        return f"dwell: {self.job}: {self._text or 'working'}{count}{postfix}; {time.monotonic() - self._start:.0f} s"

    # -- the drawing thread ---------------------------------------------------------------

    def _run(self) -> None:
        interval = _REDRAW if self.terminal else status_interval()
        while not self._stop.wait(interval):
            with self._lock:
                if self.terminal:
                    # an unnamed part (between two: the command prints its results) draws nothing
                    if self._bar is None and self._text and time.monotonic() - self._stage_start >= DELAY:
                        self._open_bar()
                    elif self._bar is not None:
                        self._bar.refresh()
                else:
                    line = self._status_line()
                    # one write per line: a line never mixes with another thread's
                    sys.stderr.write(line + "\n")
                    sys.stderr.flush()

    def _open_bar(self) -> None:
        from tqdm import tqdm

        fmt = None if self._total else "{desc} {elapsed}{postfix}"
        # leave=False: a part's line is wiped when it ends, the results print on a clean line
        self._bar = tqdm(
            total=self._total,
            desc=self._text or self.job,
            unit=f" {self._unit}" if self._unit else "it",
            unit_scale=(self._total or 0) >= 10_000,
            file=sys.stderr,
            dynamic_ncols=True,
            bar_format=fmt,
            initial=self._done,
            leave=False,
        )
        self._bar.start_t -= time.monotonic() - self._stage_start  # its clock counts from the part's start
        self._draw()

    def _draw(self) -> None:
        if self._postfix:
            self._bar.set_postfix_str(self._postfix, refresh=False)
        self._bar.update(self._done - self._bar.n)
        self._bar.refresh()

    def _close_bar(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Self:
        self._start = self._stage_start = time.monotonic()
        if self.active:
            self._thread = threading.Thread(target=self._run, name=f"dwell-progress-{self.job}", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        with self._lock:
            self._close_bar()


class _Feed:
    """A library callback feeding a :class:`Progress`: its own (``show``: True, False, or None
    for "a line on a terminal, status lines in a log") or the command's (``progress``); a
    context manager that closes what it opened, so that an interrupted or failed run still
    ends its line."""

    job = "dwell"

    def __init__(self, show: bool | None = None, *, progress: Progress | None = None) -> None:
        self._own = progress is None
        self.progress = (
            progress
            if progress is not None
            else Progress(self.job, terminal=None if show is None else bool(show), log=show is None)
        )

    def close(self) -> None:
        if self._own:
            self.progress.__exit__(None, None, None)

    def __enter__(self) -> Self:
        if self._own:
            self.progress.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class BuildBar(_Feed):
    """Linkages built (and segments so far), fed by the build's :class:`ShardDone` events.

    Pass the instance as ``on_shard`` to :func:`atlas.build.build_atlas` and use it as a
    context manager.
    """

    job = "atlas"

    def __call__(self, event: ShardDone) -> None:
        if event.shard_index is None:  # the run starts: the total
            self.progress.stage("building the atlas", event.linkages_total, "linkages")
            return
        self.progress.advance(event.linkages_done, f"{event.segments_done:,} segments")


class SearchBar(_Feed):
    """The (segment, level) rows the complete query has searched: pass the instance as
    ``on_progress`` to :func:`synth.query.answer`; a context manager, as :class:`BuildBar`."""

    job = "query"

    def __init__(self, show: bool | None = None, *, progress: Progress | None = None) -> None:
        super().__init__(show, progress=progress)
        self._feed: Callable[[int, int], None] | None = None

    def __call__(self, done: int, total: int) -> None:
        if self._feed is None:  # the search starts (a sampled query never calls)
            self._feed = self.progress.counter("searching every segment", "rows")
        self._feed(done, total)
