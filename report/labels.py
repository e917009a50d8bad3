"""Label placement without overlap, for every drawing the report writes (SVG and DXF).

A greedy placement in the spirit of cartographic point labelling: each label, in the order
given, takes the first of a fixed list of positions around its anchor (right-above first,
then the other seven compass positions, then the same further out) whose box overlaps
neither a label placed before it nor an obstacle (a pivot's symbol, the legend); if every
position collides, the one with the least overlapping area. Units are the caller's (data
units for the DXF, display pixels for the SVG) — only boxes are compared.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["Box", "place_labels"]


@dataclass(frozen=True, slots=True)
class Box:
    """An axis-parallel box ``[x0, x1] × [y0, y1]`` (y up or down: only overlaps matter)."""

    x0: float
    y0: float
    x1: float
    y1: float

    @classmethod
    def around(cls, x: float, y: float, half: float) -> Box:
        """The square of half-side ``half`` centred on (x, y) (a joint's symbol)."""
        return cls(x - half, y - half, x + half, y + half)

    def overlap(self, other: Box) -> float:
        """Area shared with ``other`` (0 when they only touch or are apart)."""
        w = min(self.x1, other.x1) - max(self.x0, other.x0)
        h = min(self.y1, other.y1) - max(self.y0, other.y0)
        return w * h if w > 0 and h > 0 else 0.0


#: Candidate positions of a label's box relative to its anchor, as multiples of
#: (gap + width, gap + height) direction signs: right-above first (the usual place of a
#: joint's name), then right, above, left-above, … and the same twice as far out.
_DIRECTIONS = ((1, 1), (1, -1), (-1, 1), (-1, -1), (1, 0), (-1, 0), (0, 1), (0, -1))


def _candidates(x: float, y: float, w: float, h: float, gap: float) -> list[Box]:
    out = []
    for reach in (1.0, 2.2, 3.6):
        g = gap * reach
        for sx, sy in _DIRECTIONS:
            # lower-left corner: to the right of the anchor (sx = 1) the box starts at x + g,
            # to the left it ends at x − g, centred when sx = 0 (likewise in y)
            left = x + g if sx > 0 else (x - g - w if sx < 0 else x - w / 2)
            low = y + g if sy > 0 else (y - g - h if sy < 0 else y - h / 2)
            out.append(Box(left, low, left + w, low + h))
    return out


def place_labels(
    anchors: Sequence[tuple[float, float]],
    sizes: Sequence[tuple[float, float]],
    *,
    gap: float,
    obstacles: Sequence[Box] = (),
) -> list[Box]:
    """Boxes for labels of ``sizes`` (width, height) next to ``anchors`` (x, y), in order.

    ``gap`` is the distance kept between an anchor and its label's nearest edge. Labels placed
    earlier win: put the most important first. Returns one box per label; its lower-left
    corner (x0, y0 in y-up units) is where the text starts."""
    placed: list[Box] = []
    blocked = list(obstacles)
    for (x, y), (w, h) in zip(anchors, sizes, strict=True):
        best, best_cost = None, float("inf")
        for box in _candidates(x, y, w, h, gap):
            cost = sum(box.overlap(other) for other in blocked)
            if cost < best_cost:
                best, best_cost = box, cost
                if cost == 0.0:
                    break
        placed.append(best)
        blocked.append(best)
    return placed
