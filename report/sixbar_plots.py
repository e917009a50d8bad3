"""Plots of a candidate six-bar over the crank turn (matplotlib, Agg, no pyplot state): output
angle, velocity and acceleration with the dwells shaded; the coupler curve with the dwell
stretch and its line (RPR) or arc (RRR); the transmission angles.

Each plot is written as PNG and SVG from one figure; the SVG text is also returned so the HTML
page can inline it (:func:`report.html_page.inline_svg`). Crank angle in degrees on every
x-axis; ψ in degrees, ψ′ in rad/rad, ψ″ in rad/rad² (per radian of crank).
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from report.cycle import Cycle
from report.escape import plot_text
from report.sixbar_drawing import SixBarGeometry, guide_path
from synth.kinds import OutputKind
from synth.query.candidates import Candidate

__all__ = [
    "PLOTS",
    "PlotFiles",
    "coupler_figure",
    "motion_figure",
    "plot_candidate",
    "save_figure",
    "transmission_figure",
]

#: Plot name → what it shows (file suffix ``-<name>.png`` / ``.svg``).
PLOTS: dict[str, str] = {
    "motion": "output angle ψ, ψ′ and ψ″ vs crank angle, dwells shaded",
    "coupler": "coupler curve with the dwell stretch and its line (RPR) or arc (RRR)",
    "transmission": "four-bar and output transmission angles vs crank angle",
}

_RC = {"svg.hashsalt": "dwell-atlas", "svg.fonttype": "none", "font.size": 9}
_DWELL_COLOR = "tab:red"


@dataclass(frozen=True, slots=True)
class PlotFiles:
    """One plot as written: PNG and SVG paths, and the SVG text (for inlining)."""

    png: Path
    svg: Path
    svg_text: str


_text = plot_text  # user text shown literally by matplotlib (report/escape.py)


def _closed(phi_deg: np.ndarray, y: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The turn drawn to 360° (the first sample repeated), with gaps where ``valid`` is False."""
    x = np.append(phi_deg, 360.0)
    y = np.append(np.where(valid, y, np.nan), y[0] if valid[0] else np.nan)
    return x, y  # NaN only as a matplotlib line break, never written to a data file


def _loop(y: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """A closed path's coordinate, first sample repeated, NaN gaps where not ``valid``."""
    return _closed(np.zeros(len(y)), y, valid)[1]


def _shade_dwells(ax, candidate: Candidate, label: bool) -> None:
    """Shade every dwell interval (split where it passes 360°)."""
    for k, dw in enumerate(candidate.figures.dwells):
        for j, (lo, hi) in enumerate(dw.spans_deg()):
            text = f"dwell {k + 1}: {math.degrees(dw.angle):.2f}°" if (label and j == 0) else None
            ax.axvspan(lo, hi, color=_DWELL_COLOR, alpha=0.13, lw=0, label=text)


def _crank_axis(ax) -> None:
    ax.set_xlim(0.0, 360.0)
    ax.set_xticks(np.arange(0.0, 361.0, 45.0))
    ax.grid(True, alpha=0.3)


def _title(candidate: Candidate) -> str:
    return _text(f"#{candidate.rank}  {candidate.id}  ({candidate.sixbar.dyad.kind})")


def motion_figure(candidate: Candidate, cycle: Cycle):
    """ψ [deg], ψ′ [rad/rad], ψ″ [rad/rad²] vs crank angle, dwell interval(s) shaded."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 6.2))
    axes = fig.subplots(3, 1, sharex=True)
    phi = np.degrees(cycle.phi)
    ok = cycle.status == 0
    rows = [
        (np.degrees(cycle.psi), cycle.assembled, "output ψ [deg]"),
        (cycle.dpsi, ok, "ψ′ [rad/rad]"),
        (cycle.ddpsi, ok, "ψ″ [rad/rad²]"),
    ]
    for i, (ax, (y, valid, label)) in enumerate(zip(axes, rows)):
        _shade_dwells(ax, candidate, label=i == 0)
        ax.plot(*_closed(phi, y, valid), lw=1.5, color="C4")
        if i:
            ax.axhline(0.0, color="0.6", lw=0.6)
        ax.set_ylabel(label)
        _crank_axis(ax)
    f = candidate.figures
    axes[0].set_title(f"{_title(candidate)} — swing {math.degrees(f.swing):.3f}°", fontsize=10)
    if f.dwells:
        axes[0].legend(fontsize=8, loc="best")
    axes[-1].set_xlabel("crank angle φ [deg]")
    fig.tight_layout()
    return fig


def coupler_figure(candidate: Candidate, cycle: Cycle, geom: SixBarGeometry):
    """Coupler curve of P, the dwell stretch and its guide, the fixed pivots, (RRR) Q's path."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.5, 5.6))
    ax = fig.add_subplot()
    ok = cycle.assembled
    P = cycle.P
    ax.plot(_loop(P.real, ok), _loop(P.imag, ok), lw=1.2, color="0.35", label="coupler curve of P")
    for i, s in enumerate(geom.dwell_stretches):
        ax.plot(
            s.real,
            s.imag,
            lw=4,
            color=_DWELL_COLOR,
            alpha=0.6,
            solid_capstyle="round",
            label="dwell stretch" if i == 0 else None,
        )
    pts, arc = guide_path(geom)
    ax.plot(
        pts.real,
        pts.imag,
        ls="--",
        lw=1,
        color="tab:purple",
        label="slot line (mid-dwell)" if arc is None else "dwell arc, radius ρ about Q at rest",
    )
    if arc is not None:
        rest = complex(geom.guide[1])
        ax.plot([rest.real], [rest.imag], "+", ms=9, color="tab:purple")
        Q = cycle.Q
        ax.plot(_loop(Q.real, ok), _loop(Q.imag, ok), lw=1, color="tab:green", alpha=0.7, label="path of Q")
    for label, z in geom.fixed.items():
        ax.plot([z.real], [z.imag], "^", ms=8, color="0.25")
        ax.annotate(
            label,
            (z.real, z.imag),
            textcoords="offset points",
            xytext=(-16, 6) if label == "D" else (6, -12),
            fontsize=9,
        )
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    if geom.units:  # the coordinates are lengths: their unit on both axes
        ax.set_xlabel(plot_text(f"x [{geom.units}]"))
        ax.set_ylabel(plot_text(f"y [{geom.units}]"))
    ax.set_title(f"{_title(candidate)} — coupler curve", fontsize=10)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    return fig


def transmission_figure(candidate: Candidate, cycle: Cycle, min_transmission: float | None = None):
    """Folded transmission angles [deg] over the turn, their minima, the requested minimum."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 3.2))
    ax = fig.add_subplot()
    phi = np.degrees(cycle.phi)
    ok = cycle.assembled
    _shade_dwells(ax, candidate, label=False)
    f = candidate.figures
    ax.plot(
        *_closed(phi, np.degrees(cycle.mu_fourbar), ok),
        lw=1.5,
        color="C0",
        label=f"four-bar at B (min {math.degrees(f.transmission_fourbar):.2f}°)",
    )
    out_label = "output at Q" if candidate.sixbar.dyad.kind == OutputKind.RRR else "output (slotted rocker: 90°)"
    ax.plot(
        *_closed(phi, np.degrees(cycle.mu_output), ok),
        lw=1.5,
        color="C4",
        label=f"{out_label} (min {math.degrees(f.transmission_output):.2f}°)",
    )
    if min_transmission is not None:
        ax.axhline(math.degrees(min_transmission), color="0.4", ls="--", lw=0.8, label="requested minimum")
    ax.set_ylim(0.0, 92.0)
    ax.set_ylabel("transmission angle [deg]")
    ax.set_xlabel("crank angle φ [deg]")
    _crank_axis(ax)
    ax.set_title(f"{_title(candidate)} — transmission angles", fontsize=10)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    return fig


def save_figure(fig, stem: Path, *, dpi: int = 110) -> PlotFiles:
    """Write ``fig`` to ``<stem>.png`` and ``<stem>.svg`` (no date in the SVG, so equal reports
    are equal files); returns both paths and the SVG text."""
    png, svg = stem.with_name(stem.name + ".png"), stem.with_name(stem.name + ".svg")
    fig.savefig(png, dpi=dpi)
    buf = io.BytesIO()
    fig.savefig(buf, format="svg", metadata={"Date": None})
    data = buf.getvalue()
    svg.write_bytes(data)
    return PlotFiles(png, svg, data.decode("utf-8"))


def plot_candidate(
    candidate: Candidate, cycle: Cycle, geom: SixBarGeometry, stem: Path, min_transmission: float | None = None
) -> dict[str, PlotFiles]:
    """All :data:`PLOTS` of one candidate, written as ``<stem>-<name>.png/.svg``."""
    import matplotlib

    with matplotlib.rc_context(_RC):
        figs = {
            "motion": motion_figure(candidate, cycle),
            "coupler": coupler_figure(candidate, cycle, geom),
            "transmission": transmission_figure(candidate, cycle, min_transmission),
        }
        return {name: save_figure(fig, stem.with_name(f"{stem.name}-{name}")) for name, fig in figs.items()}
