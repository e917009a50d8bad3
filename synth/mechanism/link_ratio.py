"""The link ratio of a six-bar: its longest link over its shortest, every link counted.

The one definition the query's limit (``--max-link-ratio``), the figures, the screen, the
refinement and the prunes use. The links of a six-bar (crank a, coupler point p = u + iv in
the coupler frame, origin A, x-axis along A → B):

* the crank a (A0–A), the rocker c (B0–B) and the ground d (A0–B0);
* the coupler, a ternary plate with joints A, B and P: its three sides b = |AB|, |AP| = |p| and
  |BP| = |p − b|;
* the output dyad: an RRR's rocker L (D–Q) and rod ρ (P–Q); an RPR's slotted rocker, as long
  as the slider's farthest reach from its pivot over the turn, max |P − D|.

The fixed pivot D is placed on the frame, not on a link: the frame's sides (|A0 D|, |B0 D|) are
left out (a pivot too near another is a clearance, :mod:`synth.mechanism.buildability`).

The segment of an atlas fixes every link but the dyad's: :func:`segment_link_ratio` is a lower
bound on the ratio of any six-bar built on it, and :func:`segment_shortest` an upper bound on
its shortest link — what the prunes of :mod:`synth.segment_search.dwell_bounds` and the query start from.

Pure: arrays in, arrays out (lengths in any one unit; the ratio is dimensionless).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from synth.types import F64

__all__ = ["SHORTEST_FLOOR", "link_ratio", "segment_link_ratio", "segment_links", "segment_shortest"]

#: The shortest link is taken as at least this fraction of the longest: a coupler point on a
#: joint (P = A or P = B) has a zero side, whose ratio is reported as 1e12 (above any limit
#: the CLI accepts), never as inf.
SHORTEST_FLOOR = 1e-12


def segment_links(a: ArrayLike, b: ArrayLike, c: ArrayLike, d: ArrayLike, u: ArrayLike, v: ArrayLike) -> F64:
    """The links a segment fixes, stacked on a new last axis (..., 6): crank a, coupler b,
    rocker c, ground d and the coupler plate's sides |AP| = |u + iv| and |BP| = |u − b + iv|
    (the arguments broadcast; lengths)."""
    a, b, c, d, u, v = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (a, b, c, d, u, v)))
    return np.stack([a, b, c, d, np.hypot(u, v), np.hypot(u - b, v)], axis=-1)


def link_ratio(links: ArrayLike) -> F64:
    """Longest over shortest of the lengths along the last axis of ``links`` (..., k), the
    shortest floored at ``SHORTEST_FLOOR`` × the longest (a finite ratio ≥ 1)."""
    links = np.asarray(links, dtype=float)
    longest = links.max(axis=-1)
    return longest / np.maximum(links.min(axis=-1), SHORTEST_FLOOR * longest)


def segment_link_ratio(a: ArrayLike, b: ArrayLike, c: ArrayLike, d: ArrayLike, u: ArrayLike, v: ArrayLike) -> F64:
    """The ratio of the links a segment fixes (:func:`segment_links`): no six-bar built on it,
    whatever its output dyad, has a smaller link ratio (its links are a superset)."""
    return link_ratio(segment_links(a, b, c, d, u, v))


def segment_shortest(a: ArrayLike, b: ArrayLike, c: ArrayLike, d: ArrayLike, u: ArrayLike, v: ArrayLike) -> F64:
    """The shortest link a segment fixes, min(a, b, c, d, |AP|, |BP|): no six-bar built on it
    has a longer shortest link, so every link of one within a ratio ρ_max is at most ρ_max
    times this."""
    return segment_links(a, b, c, d, u, v).min(axis=-1)
