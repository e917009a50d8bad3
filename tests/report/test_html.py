"""The HTML page, read as text: self-contained (no network resource), user strings escaped,
the animation hooks present for every candidate, the embedded positions equal to the JSON's,
inline SVGs well-formed with page-unique ids."""

from __future__ import annotations

import html
import json
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from harness.report_cases import EVIL_ID

from report.html_page import inline_svg


@pytest.fixture(scope="module")
def page(report_dir) -> str:
    return (report_dir[0] / "index.html").read_text(encoding="utf-8")


def _sections(page: str) -> dict[str, str]:
    return dict(re.findall(r'<section class="candidate" id="(cand-\d+)".*?>(.*?)</section>', page, flags=re.S))


def test_page_loads_nothing_from_anywhere(page):
    # namespaces are names, not fetches; anything else with a scheme would be a resource or a link out
    for m in re.finditer(r"https?://[^\s\"')<>]*", page):
        assert m.group(0) in ("http://www.w3.org/2000/svg", "http://www.w3.org/1999/xlink"), m.group(0)
    assert not re.search(r"<(link|img|iframe|object|embed|audio|video|source)\b", page, flags=re.I)
    assert not re.search(r"\ssrc\s*=", page, flags=re.I)
    assert "@import" not in page and "@font-face" not in page
    assert not re.search(r"url\((?!#)", page)  # only references to ids inside the page
    for href in re.findall(r'href="([^"]*)"', page):
        assert href.startswith("#") or re.fullmatch(r"[A-Za-z0-9._-]+", href), href  # anchors and sibling files


def test_user_strings_are_escaped(page):
    assert EVIL_ID not in page
    assert "<script>alert(" not in page
    assert html.escape(EVIL_ID, quote=True) in page  # shown, as text
    # the only script elements are the page's own: head, main, one JSON block per candidate
    scripts = re.findall(r"<script\b[^>]*>", page)
    assert scripts.count('<script type="application/json" class="cycle-data">') == 3
    assert len(scripts) == 2 + 3


def test_every_candidate_has_its_animation_hooks(page, candidates):
    sections = _sections(page)
    assert list(sections) == [f"cand-{c.rank}" for c in candidates]
    for c in candidates:
        body = sections[f"cand-{c.rank}"]
        for hook in (
            'class="crank"',
            'class="coupler"',
            'class="rocker"',
            'class="output-link"',
            'class="play"',
            'class="phi-slider"',
            "data-phi=",
            'class="cursor"',
            'class="psi-dot"',
            'class="dwell-band"',
            'class="joint j-A"',
            'class="joint j-P"',
        ):
            assert hook in body, (c.id, hook)
        if c.sixbar.dyad.kind == "RRR":
            assert 'class="rod"' in body and 'class="joint j-Q"' in body
        else:
            assert 'class="block"' in body
        assert body.count('class="dwell-band"') == len(c.figures.dwells)  # no dwell passes 360° here
        assert len(re.findall(r'<figure class="plot plot-', body)) == 3


def test_embedded_positions_are_the_json_cycle(page, report_dir):
    doc = json.loads((report_dir[0] / "candidates.json").read_text(encoding="utf-8"))
    sections = _sections(page)
    for item in doc["candidates"]:
        body = sections[f"cand-{item['rank']}"]
        data = json.loads(
            re.search(r'<script type="application/json" class="cycle-data">(.*?)</script>', body, flags=re.S).group(1)
        )
        cyc = item["cycle"]
        assert len(data["phi"]) == 360 and data["phi"] == cyc["phi_deg"]
        assert data["dwell"] == [int(x) for x in cyc["dwelling"]]
        A = np.array(data["A"])
        np.testing.assert_allclose(A[:, 0], cyc["A_x"], rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(-A[:, 1], cyc["A_y"], rtol=1e-6, atol=1e-9)  # SVG y points down
        np.testing.assert_allclose(data["psi"], cyc["psi_deg"], rtol=1e-6, atol=1e-9)
        if item["output"]["type"] == "RRR":
            np.testing.assert_allclose(np.array(data["Q"])[:, 0], cyc["Q_x"], rtol=1e-6)


def test_inline_svgs_are_well_formed_and_ids_unique(page):
    svgs = re.findall(r"<svg\b.*?</svg>", page, flags=re.S)
    assert len(svgs) == 3 * (2 + 3)  # per candidate: mechanism, strip, three plots
    for svg in svgs:
        ET.fromstring(svg)
    ids = re.findall(r'\bid="([^"]+)"', page)
    assert len(ids) == len(set(ids))
    # every reference points at an id of the page
    known = set(ids)
    for ref in re.findall(r"url\(#([^)]+)\)", page) + re.findall(r'href="#([^"]+)"', page):
        assert ref in known, ref


def test_inline_svg_strips_document_parts_and_prefixes_ids():
    doc = (
        '<?xml version="1.0"?>\n<!DOCTYPE svg PUBLIC "-//W3C//DTD SVG 1.1//EN" "x">\n'
        '<svg xmlns="http://www.w3.org/2000/svg"><metadata><x/></metadata><style>*{a:b}</style>'
        '<defs><clipPath id="c1"/></defs><g clip-path="url(#c1)"><use xlink:href="#c1"/></g></svg>'
    )
    out = inline_svg(doc, "p-")
    assert out.startswith("<svg") and "metadata" not in out and "<style" not in out and "DOCTYPE" not in out
    assert 'id="p-c1"' in out and "url(#p-c1)" in out and 'xlink:href="#p-c1"' in out
