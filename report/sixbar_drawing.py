"""A candidate six-bar at one crank position as plain geometry — the one model behind its SVG
drawing (:func:`draw_sixbar`, in the look of :func:`report.drawing.draw_sketch`) and its DXF
(:func:`report.dxf.write_dxf`).

The position shown is the middle of the first dwell (the output at rest, where a designer
checks the dyad against its line or arc); fixed frame A0 = (0, 0), B0 = (d, 0), y up, the
six-bar's (the user's) length unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from report.cycle import Cycle, unit_motion
from report.escape import plot_text
from report.labels import Box, place_labels
from report.palette import BLOCK, CURVE, DWELL, GROUND, GUIDE, LINK_COLORS
from synth.kinds import OutputKind
from synth.query.candidates import Candidate

__all__ = ["Link", "SixBarGeometry", "draw_sixbar", "guide_path", "sixbar_geometry"]

#: Gap (points) between a joint and its label; joint labels' font size (points).
_LABEL_GAP, _LABEL_SIZE = 4.0, 9
#: The slot of an RPR rocker is drawn this much longer than the farthest pin position.
SLOT_MARGIN = 1.08


@dataclass(frozen=True, slots=True)
class Link:
    """One link at the drawn position: ``name`` (e.g. ``"crank"``), ``label`` with its length,
    ``points`` (a closed polyline, first = last, for the ternary coupler) and ``length``
    (``None`` for a link of variable length, the RPR slot)."""

    name: str
    label: str
    points: list[complex]
    length: float | None


@dataclass(frozen=True, slots=True)
class SixBarGeometry:
    """A six-bar drawn at crank angle ``phi`` (rad), the six-bar's length unit.

    Attributes
    ----------
    fixed : dict
        Fixed pivots ``A0``, ``B0``, ``D`` → position.
    joints : dict
        Moving joints ``A``, ``B``, ``P`` and (RRR) ``Q`` → position.
    links : list of Link
        Crank, coupler (triangle A–B–P), rocker, and the output dyad: RRR rod P–Q and rocker
        D–Q; RPR the slotted rocker from D along ψ (length ``SLOT_MARGIN`` × farthest pin).
    ground : list of (label, length)
        Distances between fixed pivots (A0–B0 = d, A0–D, B0–D).
    curve : complex array
        The coupler curve over the turn (the cycle's samples).
    dwell_stretches : list of complex arrays
        The parts of the coupler curve travelled while the output dwells.
    guide : ("line", point, direction) or ("circle", centre, radius)
        What the dwell stretch follows: the slot's line through D at mid-dwell (RPR, direction
        a unit complex), or the arc of radius ρ about Q's rest position (RRR).
    kind : {"RPR", "RRR"}
    psi : float
        Output angle at the drawn position (rad).
    title : str
    units : str
        Name of the length unit (e.g. ``"mm"``; ``""`` unitless): labels and the DXF's
        ``$INSUNITS``.
    """

    phi: float
    fixed: dict[str, complex]
    joints: dict[str, complex]
    links: list[Link]
    ground: list[tuple[str, float]]
    curve: np.ndarray
    dwell_stretches: list[np.ndarray]
    guide: tuple[str, complex, complex | float]
    kind: str
    psi: float
    title: str = field(default="")
    units: str = field(default="")

    def extent(self) -> float:
        """Largest side of the bounding box of everything drawn (length, > 0)."""
        pts = np.concatenate(
            [
                np.asarray(list(self.fixed.values()) + list(self.joints.values())),
                np.concatenate([np.asarray(k.points) for k in self.links]),
                self.curve,
            ]
        )
        return float(max(np.ptp(pts.real), np.ptp(pts.imag), 1e-12))


def _fmt(x: float) -> str:
    return f"{x:.4g}"


def _runs(mask: np.ndarray) -> list[np.ndarray]:
    """Index arrays of the cyclic runs of True in ``mask`` (a run may wrap past the end)."""
    n = mask.size
    if mask.all():
        return [np.arange(n + 1) % n]  # closed
    if not mask.any():
        return []
    shift = int(np.argmin(mask))  # start the scan at a False so no run is cut
    idx = (np.arange(n) + shift) % n
    out, cur = [], []
    for i in idx:
        if mask[i]:
            cur.append(i)
        elif cur:
            out.append(np.array(cur))
            cur = []
    if cur:
        out.append(np.array(cur))
    return out


def sixbar_geometry(candidate: Candidate, cycle: Cycle, phi: float | None = None, *, units: str = "") -> SixBarGeometry:
    """The geometry of ``candidate`` at crank angle ``phi`` (rad; default: mid first dwell,
    or 0 without a dwell), positions from the exact simulation at that angle; ``units`` names
    the candidate's length unit."""
    sb, f = candidate.sixbar, candidate.figures
    if phi is None:
        phi = 0.5 * (f.dwells[0].start + f.dwells[0].end) if f.dwells else 0.0
    phi = float(math.fmod(phi, 2 * math.pi))
    m, scale = unit_motion(sb, np.array([phi]))
    A, B, P = (complex(x[0]) * scale for x in (m.fourbar.A, m.fourbar.B, m.z[0]))
    psi = float(m.psi[0])
    D = sb.dyad.pivot
    fixed = {"A0": 0j, "B0": complex(sb.d, 0.0), "D": D}
    joints = {"A": A, "B": B, "P": P}
    u = f" {units}" if units else ""  # every length label names its unit

    def length(x: float) -> str:
        return f"{_fmt(x)}{u}"

    links = [
        Link("crank", f"crank a = {length(sb.a)}", [0j, A], sb.a),
        Link(
            "coupler",
            f"coupler b = {length(sb.b)}, |AP| = {length(abs(P - A))}, |BP| = {length(abs(P - B))}",
            [A, B, P, A],
            sb.b,
        ),
        Link("rocker", f"rocker c = {length(sb.c)}", [complex(sb.d, 0.0), B], sb.c),
    ]
    stretches = [cycle.P[run] for run in _runs(cycle.dwelling & cycle.assembled)]
    if sb.dyad.kind == OutputKind.RRR:
        Q = complex(m.moving_pivot[0]) * scale
        joints["Q"] = Q
        links += [
            Link("rod", f"rod ρ = {length(sb.dyad.rod)}", [P, Q], sb.dyad.rod),
            Link("output", f"output rocker L = {length(sb.dyad.rocker)}", [D, Q], sb.dyad.rocker),
        ]
        rest = candidate.dwell_position
        if rest is None:  # the arc's centre: where Q stands at mid-dwell
            rest = complex(unit_motion(sb, np.array([_mid_dwell(f)]))[0].moving_pivot[0]) * scale
        guide: tuple = ("circle", complex(rest), float(sb.dyad.rod))
    else:
        reach = float(np.max(np.abs(cycle.P[cycle.assembled] - D))) if cycle.assembled.any() else abs(P - D)
        slot = D + SLOT_MARGIN * reach * np.exp(1j * psi)
        links.append(Link("output", f"slotted rocker (reach {length(reach)})", [D, complex(slot)], None))
        mid = _mid_dwell(f)
        psi_mid = float(unit_motion(sb, np.array([mid]))[0].psi[0])
        guide = ("line", D, complex(np.exp(1j * psi_mid)))
    ground = [("A0–B0 (d)", sb.d), ("A0–D", abs(D)), ("B0–D", abs(D - sb.d))]
    title = f"#{candidate.rank} {candidate.id} ({sb.dyad.kind}) at φ = {math.degrees(phi) % 360:.1f}°"
    return SixBarGeometry(
        phi=phi,
        fixed=fixed,
        joints=joints,
        links=links,
        ground=ground,
        curve=cycle.P.copy(),
        dwell_stretches=stretches,
        guide=guide,
        kind=sb.dyad.kind,
        psi=psi,
        title=title,
        units=units,
    )


def _mid_dwell(figures) -> float:
    return 0.5 * (figures.dwells[0].start + figures.dwells[0].end) if figures.dwells else 0.0


def draw_sixbar(geom: SixBarGeometry, path: str | Path) -> Path:
    """Draw the six-bar to ``path`` (SVG or PNG by suffix): links labelled with their lengths,
    fixed pivots A0, B0, D and joints A, B, P (Q) labelled, the coupler curve with the dwell
    stretch highlighted and its line (RPR) or arc (RRR). Same look as
    :func:`report.drawing.draw_sketch` (which has no notion of a dwell to highlight); colours
    from :mod:`report.palette`; joint labels placed so that none overlaps another, a joint or
    the legend (:func:`report.labels.place_labels`, measured with the renderer)."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, Polygon, Rectangle
    from matplotlib.transforms import Affine2D

    with matplotlib.rc_context({"svg.hashsalt": "dwell-atlas", "svg.fonttype": "none"}):
        fig = Figure(figsize=(7.5, 6.0))
        ax = fig.add_subplot()
        span = geom.extent()
        size = 0.025 * span
        c = geom.curve
        ax.plot(
            np.append(c.real, c.real[0]),
            np.append(c.imag, c.imag[0]),
            lw=0.8,
            ls="--",
            color=CURVE,
            label="coupler curve of P",
        )
        for i, s in enumerate(geom.dwell_stretches):
            ax.plot(
                s.real,
                s.imag,
                lw=3.5,
                color=DWELL,
                alpha=0.55,
                solid_capstyle="round",
                label="dwell stretch" if i == 0 else None,
            )
        _draw_guide(ax, geom, span)
        a0, b0 = geom.fixed["A0"], geom.fixed["B0"]
        ax.plot([a0.real, b0.real], [a0.imag, b0.imag], color=GROUND, lw=1.0, ls="-.")
        for link in geom.links:
            pts = np.asarray(link.points)
            color = LINK_COLORS[link.name]
            if link.name == "coupler":
                ax.add_patch(Polygon(np.c_[pts.real, pts.imag], closed=True, alpha=0.2, color=color))
            ax.plot(pts.real, pts.imag, lw=3, color=color, solid_capstyle="round", label=plot_text(link.label))
        if geom.kind == OutputKind.RPR:
            P = geom.joints["P"]
            rect = Rectangle((P.real - 1.5 * size, P.imag - size), 3 * size, 2 * size, alpha=0.6, color=BLOCK)
            rect.set_transform(Affine2D().rotate_around(P.real, P.imag, geom.psi) + ax.transData)
            ax.add_patch(rect)
        for z in geom.fixed.values():
            x, y = z.real, z.imag
            ax.add_patch(Polygon([(x, y), (x - size, y - 1.6 * size), (x + size, y - 1.6 * size)], color="0.3"))
            ax.add_patch(Circle((x, y), 0.45 * size, facecolor="white", edgecolor="black", zorder=5))
        for z in geom.joints.values():
            ax.add_patch(Circle((z.real, z.imag), 0.4 * size, facecolor="white", edgecolor="black", zorder=5))
        unit = f" {geom.units}" if geom.units else ""
        ground = ", ".join(f"{name} = {_fmt(v)}{unit}" for name, v in geom.ground)
        ax.set_xlabel(plot_text(f"ground: {ground}"), fontsize=8)  # the unit's name is the user's text
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, alpha=0.25)
        ax.set_title(plot_text(geom.title), fontsize=10)  # a user's id is text, not mathtext nor controls
        legend = ax.legend(fontsize=7, loc="best", framealpha=0.8)
        fig.tight_layout()
        _place_joint_labels(fig, ax, legend, geom, FigureCanvasAgg(fig))
        path = Path(path)
        fig.savefig(path, dpi=120, metadata=_metadata(path))
    return path


def _place_joint_labels(fig, ax, legend, geom: SixBarGeometry, canvas) -> None:
    """Annotate every pivot and joint where its label overlaps no other label, no joint symbol
    and not the legend: sizes measured by the renderer after the layout, boxes in display
    pixels, offsets converted to points (what ``annotate`` takes)."""
    canvas.draw()  # the final layout (equal aspect, legend position) before measuring
    renderer = canvas.get_renderer()
    points = {**geom.fixed, **geom.joints}
    fixed = set(geom.fixed)
    px_per_pt = fig.dpi / 72.0
    anchors, sizes, texts = [], [], []
    for label, z in points.items():
        x, y = ax.transData.transform((z.real, z.imag))
        text = ax.annotate(
            label,
            (z.real, z.imag),
            textcoords="offset points",
            xytext=(0, 0),
            fontsize=_LABEL_SIZE,
            weight="bold" if label in fixed else "normal",
            va="baseline",
            ha="left",
        )
        ext = text.get_window_extent(renderer)
        anchors.append((float(x), float(y)))
        sizes.append((ext.width, ext.height))
        texts.append((text, ext.x0 - x, ext.y0 - y))  # the text's box relative to its anchor at offset 0
    symbol = 0.6 * _LABEL_SIZE * px_per_pt
    obstacles = [Box.around(x, y, symbol) for x, y in anchors]
    lb = legend.get_window_extent(renderer)
    obstacles.append(Box(lb.x0, lb.y0, lb.x1, lb.y1))
    boxes = place_labels(anchors, sizes, gap=_LABEL_GAP * px_per_pt, obstacles=obstacles)
    for (text, dx, dy), (x, y), box in zip(texts, anchors, boxes):
        text.xyann = ((box.x0 - dx - x) / px_per_pt, (box.y0 - dy - y) / px_per_pt)


def _metadata(path: Path) -> dict:
    """No creation date in the file, so a report written twice is byte-identical (PNG and SVG
    take different keys)."""
    return {"Date": None} if path.suffix.lower() == ".svg" else {}


def guide_path(geom: SixBarGeometry) -> tuple[np.ndarray, tuple[float, float] | None]:
    """Points of the dwell's guide as drawn, and for an arc its (start, end) angle about the
    centre (rad, counter-clockwise), else None.

    RPR: a piece of the slot's line at mid-dwell, centred on the dwell stretch, 0.7 × the
    drawing's extent long. RRR: the arc of radius ρ about Q's rest position over the stretch's
    angular range, widened by half of it on each side (at least 10°), so the stretch is seen to
    follow it without the whole circle swamping the drawing."""
    kind, where, what = geom.guide
    stretch = geom.dwell_stretches[0] if geom.dwell_stretches else None
    if kind == "line":
        e = complex(what)
        s = 0.0 if stretch is None else float(((stretch[len(stretch) // 2] - where) * np.conj(e)).real)
        return where + (s + np.array([-0.35, 0.35]) * geom.extent()) * e, None
    centre, radius = complex(where), float(what)
    if stretch is None or len(stretch) < 2:
        t0, t1 = 0.0, 2 * math.pi
    else:
        ang = np.unwrap(np.angle(stretch - centre))
        lo, hi = float(ang.min()), float(ang.max())
        widen = max(0.5 * (hi - lo), math.radians(10.0))
        t0, t1 = lo - widen, hi + widen
    t = np.linspace(t0, t1, 121)
    return centre + radius * np.exp(1j * t), (t0, t1)


def _draw_guide(ax, geom: SixBarGeometry, span: float) -> None:
    """The RPR slot's line at mid-dwell or the RRR rod's arc about Q's rest position."""
    pts, arc = guide_path(geom)
    label = "slot line at mid-dwell" if arc is None else "dwell arc (radius ρ about Q at rest)"
    ax.plot(pts.real, pts.imag, color=GUIDE, lw=1.0, ls=":", label=label)
    if arc is not None:
        c = complex(geom.guide[1])
        ax.plot([c.real], [c.imag], "+", color=GUIDE, ms=8)
