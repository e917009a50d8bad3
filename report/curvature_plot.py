"""Drawing of the curvature geometry of a four-bar's coupler plane at one crank position.

Plain geometry in, a PNG or SVG out (matplotlib): the linkage, the pole with its tangent and
normal, the inflection circle, the circle-point cubic and the centre-point curve, Ball's
point with the coupler curve it traces and its tangent line, and any double Ball points.
Curves are given as complex arrays with a mask of the samples to draw; a curve is broken
wherever a sample is masked out or leaves the view (the cubics pass through infinity).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from report.escape import plot_text

__all__ = ["CurvatureScene", "plot_curvature"]


@dataclass(frozen=True, slots=True)
class CurvatureScene:
    """Fixed-frame geometry of one instant (complex points; ``None`` for a point not shown)."""

    ground: tuple[complex, complex]  #: A0, B0
    joints: tuple[complex, complex]  #: A, B
    pole: complex | None
    pole_tangent: complex | None  #: unit direction
    inflection_center: complex | None
    inflection_diameter: float | None
    circle_curve: np.ndarray  #: circle points over a dense fan of rays (complex)
    circle_mask: np.ndarray  #: which of them to draw (bool)
    center_curve: np.ndarray  #: their conjugate centre points
    center_mask: np.ndarray
    ball_point: complex | None
    ball_tangent: complex | None  #: unit direction of its path
    ball_path: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))  #: its coupler curve
    double_ball: list[complex] = field(default_factory=list)  #: double Ball points at this instant


def _broken(z: np.ndarray, mask: np.ndarray, centre: complex, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """x, y with NaN gaps (matplotlib's line breaks) where masked, out of view, or jumping."""
    z = np.asarray(z, complex)
    keep = np.asarray(mask, bool) & (np.abs(z - centre) <= 3.0 * radius)
    jump = np.zeros_like(keep)
    jump[1:] = np.abs(np.diff(z)) > radius
    keep &= ~jump
    x = np.where(keep, z.real, np.nan)
    y = np.where(keep, z.imag, np.nan)
    return x, y


def plot_curvature(scene: CurvatureScene, path: str | Path, title: str = "") -> Path:
    """Draw ``scene`` to ``path`` (the suffix decides PNG or SVG), equal axis scales."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    A0, B0 = scene.ground
    A, B = scene.joints
    # The view frames the linkage, the pole and Ball's point; a far inflection circle is cut.
    anchors = [A0, B0, A, B] + [z for z in (scene.pole, scene.ball_point) if z is not None]
    xs, ys = [z.real for z in anchors], [z.imag for z in anchors]
    centre = complex(0.5 * (min(xs) + max(xs)), 0.5 * (min(ys) + max(ys)))
    size = max(abs(B0 - A0), abs(A - A0), abs(B - A), abs(B - B0))
    radius = min(0.65 * max(max(xs) - min(xs), max(ys) - min(ys), size), 6.0 * size)

    fig, ax = plt.subplots(figsize=(8, 7))
    ax.plot(
        *_broken(scene.circle_curve, scene.circle_mask, centre, radius),
        color="tab:blue",
        lw=1.2,
        label="circle-point curve (cubic of stationary curvature)",
    )
    ax.plot(
        *_broken(scene.center_curve, scene.center_mask, centre, radius),
        color="tab:orange",
        lw=1.0,
        ls="--",
        label="centre-point curve",
    )
    if scene.inflection_center is not None and scene.inflection_diameter is not None:
        ax.add_patch(
            Circle(
                (scene.inflection_center.real, scene.inflection_center.imag),
                scene.inflection_diameter / 2,
                fill=False,
                color="tab:green",
                lw=1.2,
                label="inflection circle",
            )
        )
    if scene.ball_path.size:
        ax.plot(
            *_broken(scene.ball_path, np.ones(scene.ball_path.size, bool), centre, 10 * radius),
            color="tab:purple",
            lw=0.8,
            alpha=0.8,
            label="coupler curve of Ball's point",
        )
    if scene.ball_point is not None:
        ax.plot([scene.ball_point.real], [scene.ball_point.imag], "D", color="tab:purple", ms=7, label="Ball's point")
        if scene.ball_tangent is not None:
            ends = scene.ball_point + np.array([-1.0, 1.0]) * 2.0 * radius * scene.ball_tangent
            ax.plot(ends.real, ends.imag, color="tab:purple", lw=0.8, ls=":", label="its tangent line")
    if scene.pole is not None:
        ax.plot([scene.pole.real], [scene.pole.imag], "o", color="tab:red", ms=7, label="pole")
        if scene.pole_tangent is not None:
            for direction, style in ((scene.pole_tangent, "-"), (1j * scene.pole_tangent, "-.")):
                ends = scene.pole + np.array([-1.0, 1.0]) * 0.5 * radius * direction
                ax.plot(ends.real, ends.imag, color="tab:red", lw=0.7, ls=style)
    for k, z in enumerate(scene.double_ball):
        ax.plot([z.real], [z.imag], "*", color="black", ms=10, label="double Ball points" if k == 0 else None)
    ax.plot(
        [A0.real, A.real, B.real, B0.real],
        [A0.imag, A.imag, B.imag, B0.imag],
        color="0.2",
        lw=2.5,
        marker="o",
        mfc="white",
        label="four-bar",
    )
    for name, z in (("A0", A0), ("B0", B0), ("A", A), ("B", B)):
        ax.annotate(name, (z.real, z.imag), textcoords="offset points", xytext=(5, 5), fontsize=9)
    ax.set_xlim(centre.real - radius, centre.real + radius)
    ax.set_ylim(centre.imag - radius, centre.imag + radius)
    ax.set_aspect("equal", adjustable="box")
    ax.grid(True, alpha=0.25)
    ax.legend(loc="upper right", fontsize=7, framealpha=0.85)
    if title:
        ax.set_title(plot_text(title), fontsize=10)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
