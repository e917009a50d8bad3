"""DXF of a candidate six-bar for CAD (ezdxf): the same geometry as its SVG drawing
(:class:`report.sixbar_drawing.SixBarGeometry`), a layer per link, real dimensions.

Coordinates are the six-bar's, in the user's length unit, declared in ``$INSUNITS`` (the
unit named by ``--units``; 0 = unitless when the name is not a DXF unit); fixed frame
A0 = (0, 0), B0 = (d, 0), y up. Every link length is an aligned DIMENSION between its joints,
every fixed pivot's position a pair of linear DIMENSIONs from A0; labels are placed so that
no two overlap (:func:`report.labels.place_labels`, boxes measured with ezdxf's font
metrics). Colours are the SVG drawing's (:mod:`report.palette`) as true colours.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from report.labels import Box, place_labels
from report.palette import CURVE, DWELL, LINK_COLORS, rgb
from report.sixbar_drawing import SixBarGeometry, guide_path

__all__ = ["INSUNITS", "LAYERS", "write_dxf"]

#: Unit name (as typed in ``--units``, case-insensitive) → DXF ``$INSUNITS`` code.
INSUNITS: dict[str, int] = {
    "in": 1,
    "inch": 1,
    "inches": 1,
    "ft": 2,
    "foot": 2,
    "feet": 2,
    "mi": 3,
    "mm": 4,
    "cm": 5,
    "m": 6,
    "km": 7,
    "µm": 13,
    "um": 13,
    "dm": 14,
    "yd": 10,
}

#: Layer name → (true colour, what it holds). One layer per link (as the drawing names them).
LAYERS: dict[str, tuple[str, str]] = {
    "FIXED_PIVOTS": ("#4d4d4d", "fixed pivots A0, B0, D: circle and ground triangle"),
    "JOINTS": ("#111111", "moving joints A, B, P (Q): circles"),
    "CRANK": (LINK_COLORS["crank"], "crank A0-A (centre line)"),
    "COUPLER": (LINK_COLORS["coupler"], "coupler triangle A-B-P (centre lines)"),
    "ROCKER": (LINK_COLORS["rocker"], "rocker B0-B (centre line)"),
    "ROD": (LINK_COLORS["rod"], "RRR rod P-Q (centre line)"),
    "OUTPUT": (LINK_COLORS["output"], "output link: RRR rocker D-Q, or RPR slotted rocker from D"),
    "COUPLER_CURVE": (CURVE, "coupler curve of P over the turn"),
    "DWELL": (DWELL, "coupler-curve stretches travelled while the output dwells, and their line (RPR) or arc (RRR)"),
    "DIMENSIONS": ("#000000", "link lengths (aligned) and fixed-pivot positions from A0 (linear)"),
    "TEXT": ("#000000", "pivot and joint labels, link names, the title and ground distances"),
}


def _xy(z: complex) -> tuple[float, float]:
    return (float(z.real), float(z.imag))


def _one_line(text: str) -> str:
    """A TEXT entity holds one line: user text (an id) loses its line breaks and controls."""
    return " ".join("".join(ch if ch.isprintable() else " " for ch in text).split())


def _layer(link_name: str) -> str:
    return link_name.upper()


def write_dxf(geom: SixBarGeometry, path: str | Path) -> Path:
    """Write ``geom`` as a DXF R2010 file at ``path``; returns the path.

    Entities: CIRCLE and closed LWPOLYLINE (ground triangle) per fixed pivot, CIRCLE per moving
    joint, LINE per binary link and a closed LWPOLYLINE for the coupler triangle (each on its
    link's layer), LWPOLYLINE for the coupler curve (closed) and each dwell stretch, a LINE
    (RPR slot line) or ARC (RRR, radius ρ about Q's rest position) for the dwell's guide,
    DIMENSION (aligned) for every link of fixed length and (linear) for the fixed pivots'
    coordinates, and TEXT for every label (pivots, joints, link names, the title and ground
    distances).
    """
    import ezdxf
    from ezdxf.tools.text_size import text_size

    doc = ezdxf.new("R2010", setup=True)
    doc.header["$INSUNITS"] = INSUNITS.get(geom.units.strip().lower(), 0)
    doc.header["$MEASUREMENT"] = 0 if doc.header["$INSUNITS"] in (1, 2, 3, 10) else 1
    for name, (color, description) in LAYERS.items():
        layer = doc.layers.add(name)
        layer.rgb = rgb(color)
        layer.description = description
    msp = doc.modelspace()
    span = geom.extent()
    r = 0.012 * span
    h = 0.022 * span  # text height

    for z in geom.fixed.values():
        x, y = _xy(z)
        msp.add_circle((x, y), r, dxfattribs={"layer": "FIXED_PIVOTS"})
        msp.add_lwpolyline(
            [(x, y), (x - 2 * r, y - 3.2 * r), (x + 2 * r, y - 3.2 * r)],
            close=True,
            dxfattribs={"layer": "FIXED_PIVOTS"},
        )
    for link in geom.links:
        pts = [_xy(p) for p in link.points]
        if len(pts) == 2:
            msp.add_line(pts[0], pts[1], dxfattribs={"layer": _layer(link.name)})
        else:
            msp.add_lwpolyline(pts[:-1], close=True, dxfattribs={"layer": _layer(link.name)})
    for z in geom.joints.values():
        msp.add_circle(_xy(z), 0.8 * r, dxfattribs={"layer": "JOINTS"})

    msp.add_lwpolyline([_xy(p) for p in geom.curve], close=True, dxfattribs={"layer": "COUPLER_CURVE"})
    for stretch in geom.dwell_stretches:
        if len(stretch) >= 2:
            msp.add_lwpolyline([_xy(p) for p in stretch], dxfattribs={"layer": "DWELL"})
    pts, arc = guide_path(geom)
    if arc is None:
        msp.add_line(_xy(pts[0]), _xy(pts[-1]), dxfattribs={"layer": "DWELL"})
    else:
        start, end = (math.degrees(t) for t in arc)
        msp.add_arc(
            _xy(complex(geom.guide[1])), float(geom.guide[2]), start % 360.0, end % 360.0, dxfattribs={"layer": "DWELL"}
        )

    _dimensions(msp, geom, h, span)
    _labels(msp, geom, h, r, text_size)
    path = Path(path)
    doc.saveas(path)
    return path


def _dimensions(msp, geom: SixBarGeometry, h: float, span: float) -> None:
    """Aligned dimensions of every link of fixed length (each side of the coupler triangle),
    linear ones of the fixed pivots' x and y from A0, drawn on the DIMENSIONS layer."""
    style = {
        "dimtxt": 0.7 * h,
        "dimasz": 0.5 * h,
        "dimexe": 0.3 * h,
        "dimexo": 0.3 * h,
        "dimgap": 0.2 * h,
        "dimdec": 4,
        "dimzin": 8,
        "dimlfac": 1.0,
    }  # EZDXF style shows cm of metres (dimlfac 100)
    attribs = {"layer": "DIMENSIONS"}
    sides: list[tuple[complex, complex]] = []
    for link in geom.links:
        if link.length is None:  # the RPR slot: its length varies over the turn
            continue
        pts = link.points[:-1] if len(link.points) > 2 else link.points
        sides += [(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts) if len(pts) > 2 else 1)]
    for p1, p2 in sides:
        if abs(p2 - p1) > 1e-9 * span:
            msp.add_aligned_dim(
                p1=_xy(p1), p2=_xy(p2), distance=1.2 * h, dimstyle="EZDXF", override=style, dxfattribs=attribs
            ).render()
    # fixed pivots from A0: x below the drawing, y to the left of it
    lowest = min(float(np.min(geom.curve.imag)), *(z.imag for z in geom.fixed.values()))
    left = min(float(np.min(geom.curve.real)), *(z.real for z in geom.fixed.values()))
    a0 = geom.fixed["A0"]
    for k, (label, z) in enumerate(item for item in geom.fixed.items() if item[0] != "A0"):
        base_y = lowest - (3 + 2 * k) * h
        if abs(z.real - a0.real) > 1e-9 * span:
            msp.add_linear_dim(
                base=(0.5 * (a0.real + z.real), base_y),
                p1=_xy(a0),
                p2=_xy(z),
                angle=0,
                dimstyle="EZDXF",
                override=style,
                dxfattribs=attribs,
            ).render()
        if abs(z.imag - a0.imag) > 1e-9 * span:
            base_x = left - (3 + 2 * k) * h
            msp.add_linear_dim(
                base=(base_x, 0.5 * (a0.imag + z.imag)),
                p1=_xy(a0),
                p2=_xy(z),
                angle=90,
                dimstyle="EZDXF",
                override=style,
                dxfattribs=attribs,
            ).render()


def _labels(msp, geom: SixBarGeometry, h: float, r: float, text_size) -> None:
    """Joint and pivot labels, then link names, placed without overlap; the title and the
    ground distances in a column under the dimensions."""
    items: list[tuple[str, complex, float]] = [(label, z, h) for label, z in {**geom.fixed, **geom.joints}.items()]
    for link in geom.links:
        pts = link.points[:-1] if len(link.points) > 2 else link.points
        items.append((link.label, complex(np.mean(np.asarray(pts))), 0.8 * h))
    entities, anchors, sizes, descenders = [], [], [], []
    for label, z, height in items:
        text = msp.add_text(_one_line(label), dxfattribs={"layer": "TEXT", "height": height})
        size = text_size(text)
        entities.append(text)
        anchors.append(_xy(z))
        sizes.append((size.width, size.total_height))
        descenders.append(size.total_height - size.cap_height)
    obstacles = [Box.around(x, y, 1.2 * r) for x, y in anchors[: len(geom.fixed) + len(geom.joints)]]
    boxes = place_labels(anchors, sizes, gap=0.8 * r, obstacles=obstacles)
    for text, box, descender in zip(entities, boxes, descenders):
        # TEXT's insertion point is the left end of its baseline, the box's bottom the descender line
        text.set_placement((box.x0, box.y0 + descender))

    lowest = min(float(np.min(geom.curve.imag)), *(z.imag for z in geom.fixed.values()))
    left = min(float(np.min(geom.curve.real)), *(z.real for z in geom.fixed.values()))
    unit = f" {geom.units}" if geom.units else ""
    lines = [geom.title] + [f"{name} = {value:.6g}{unit}" for name, value in geom.ground]
    top = lowest - (4 + 2 * len(geom.fixed)) * h
    for i, line in enumerate(lines):
        msp.add_text(_one_line(line), dxfattribs={"layer": "TEXT", "height": h}).set_placement(
            (left, top - 1.6 * h * (i + 1))
        )
