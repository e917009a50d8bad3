"""CAD a designer can use (issue 14): the DXF declares its unit, has a layer per link and real
DIMENSION entities whose measurements are the six-bar's link lengths and pivot positions;
no two labels overlap in the DXF (boxes from ezdxf's font metrics) or in the SVG drawing
(boxes from matplotlib's text paths at the SVG's font size); the SVG drawing, the DXF and the
HTML page use one palette."""

from __future__ import annotations

import itertools
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from report.cycle import sixbar_cycle
from report.dxf import INSUNITS, LAYERS, write_dxf
from report.labels import Box, place_labels
from report.palette import LINK_COLORS, rgb
from report.sixbar_drawing import draw_sixbar, sixbar_geometry

ezdxf = pytest.importorskip("ezdxf")


def _geometries(cands, units="mm"):
    return [sixbar_geometry(c, sixbar_cycle(c.sixbar, c.figures), units=units) for c in cands]


def _link_lengths(c) -> list[float]:
    """Every fixed length of the six-bar (user units): crank, coupler sides, rocker, output dyad."""
    sb = c.sixbar
    p = complex(sb.u, sb.v)  # the coupler point in the coupler frame (A = 0, B = b)
    lengths = [sb.a, sb.b, sb.c, abs(p), abs(p - sb.b)]
    if sb.dyad.kind == "RRR":
        lengths += [sb.dyad.rod, sb.dyad.rocker]
    return lengths


def _overlaps(boxes: list[tuple[str, Box]]) -> list[tuple[str, str, float]]:
    return [(a, b, ba.overlap(bb)) for (a, ba), (b, bb) in itertools.combinations(boxes, 2) if ba.overlap(bb) > 0]


@pytest.mark.parametrize("units, code", [("mm", 4), ("in", 1), ("M", 6), ("furlong", 0), ("", 0)])
def test_dxf_declares_the_unit(tmp_path, candidates, units, code):
    (geom,) = _geometries(candidates[:1], units)
    doc = ezdxf.readfile(write_dxf(geom, tmp_path / "a.dxf"))
    assert doc.header["$INSUNITS"] == code
    assert INSUNITS.get(units.lower(), 0) == code


def test_dxf_dimensions_measure_the_links_and_pivots(tmp_path, candidates):
    for c, geom in zip(candidates, _geometries(candidates)):
        doc = ezdxf.readfile(write_dxf(geom, tmp_path / f"{c.rank}.dxf"))
        assert not doc.audit().has_errors
        dims = doc.modelspace().query("DIMENSION")
        assert all(d.dxf.layer == "DIMENSIONS" for d in dims)
        # shown as measured: the EZDXF style's factor 100 (metres drawn, cm shown) is overridden
        assert all(d.override().get("dimlfac") == 1.0 for d in dims)
        measured = np.array([d.get_measurement() for d in dims])
        pivot = c.sixbar.dyad.pivot
        expected = [*_link_lengths(c), c.sixbar.d, abs(pivot.real), abs(pivot.imag)]
        assert len(measured) == len(expected)  # one dimension each, no more
        for value in expected:  # ezdxf recomputes each from the dimension's definition points
            assert min(abs(measured - value)) < 1e-9 * max(1.0, value), (c.id, value, measured)


def test_dxf_has_a_layer_per_link_in_the_palette(tmp_path, candidates):
    for c, geom in zip(candidates, _geometries(candidates)):
        doc = ezdxf.readfile(write_dxf(geom, tmp_path / f"{c.rank}.dxf"))
        msp = doc.modelspace()
        for link in geom.links:
            layer = doc.layers.get(link.name.upper())
            assert layer.rgb == rgb(LINK_COLORS[link.name])
            assert len(msp.query(f'LINE LWPOLYLINE[layer=="{link.name.upper()}"]')) == 1
        assert set(LAYERS) == {layer.dxf.name for layer in doc.layers} - {"0", "Defpoints"} - {
            layer.dxf.name for layer in doc.layers if layer.dxf.name not in LAYERS
        }


def test_no_two_dxf_labels_overlap(tmp_path, candidates, double_report_dir):
    from ezdxf import bbox

    for c, geom in zip([*candidates, *double_report_dir[2]], _geometries([*candidates, *double_report_dir[2]])):
        doc = ezdxf.readfile(write_dxf(geom, tmp_path / f"{c.rank}.dxf"))
        texts = doc.modelspace().query("TEXT")
        assert {"A0", "B0", "D", "A", "B", "P"} <= {t.dxf.text for t in texts}
        boxes = []
        for t in texts:
            ext = bbox.extents([t])
            boxes.append((t.dxf.text, Box(ext.extmin.x, ext.extmin.y, ext.extmax.x, ext.extmax.y)))
        assert not _overlaps(boxes), (c.id, _overlaps(boxes))


def _svg_label_boxes(path) -> list[tuple[str, Box]]:
    """Boxes of the joint labels and the legend's entries as the SVG places them (font size
    from the element, width and height from matplotlib's text path of that string)."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    out = []
    for el in ET.parse(path).getroot().iter("{http://www.w3.org/2000/svg}text"):
        style = el.get("style", "")
        size = float(re.search(r"font-size: ([\d.]+)px", style).group(1))
        bold = "font-weight: 700" in style or "bold" in style
        ext = TextPath(
            (0, 0), el.text, size=size, prop=FontProperties(family="DejaVu Sans", weight="bold" if bold else "normal")
        ).get_extents()
        x, y = float(el.get("x")), float(el.get("y"))
        out.append((el.text, Box(x + ext.x0, y - ext.y1, x + ext.x1, y - ext.y0)))  # SVG: y down
    return out


def test_no_two_svg_labels_overlap(tmp_path, candidates, double_report_dir):
    joints = {"A0", "B0", "D", "A", "B", "P", "Q"}
    cands = [*candidates, *double_report_dir[2]]
    for c, geom in zip(cands, _geometries(cands)):
        boxes = _svg_label_boxes(draw_sixbar(geom, tmp_path / f"{c.rank}.svg"))
        labels = [(t, b) for t, b in boxes if t in joints]
        legend = [
            (t, b)
            for t, b in boxes
            if t.startswith(
                ("crank a", "coupler b", "rocker c", "rod", "output", "slotted", "dwell", "coupler curve", "slot line")
            )
        ]
        assert len(labels) == len(geom.fixed) + len(geom.joints)
        clashes = _overlaps(labels) + [
            (a, b, ba.overlap(bb)) for a, ba in labels for b, bb in legend if ba.overlap(bb) > 0
        ]
        assert not clashes, (c.id, clashes)


def test_svg_drawing_and_page_use_the_palette(report_dir, candidates):
    from report.export import safe_stem

    out, _ = report_dir
    page = (out / "index.html").read_text(encoding="utf-8")
    for c in candidates:
        svg = (out / f"{safe_stem(c)}-drawing.svg").read_text(encoding="utf-8")
        names = ["crank", "coupler", "rocker", "output"] + (["rod"] if c.sixbar.dyad.kind == "RRR" else [])
        for name in names:
            assert f"stroke: {LINK_COLORS[name]}" in svg, (c.id, name)
    css_class = {"crank": "crank", "coupler": "coupler", "rocker": "rocker", "rod": "rod", "output": "output-link"}
    for name, color in LINK_COLORS.items():
        assert re.search(rf"svg\.mech \.{css_class[name]}\{{[^}}]*stroke:{color}", page), name


# ---------------------------------------------------------------------------------------------
# The placement itself
# ---------------------------------------------------------------------------------------------


@given(
    st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5)), min_size=1, max_size=12),
    st.lists(st.tuples(st.floats(0.05, 1.0), st.floats(0.05, 0.5)), min_size=12, max_size=12),
)
def test_a_label_stays_by_its_anchor_and_never_covers_it(anchors, sizes):
    boxes = place_labels(anchors, sizes[: len(anchors)], gap=0.1)
    for (x, y), (w, h), b in zip(anchors, sizes, boxes):
        assert (b.x1 - b.x0, b.y1 - b.y0) == pytest.approx((w, h))
        assert not (b.x0 < x < b.x1 and b.y0 < y < b.y1)
        # within the farthest candidate position (3.6 gaps plus the box)
        assert b.x0 >= x - 0.36 - w - 1e-12 and b.x1 <= x + 0.36 + w + 1e-12
        assert b.y0 >= y - 0.36 - h - 1e-12 and b.y1 <= y + 0.36 + h + 1e-12


@given(st.lists(st.tuples(st.integers(-20, 20), st.integers(-20, 20)), min_size=1, max_size=40, unique=True))
def test_labels_of_anchors_a_label_apart_never_overlap(cells):
    """Anchors on a grid one unit apart, labels 0.4 × 0.2 with gap 0.1: each fits by its anchor."""
    anchors = [(float(i), float(j)) for i, j in cells]
    boxes = place_labels(anchors, [(0.4, 0.2)] * len(anchors), gap=0.1)
    assert not _overlaps([(str(k), b) for k, b in enumerate(boxes)])


def test_eight_labels_on_one_anchor_all_fit():
    """The four quadrants near the anchor, then the four far out: no overlap."""
    boxes = place_labels([(0.0, 0.0)] * 8, [(0.4, 0.2)] * 8, gap=0.1)
    assert not _overlaps([(str(k), b) for k, b in enumerate(boxes)])


def test_placement_avoids_obstacles():
    (box,) = place_labels([(0.0, 0.0)], [(1.0, 0.5)], gap=0.1, obstacles=[Box(0.0, 0.0, 5.0, 5.0)])
    assert box.overlap(Box(0.0, 0.0, 5.0, 5.0)) == 0
    assert box.x1 <= 0.0 or box.y1 <= 0.0
