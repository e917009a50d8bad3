"""DXF of a candidate six-bar for CAD (ezdxf): the same geometry as its SVG drawing
(:class:`report.sixbar_drawing.SixBarGeometry`), one layer per kind of thing.

Coordinates are the six-bar's, in the user's length unit (the drawing is unitless:
``$INSUNITS`` = 0, so CAD takes the numbers as they are); fixed frame A0 = (0, 0),
B0 = (d, 0), y up.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from report.sixbar_drawing import SixBarGeometry, guide_path

__all__ = ["LAYERS", "write_dxf"]

#: Layer name → (AutoCAD colour index, what it holds).
LAYERS: dict[str, tuple[int, str]] = {
    "FIXED_PIVOTS": (1, "fixed pivots A0, B0, D: circle and ground triangle"),
    "LINKS": (5, "links as centre lines (coupler as the triangle A-B-P) and moving joints"),
    "COUPLER_CURVE": (8, "coupler curve of P over the turn"),
    "DWELL": (3, "coupler-curve stretches travelled while the output dwells, and their line (RPR) or arc (RRR)"),
    "TEXT": (7, "pivot labels, link lengths and the title"),
}


def _xy(z: complex) -> tuple[float, float]:
    return (float(z.real), float(z.imag))


def _one_line(text: str) -> str:
    """A TEXT entity holds one line: user text (an id) loses its line breaks and controls."""
    return " ".join("".join(ch if ch.isprintable() else " " for ch in text).split())


def write_dxf(geom: SixBarGeometry, path: str | Path) -> Path:
    """Write ``geom`` as a DXF R2010 file at ``path``; returns the path.

    Entities: CIRCLE and closed LWPOLYLINE (ground triangle) per fixed pivot, LINE per binary
    link and a closed LWPOLYLINE for the coupler triangle, CIRCLE per moving joint, LWPOLYLINE
    for the coupler curve (closed) and each dwell stretch, a LINE (RPR slot line) or ARC (RRR,
    radius ρ about Q's rest position) for the dwell's guide, and TEXT for every label (pivots,
    joints, link lengths with their values, ground distances, the title).
    """
    import ezdxf

    doc = ezdxf.new("R2010", setup=True)
    doc.header["$INSUNITS"] = 0
    for name, (color, description) in LAYERS.items():
        layer = doc.layers.add(name, color=color)
        layer.description = description
    msp = doc.modelspace()
    span = geom.extent()
    r = 0.012 * span
    h = 0.022 * span  # text height
    text = {"layer": "TEXT", "height": h}

    for label, z in geom.fixed.items():
        x, y = _xy(z)
        msp.add_circle((x, y), r, dxfattribs={"layer": "FIXED_PIVOTS"})
        msp.add_lwpolyline([(x, y), (x - 2 * r, y - 3.2 * r), (x + 2 * r, y - 3.2 * r)], close=True,
                           dxfattribs={"layer": "FIXED_PIVOTS"})
        msp.add_text(label, dxfattribs=text).set_placement((x + 2.5 * r, y - 4 * r))
    for link in geom.links:
        pts = [_xy(p) for p in link.points]
        if len(pts) == 2:
            msp.add_line(pts[0], pts[1], dxfattribs={"layer": "LINKS"})
        else:
            msp.add_lwpolyline(pts[:-1], close=True, dxfattribs={"layer": "LINKS"})
        mid = np.mean(np.asarray(link.points[:-1] if len(pts) > 2 else link.points))
        msp.add_text(link.label, dxfattribs={**text, "height": 0.8 * h}).set_placement(_xy(mid + 1.5j * r))
    for label, z in geom.joints.items():
        x, y = _xy(z)
        msp.add_circle((x, y), 0.8 * r, dxfattribs={"layer": "LINKS"})
        msp.add_text(label, dxfattribs=text).set_placement((x + 1.5 * r, y + 1.5 * r))

    msp.add_lwpolyline([_xy(p) for p in geom.curve], close=True, dxfattribs={"layer": "COUPLER_CURVE"})
    for stretch in geom.dwell_stretches:
        if len(stretch) >= 2:
            msp.add_lwpolyline([_xy(p) for p in stretch], dxfattribs={"layer": "DWELL"})
    pts, arc = guide_path(geom)
    if arc is None:
        msp.add_line(_xy(pts[0]), _xy(pts[-1]), dxfattribs={"layer": "DWELL"})
    else:
        start, end = (math.degrees(t) for t in arc)
        msp.add_arc(_xy(complex(geom.guide[1])), float(geom.guide[2]), start % 360.0, end % 360.0,
                    dxfattribs={"layer": "DWELL"})

    # ground distances and the title under the drawing
    lowest = min(float(np.min(geom.curve.imag)), *(z.imag for z in geom.fixed.values()))
    left = min(float(np.min(geom.curve.real)), *(z.real for z in geom.fixed.values()))
    lines = [geom.title] + [f"{name} = {value:.6g}" for name, value in geom.ground]
    for i, line in enumerate(lines):
        msp.add_text(_one_line(line), dxfattribs=text).set_placement((left, lowest - 6 * r - 1.6 * h * (i + 1)))
    path = Path(path)
    doc.saveas(path)
    return path
