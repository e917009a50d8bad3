"""Progress bars on stderr (tqdm), fed by the library's callbacks: the atlas build's
(:class:`atlas.build.ShardDone` events) and the complete query's (rows searched).

The library reports progress and never imports a bar; the commands that build (``dwell atlas
build``, ``dwell demo``) and search (``dwell query --complete``) own them here.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Self

if TYPE_CHECKING:
    from atlas.build import ShardDone

__all__ = ["BuildBar", "SearchBar"]


class _Bar:
    """A tqdm bar on stderr, drawn when ``show`` (None: if stderr is a terminal); a context
    manager that closes it, so that an interrupted or failed run still ends the line."""

    def __init__(self, show: bool | None = None) -> None:
        self.show = sys.stderr.isatty() if show is None else bool(show)
        self._bar = None

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class BuildBar(_Bar):
    """A tqdm bar of linkages built (rate and ETA in linkages/s, segments so far), on stderr.

    Pass the instance as ``on_shard`` to :func:`atlas.build.build_atlas` and use it as a
    context manager, so that an interrupted or failed build still closes the bar. ``show``:
    True, False, or None for "if stderr is a terminal".
    """

    def __call__(self, event: ShardDone) -> None:
        if event.shard_index is None:  # the run starts: the clock and the total
            if self.show:
                from tqdm import tqdm

                self._bar = tqdm(total=event.linkages_total, unit=" linkages", unit_scale=True, desc="atlas",
                                 file=sys.stderr, smoothing=0.05, dynamic_ncols=True)
            return
        if self._bar is None:
            return
        self._bar.set_postfix(segments=event.segments_done, refresh=False)
        self._bar.update(event.linkages)
        if event.shards_left == 0:
            self.close()



class SearchBar(_Bar):
    """A tqdm bar of the (segment, level) rows the complete query has searched: pass the
    instance as ``on_progress`` to :func:`synth.query.answer`; a context manager, as
    :class:`BuildBar`. ``show``: True, False, or None for "if stderr is a terminal"."""

    def __call__(self, done: int, total: int) -> None:
        if not self.show:
            return
        if self._bar is None:
            from tqdm import tqdm

            self._bar = tqdm(total=total, unit=" rows", unit_scale=True, desc="search", file=sys.stderr,
                             dynamic_ncols=True)
        self._bar.update(done - self._bar.n)
        if done >= total:
            self.close()

