"""The atlas build's progress bar: tqdm on stderr, fed by :mod:`atlas.build`'s callback.

The library reports progress as :class:`atlas.build.ShardDone` events and never imports the
bar; the commands that build (``dwell atlas build``, ``dwell demo``) own it here.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from atlas.build import ShardDone

__all__ = ["BuildBar"]


class BuildBar:
    """A tqdm bar of linkages built (rate and ETA in linkages/s, segments so far), on stderr.

    Pass the instance as ``on_shard`` to :func:`atlas.build.build_atlas` and use it as a
    context manager, so that an interrupted or failed build still closes the bar. ``show``:
    True, False, or None for "if stderr is a terminal".
    """

    def __init__(self, show: bool | None = None) -> None:
        self.show = sys.stderr.isatty() if show is None else bool(show)
        self._bar = None

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

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> BuildBar:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
