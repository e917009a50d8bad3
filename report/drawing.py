"""Drawings of a mechanism at one position (matplotlib, SVG or PNG).

A :class:`Sketch` is plain geometry: links as polylines, ground pivots, slider blocks and
guides, labelled points. Each mechanism builds its own sketch; this module only draws.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

from report.escape import plot_text
from report.folder import staged_file

__all__ = ["Sketch", "draw_sketch"]

Point = tuple[float, float]


@dataclass(frozen=True, slots=True)
class Sketch:
    """Geometry to draw, in the mechanism's length unit."""

    links: list[tuple[str, list[Point]]]  #: (label, polyline); a ternary link is a closed polygon
    ground_pivots: list[tuple[str, Point]] = field(default_factory=list)
    joints: list[tuple[str, Point]] = field(default_factory=list)
    sliders: list[tuple[str, Point, float]] = field(default_factory=list)  #: (label, centre, angle rad)
    guides: list[tuple[Point, Point]] = field(default_factory=list)  #: fixed guide lines
    paths: list[tuple[str, list[Point]]] = field(default_factory=list)  #: traced point paths


def draw_sketch(sketch: Sketch, path: str | Path, title: str = "") -> Path:
    """Draw ``sketch`` to ``path`` (suffix decides SVG or PNG), equal axis scales."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon, Rectangle
    from matplotlib.transforms import Affine2D

    fig, ax = plt.subplots(figsize=(7, 5.5))
    xs: list[float] = []
    ys: list[float] = []
    for label, pts in sketch.paths:
        ax.plot([p[0] for p in pts], [p[1] for p in pts], lw=0.8, ls="--", color="tab:gray", label=plot_text(label))
    for p0, p1 in sketch.guides:
        ax.plot([p0[0], p1[0]], [p0[1], p1[1]], color="0.35", lw=1.0, ls="-.")
    for i, (label, pts) in enumerate(sketch.links):
        x = [p[0] for p in pts]
        y = [p[1] for p in pts]
        xs += x
        ys += y
        color = f"C{i % 10}"
        closed = len(pts) > 2 and pts[0] == pts[-1]
        if closed:
            ax.add_patch(Polygon(pts, closed=True, alpha=0.25, color=color))
        ax.plot(x, y, lw=3, color=color, solid_capstyle="round")
        mid = (
            (sum(x[:-1]) / (len(x) - 1), sum(y[:-1]) / (len(y) - 1))
            if closed
            else ((x[0] + x[-1]) / 2, (y[0] + y[-1]) / 2)
        )
        ax.annotate(plot_text(label), mid, textcoords="offset points", xytext=(4, 4), fontsize=8, color=color)
    span = max(max(xs, default=1) - min(xs, default=0), max(ys, default=1) - min(ys, default=0), 1e-9)
    size = 0.04 * span
    for label, (x, y) in sketch.ground_pivots:
        ax.add_patch(Polygon([(x, y), (x - size, y - 1.6 * size), (x + size, y - 1.6 * size)], color="0.3"))
        ax.plot([x], [y], "o", ms=6, mfc="white", mec="black")
        ax.annotate(plot_text(label), (x, y), textcoords="offset points", xytext=(6, -14), fontsize=9)
    for label, (x, y) in sketch.joints:
        ax.plot([x], [y], "o", ms=5, mfc="white", mec="black")
        ax.annotate(plot_text(label), (x, y), textcoords="offset points", xytext=(6, 6), fontsize=9)
    for label, (x, y), angle in sketch.sliders:
        rect = Rectangle((x - 1.5 * size, y - size), 3 * size, 2 * size, fill=True, alpha=0.5, color="tab:olive")
        rect.set_transform(Affine2D().rotate_around(x, y, angle) + ax.transData)
        ax.add_patch(rect)
        ax.annotate(plot_text(label), (x, y), textcoords="offset points", xytext=(6, -14), fontsize=9)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.25)
    if title:
        ax.set_title(plot_text(title), fontsize=10)
    if sketch.paths:
        ax.legend(fontsize=8, loc="best")
    with warnings.catch_warnings():
        # a label too long for any margin (a linkage file may name a joint so): drawn as it is,
        # without matplotlib's warning on the user's terminal
        warnings.filterwarnings("ignore", message="Tight layout not applied", category=UserWarning)
        fig.tight_layout()
    path = Path(path)
    with staged_file(path) as tmp:  # a killed run leaves the old file or the new one (report/folder.py)
        fig.savefig(tmp, format=path.suffix.lstrip(".").lower() or None)
    plt.close(fig)
    return path
