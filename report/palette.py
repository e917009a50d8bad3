"""One palette for every picture of a six-bar: the SVG drawing, the HTML animation (its CSS)
and the DXF layers (true colours), so a link has the same colour wherever a designer sees it.

Colours are matplotlib's ``tab10`` hex values, named by what they draw.
"""

from __future__ import annotations

__all__ = ["BLOCK", "CURVE", "DWELL", "GROUND", "LINK_COLORS", "GUIDE", "rgb"]

#: Link name (as in :class:`report.sixbar_drawing.Link`) → colour.
LINK_COLORS: dict[str, str] = {
    "crank": "#1f77b4",
    "coupler": "#ff7f0e",
    "rocker": "#2ca02c",
    "rod": "#8c564b",
    "output": "#9467bd",
}
#: The dwell stretch of the coupler curve and the output link while it rests.
DWELL = "#d62728"
#: The RPR slider block.
BLOCK = "#bcbd22"
#: The coupler curve (dashed).
CURVE = "#9a9a9a"
#: The dwell's guide: the slot's line or the rod's arc.
GUIDE = "#9467bd"
#: The ground line A0–B0.
GROUND = "#777777"


def rgb(color: str) -> tuple[int, int, int]:
    """``"#rrggbb"`` as an (r, g, b) tuple of 0–255 integers (DXF true colour)."""
    return int(color[1:3], 16), int(color[3:5], 16), int(color[5:7], 16)
