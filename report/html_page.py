"""The report's HTML page: one self-contained file (inline SVG, CSS and JavaScript; no network
resource, no external font or script) with a table of the candidates and, for each, an
animation of the six-bar through the turn, its ψ(φ) strip chart, its dimensions and its plots.

The animation plays precomputed positions (the report's :class:`~report.cycle.Cycle`, embedded
as JSON in a ``<script type="application/json" class="cycle-data">`` block per candidate); the
script only moves SVG elements. Observable hooks, for people and tests alike:

* ``section.candidate#cand-<rank>`` with ``data-phi`` (crank angle shown, deg) and the class
  ``is-dwelling`` while the output dwells;
* inside it ``.crank``, ``.rocker``, ``.rod`` (RRR), ``.output-link`` (lines; ``x2``/``y2`` is the
  moving end, SVG y = −y), ``.coupler`` (polygon), ``.block`` (RPR), joints ``.j-A`` … ``.j-Q``;
  ``.output-link`` has the class ``dwelling`` while the output dwells;
* ``button.play`` (``aria-pressed="true"`` while playing), ``input.phi-slider`` (value = step
  index, ``data-phi`` = crank angle in degrees, ``data-step`` = step in degrees);
* ``window.dwellAtlas.animations[<section id>]`` → ``{show(i), play(), pause()}``.

Self-test: opened with ``?selftest`` (or ``?selftest=A1,A2`` crank angles in degrees, default
90,270; ``&wait=MS``, default 600) the page records, for every candidate, the moving end of the
crank and of the output link at load and ``wait`` ms later, then after moving the slider to each
angle, then whether Play resumes; it writes that and every error and console error met since
the page started as JSON into ``<pre id="selftest">`` (readable with ``chromium --dump-dom``).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from report.cycle import Cycle
from report.escape import script_json, text
from report.palette import BLOCK, CURVE, DWELL, LINK_COLORS
from report.sixbar_drawing import SLOT_MARGIN, SixBarGeometry
from synth.kinds import OutputKind
from synth.query.candidates import Candidate, Request

__all__ = ["PageEntry", "inline_svg", "render_page"]

#: One crank turn of the animation takes this long (ms).
TURN_MS = 6000
#: Strip chart size (px): width, height, and margins left, right, top, bottom.
STRIP = (640.0, 150.0, 52.0, 12.0, 10.0, 26.0)


@dataclass(frozen=True, slots=True)
class PageEntry:
    """One candidate on the page: its cycle and drawn geometry, its plots as SVG text (name →
    SVG), and the report files that belong to it (names relative to the page)."""

    candidate: Candidate
    cycle: Cycle
    geometry: SixBarGeometry
    plots: dict[str, str] = field(default_factory=dict)
    files: list[str] = field(default_factory=list)


_esc = text  # the one escaping helper (report/escape.py), short name for the many f-strings


def _num(x: float, digits: int = 6) -> str:
    return f"{x:.{digits}g}"


def _length(x: float, units: str, digits: int = 6) -> str:
    """A length with its unit's name (``12.5 in``; the bare number without one)."""
    return f"{_num(x, digits)} {units}" if units else _num(x, digits)


_json_script = script_json


# --------------------------------------------------------------------------------------------
# Inline SVG from matplotlib
# --------------------------------------------------------------------------------------------

_ID = re.compile(r'\bid="([^"]+)"')
_URL = re.compile(r"url\(#([^)]+)\)")
_HREF = re.compile(r'(xlink:href|href)="#([^"]+)"')


def inline_svg(svg_text: str, prefix: str) -> str:
    """A matplotlib SVG document made fit to sit inside an HTML page.

    Drops the XML declaration, DOCTYPE, metadata and matplotlib's global ``<style>`` (its
    ``*{…}`` rule would restyle the whole page; the page CSS carries it, scoped), and prefixes
    every id and reference with ``prefix`` so several plots (clip paths) do not collide.
    """
    text = re.sub(r"<\?xml.*?\?>", "", svg_text, flags=re.DOTALL)
    text = re.sub(r"<!DOCTYPE.*?>", "", text, flags=re.DOTALL)
    text = re.sub(r"<metadata>.*?</metadata>", "", text, flags=re.DOTALL)
    text = re.sub(r"<style[^>]*>.*?</style>", "", text, flags=re.DOTALL)
    text = _ID.sub(lambda m: f'id="{prefix}{m.group(1)}"', text)
    text = _URL.sub(lambda m: f"url(#{prefix}{m.group(1)})", text)
    text = _HREF.sub(lambda m: f'{m.group(1)}="#{prefix}{m.group(2)}"', text)
    return text.strip()


# --------------------------------------------------------------------------------------------
# Animation data and static SVG
# --------------------------------------------------------------------------------------------


def _pt(z: complex) -> list[float]:
    """[x, −y]: SVG's y axis points down; 7 significant digits are far below a pixel."""
    return [float(f"{z.real:.7g}"), float(f"{-z.imag:.7g}")]


def _slot_ends(entry: PageEntry) -> np.ndarray:
    """RPR: the far end of the slotted rocker at every step (D + reach·e^{iψ})."""
    cyc, D = entry.cycle, entry.candidate.sixbar.dyad.pivot
    reach = float(np.max(np.abs(cyc.P[cyc.assembled] - D))) if cyc.assembled.any() else 1.0
    return D + SLOT_MARGIN * reach * np.exp(1j * cyc.psi)


def _strip_map(psi_deg: np.ndarray) -> tuple[float, float]:
    """(ψ at the bottom, ψ at the top) of the strip chart (deg)."""
    lo, hi = float(np.min(psi_deg)), float(np.max(psi_deg))
    pad = max(0.06 * (hi - lo), 0.5)
    return lo - pad, hi + pad


def _strip_xy(phi_deg: np.ndarray | float, psi_deg: np.ndarray | float, lo: float, hi: float):
    W, H, ml, mr, mt, mb = STRIP
    x = ml + np.asarray(phi_deg) / 360.0 * (W - ml - mr)
    y = mt + (hi - np.asarray(psi_deg)) / (hi - lo) * (H - mt - mb)
    return x, y


def _animation_data(entry: PageEntry) -> dict:
    """Everything the script needs to play one candidate (positions as [x, −y])."""
    cyc, sb = entry.cycle, entry.candidate.sixbar
    psi_deg = np.degrees(cyc.psi)
    lo, hi = _strip_map(psi_deg[cyc.assembled] if cyc.assembled.any() else psi_deg)
    _, sy = _strip_xy(np.degrees(cyc.phi), psi_deg, lo, hi)
    W, _, ml, mr, _, _ = STRIP
    data = {
        "kind": sb.dyad.kind,
        "step": float(f"{360.0 / len(cyc):.9g}"),
        "phi": [float(f"{v:.9g}") for v in np.degrees(cyc.phi)],
        "psi": [float(f"{v:.7g}") for v in psi_deg],
        "dwell": [int(v) for v in cyc.dwelling],
        "ok": [int(v) for v in cyc.assembled],
        "A0": _pt(0j),
        "B0": _pt(complex(sb.d, 0.0)),
        "D": _pt(sb.dyad.pivot),
        "A": [_pt(z) for z in cyc.A],
        "B": [_pt(z) for z in cyc.B],
        "P": [_pt(z) for z in cyc.P],
        "sy": [round(float(v), 2) for v in sy],
        "strip": {"x0": ml, "w": W - ml - mr},
    }
    if sb.dyad.kind == OutputKind.RRR:
        data["Q"] = [_pt(z) for z in cyc.Q]
    else:
        data["S"] = [_pt(z) for z in _slot_ends(entry)]
    return data


def _box(entry: PageEntry, data: dict) -> tuple[float, float, float, float]:
    """viewBox (x, y, w, h) in SVG coordinates around everything that moves or is fixed."""
    pts = [data["A0"], data["B0"], data["D"], *data["A"], *data["B"], *data["P"]]
    pts += data.get("Q", []) + data.get("S", [])
    xs = [p[0] for p in pts]
    ys = [p[1] for p in pts]
    x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    pad = 0.08 * max(x1 - x0, y1 - y0, 1e-9)
    return x0 - pad, y0 - pad, x1 - x0 + 2 * pad, y1 - y0 + 2 * pad


def _poly(points: list[list[float]]) -> str:
    return " ".join(f"{p[0]:.7g},{p[1]:.7g}" for p in points)


def _runs_svg(entry: PageEntry) -> list[str]:
    """Polylines of the coupler curve's dwell stretches (static)."""
    return [
        f'<polyline class="dwell-stretch" points="{_poly([_pt(z) for z in s])}"/>'
        for s in entry.geometry.dwell_stretches
        if len(s) >= 2
    ]


def _mechanism_svg(entry: PageEntry, data: dict) -> str:
    """The animated mechanism at the first step; the script moves the classed elements."""
    x, y, w, h = _box(entry, data)
    u = max(w, h) / 500.0  # one "pixel" of a 500-px drawing, in user units
    kind = data["kind"]
    A, B, P = data["A"][0], data["B"][0], data["P"][0]

    def line(cls: str, p: list[float], q: list[float]) -> str:
        return f'<line class="{cls}" x1="{p[0]:.7g}" y1="{p[1]:.7g}" x2="{q[0]:.7g}" y2="{q[1]:.7g}"/>'

    out = [
        (
            f'<svg class="mech" xmlns="http://www.w3.org/2000/svg" viewBox="{x:.7g} {y:.7g} {w:.7g} {h:.7g}" '
            f'width="560" height="{560 * h / w:.0f}" role="img" aria-label="six-bar animation">'
        ),
        f'<polyline class="coupler-curve" points="{_poly(data["P"] + data["P"][:1])}"/>',
    ]
    out += _runs_svg(entry)
    if kind == OutputKind.RRR:
        out.append(f'<polyline class="q-path" points="{_poly(data["Q"])}"/>')
    out.append(line("ground", data["A0"], data["B0"]))
    out.append(line("crank", data["A0"], A))
    out.append(f'<polygon class="coupler" points="{_poly([A, B, P])}"/>')
    out.append(line("rocker", data["B0"], B))
    if kind == OutputKind.RRR:
        Q = data["Q"][0]
        out.append(line("rod", P, Q))
        out.append(line("output-link", data["D"], Q))
    else:
        out.append(line("output-link", data["D"], data["S"][0]))
        s = 7 * u
        out.append(
            f'<rect class="block" x="{-1.6 * s:.5g}" y="{-s:.5g}" width="{3.2 * s:.5g}" height="{2 * s:.5g}" '
            f'transform="translate({P[0]:.7g},{P[1]:.7g}) rotate({-data["psi"][0]:.6g})"/>'
        )
    for name in ("A0", "B0", "D"):
        px, py = data[name]
        s = 8 * u
        tri = _poly([[px, py], [px - s, py + 1.6 * s], [px + s, py + 1.6 * s]])
        out.append(f'<polygon class="ground-pivot" points="{tri}"/>')
        out.append(f'<circle class="pivot" cx="{px:.7g}" cy="{py:.7g}" r="{3.2 * u:.4g}"/>')
        # D often sits near B0: its label goes on the other side
        lx, anchor = (px - 1.3 * s, "end") if name == "D" else (px + 1.3 * s, "start")
        out.append(
            f'<text class="label fixed" x="{lx:.7g}" y="{py + 2.4 * s:.7g}" text-anchor="{anchor}" '
            f'font-size="{13 * u:.4g}">{_esc(name)}</text>'
        )
    joints = {"A": A, "B": B, "P": P} | ({"Q": data["Q"][0]} if kind == OutputKind.RRR else {})
    for name, p in joints.items():
        out.append(f'<circle class="joint j-{_esc(name)}" cx="{p[0]:.7g}" cy="{p[1]:.7g}" r="{3.6 * u:.4g}"/>')
        out.append(
            f'<text class="label l-{_esc(name)}" x="{p[0] + 6 * u:.7g}" y="{p[1] - 6 * u:.7g}" '
            f'font-size="{13 * u:.4g}">{_esc(name)}</text>'
        )
    out.append("</svg>")
    return "\n".join(out)


def _strip_svg(entry: PageEntry, data: dict) -> str:
    """ψ(φ) strip chart with the dwell interval(s) shaded and a cursor the script moves."""
    W, H, ml, mr, mt, mb = STRIP
    cyc = entry.cycle
    psi_deg = np.array(data["psi"])
    lo, hi = _strip_map(psi_deg[cyc.assembled] if cyc.assembled.any() else psi_deg)
    phi_deg = np.append(np.degrees(cyc.phi), 360.0)
    x, y = _strip_xy(phi_deg, np.append(psi_deg, psi_deg[0]), lo, hi)
    out = [
        (
            f'<svg class="strip" xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {W:g} {H:g}" width="{W:g}" '
            f'height="{H:g}" role="img" aria-label="output angle against crank angle">'
        )
    ]
    top, bottom = mt, H - mb
    for dw in entry.candidate.figures.dwells:
        for a, b in dw.spans_deg():
            xa, _ = _strip_xy(a, lo, lo, hi)
            xb, _ = _strip_xy(b, lo, lo, hi)
            out.append(
                f'<rect class="dwell-band" x="{xa:.2f}" y="{top:.2f}" width="{xb - xa:.2f}" '
                f'height="{bottom - top:.2f}"/>'
            )
    out.append(f'<rect class="frame" x="{ml:g}" y="{top:g}" width="{W - ml - mr:g}" height="{bottom - top:g}"/>')
    for tick in range(0, 361, 90):
        tx, _ = _strip_xy(tick, lo, lo, hi)
        out.append(
            f'<line class="tick" x1="{tx:.2f}" y1="{bottom:g}" x2="{tx:.2f}" y2="{bottom + 4:g}"/>'
            f'<text class="tick-label" x="{tx:.2f}" y="{H - 8:g}" text-anchor="middle">{tick}°</text>'
        )
    for value in (lo, hi):
        _, ty = _strip_xy(0.0, value, lo, hi)
        out.append(f'<text class="tick-label" x="{ml - 5:g}" y="{ty + 4:.2f}" text-anchor="end">{value:.1f}°</text>')
    out.append(f'<text class="axis-label" x="{ml + 4:g}" y="{top + 12:g}">ψ</text>')
    out.append(f'<text class="axis-label" x="{W - mr - 4:g}" y="{bottom - 5:g}" text-anchor="end">φ</text>')
    out.append(f'<polyline class="psi-curve" points="{" ".join(f"{a:.2f},{b:.2f}" for a, b in zip(x, y))}"/>')
    out.append(f'<line class="cursor" x1="{x[0]:.2f}" y1="{top:g}" x2="{x[0]:.2f}" y2="{bottom:g}"/>')
    out.append(f'<circle class="psi-dot" cx="{x[0]:.2f}" cy="{y[0]:.2f}" r="4"/>')
    out.append("</svg>")
    return "\n".join(out)


# --------------------------------------------------------------------------------------------
# Tables
# --------------------------------------------------------------------------------------------


def _request_line(request: Request, units: str = "") -> str:
    r = request
    swing = (
        "swing free"
        if r.swing is None
        else f"swing {_num(math.degrees(r.swing))}° ± {_num(math.degrees(r.swing_tol))}°"
    )
    parts = [
        f"dwell {_num(math.degrees(r.dwell))}° ± {_num(math.degrees(r.dwell_tol))}°",
        f"{r.dwells} dwell(s) per turn",
        swing,
        f"output {r.output}",
        f"dwell band {_num(math.degrees(r.band))}°",
        f"crank {_length(r.crank, units)}",
        *((f"manufacturing tolerance ±{_length(r.tolerance, units)}",) if r.tolerance > 0 else ()),
        f"transmission ≥ {_num(math.degrees(r.min_transmission))}°",
        f"link ratio ≤ {_num(r.max_link_ratio)}",
        f"slider arm ≥ {_num(r.min_arm)} cranks · clearance ≥ {_num(r.min_clearance)} cranks",
    ]
    return " · ".join(_esc(p) for p in parts)


def _dwells_text(c: Candidate) -> str:
    f = c.figures
    return "; ".join(f"{math.degrees(d.angle):.2f}°" for d in f.dwells) or "–"


def _summary_table(entries: list[PageEntry], units: str = "") -> str:
    # the toleranced deviation (--tolerance) beside the nominal one, where it was worked out
    toleranced = any(e.candidate.toleranced_deviation is not None for e in entries)
    head = (
        "rank",
        "id",
        "output",
        "dwell(s)",
        "deviation",
        *(("toleranced deviation",) if toleranced else ()),
        "swing",
        "μ four-bar",
        "μ output",
        "link ratio",
        f"footprint ({units}²)" if units else "footprint",
    )
    rows = []
    for e in entries:
        c, f = e.candidate, e.candidate.figures
        dev = max(f.deviations) if f.deviations else None
        tol = c.toleranced_deviation
        cells = [
            f'<a href="#cand-{int(c.rank)}">{int(c.rank)}</a>',
            f"<code>{_esc(c.id)}</code>",
            _esc(c.sixbar.dyad.kind),
            _esc(_dwells_text(c)),
            "–" if dev is None else f"{math.degrees(dev):.4f}°",
            *((("–" if tol is None else f"{math.degrees(tol):.4f}°"),) if toleranced else ()),
            f"{math.degrees(f.swing):.3f}°",
            f"{math.degrees(f.transmission_fourbar):.1f}°",
            "slot" if c.sixbar.dyad.kind == "RPR" else f"{math.degrees(f.transmission_output):.1f}°",
            f"{f.link_ratio:.2f}",
            _num(f.footprint, 6),
        ]
        rows.append("<tr>" + "".join(f"<td>{x}</td>" for x in cells) + "</tr>")
    return (
        '<table class="summary"><thead><tr>'
        + "".join(f"<th>{_esc(h)}</th>" for h in head)
        + "</tr></thead><tbody>"
        + "\n".join(rows)
        + "</tbody></table>"
    )


def _dimensions_table(entry: PageEntry, rpm: float, units: str = "") -> str:
    """Every dimension and figure of one candidate (lengths in the user's unit ``units``, named
    beside each; the output's peak rates at ``rpm``)."""
    c = entry.candidate
    sb, f, dy = c.sixbar, c.figures, c.sixbar.dyad

    def xy(z: complex) -> str:
        return f"({_num(z.real)}, {_num(z.imag)}){f' {units}' if units else ''}"

    def ln(x: float, digits: int = 6) -> str:
        return _length(x, units, digits)

    rows: list[tuple[str, str]] = [
        ("crank a (A0–A)", ln(sb.a)),
        ("coupler b (A–B)", ln(sb.b)),
        ("rocker c (B0–B)", ln(sb.c)),
        ("ground d (A0–B0)", ln(sb.d)),
        ("four-bar branch", f"{sb.branch:+d}"),
        ("coupler point (u, v), coupler frame", xy(sb.coupler_point)),
        ("output dyad", dy.kind),
        ("output pivot D", xy(dy.pivot)),
    ]
    if dy.kind == OutputKind.RRR:
        rows += [
            ("output rocker L (D–Q)", ln(dy.rocker)),
            ("rod ρ (P–Q)", ln(dy.rod)),
            ("dyad branch", f"{dy.branch:+d}"),
        ]
        if c.dwell_position is not None:
            rows.append(("Q at rest (dwell)", xy(c.dwell_position)))
    for k, d in enumerate(f.dwells):
        dev = f" · deviation {math.degrees(f.deviations[k]):.4f}°" if k < len(f.deviations) else ""
        # both ends in [0°, 360°): a dwell over φ = 0 reads 354.58° … 39.56°, not … 399.56°
        start, end = d.ends_deg()
        span = f"{math.degrees(d.angle):.3f}° over φ = {start:.2f}° … {end:.2f}°"
        rows.append((f"dwell {k + 1}", span + dev))
    if c.refined_from is not None:
        # exact refinement (synth/query/refine.py): the retrieved six-bar's figures, for comparison
        g = c.refined_from
        dwells = " / ".join(f"{math.degrees(d.angle):.3f}°" for d in g.dwells)
        dev = f" · deviation {math.degrees(max(g.deviations)):.4f}°" if g.deviations else ""
        rows.append(("refined from (as retrieved)", f"dwell {dwells} · swing {math.degrees(g.swing):.4f}°{dev}"))
    if c.toleranced_deviation is not None:
        rows.append(
            (
                "toleranced deviation (95 % of six-bars made within the tolerance)",
                f"{math.degrees(c.toleranced_deviation):.4f}°",
            )
        )
    rows += [
        ("swing", f"{math.degrees(f.swing):.4f}°"),
        ("min transmission, four-bar", f"{math.degrees(f.transmission_fourbar):.2f}°"),
        (
            "min transmission, output",
            "slot (90° by construction)" if dy.kind == "RPR" else f"{math.degrees(f.transmission_output):.2f}°",
        ),
        ("link ratio", _num(f.link_ratio, 4)),
        ("footprint (hull area)", f"{_num(f.footprint, 5)}{f' {units}²' if units else ''}"),
    ]
    if f.build is not None:
        b = f.build
        if b.arm is not None:
            rows += [
                ("slider to slot pivot, smallest (torque arm)", ln(b.arm)),
                ("slot length used, |P − D|", f"{_num(b.slot[0])} … {ln(b.slot[1])}"),
            ]
        speed, accel, jerk = b.dynamics(rpm)
        rows += [
            ("clearance to the fixed pivots", f"{ln(b.clearance)} ({b.clearance_between})"),
            (
                f"output peak speed / acceleration / jerk at {_num(rpm)} rpm",
                f"{_num(speed, 4)} rad/s · {_num(accel, 4)} rad/s² · {_num(jerk, 4)} rad/s³",
            ),
        ]
    rows.append(("segment", str(int(c.segment_id))))
    body = "".join(f"<tr><th>{_esc(k)}</th><td>{_esc(v)}</td></tr>" for k, v in rows)
    return f'<table class="dimensions">{body}</table>'


# --------------------------------------------------------------------------------------------
# Page
# --------------------------------------------------------------------------------------------


def _candidate_section(entry: PageEntry, rpm: float, units: str = "") -> str:
    c = entry.candidate
    rank = int(c.rank)
    sid = f"cand-{rank}"
    data = _animation_data(entry)
    n = len(data["phi"])
    plots = "\n".join(
        f'<figure class="plot plot-{_esc(name)}">{inline_svg(svg, f"{sid}-{name}-")}</figure>'
        for name, svg in entry.plots.items()
    )
    files = " · ".join(f'<a href="{_esc(name)}">{_esc(name)}</a>' for name in entry.files)
    phi0, kind = f"{data['phi'][0]:g}", _esc(c.sixbar.dyad.kind)
    return f"""<section class="candidate" id="{sid}" data-rank="{rank}" data-kind="{kind}" data-phi="{phi0}">
<h2>#{rank} <code class="cid">{_esc(c.id)}</code> <span class="badge">{_esc(c.sixbar.dyad.kind)}</span></h2>
<div class="row">
<div class="anim">
{_mechanism_svg(entry, data)}
<div class="controls">
<button class="play" type="button" aria-pressed="false">Play</button>
<input class="phi-slider" type="range" min="0" max="{n - 1}" step="1" value="0" data-phi="{phi0}"
 data-step="{data["step"]:g}" aria-label="crank angle">
<output class="phi-readout">φ = 0°</output>
<span class="dwell-flag">dwell</span>
</div>
{_strip_svg(entry, data)}
</div>
<div class="dims">{_dimensions_table(entry, rpm, units)}</div>
</div>
<details class="plots" open><summary>Plots</summary>
<div class="plot-row">{plots}</div>
</details>
<p class="files">Files: {files}</p>
<script type="application/json" class="cycle-data">{_json_script(data)}</script>
</section>"""


def _palette_css() -> str:
    """The links' colours of :mod:`report.palette` (the SVG drawing's and the DXF's) as CSS."""
    rules = [
        f":root{{--dwell:{DWELL}}}",
        f"svg.mech .crank{{stroke:{LINK_COLORS['crank']}}}",
        f"svg.mech .coupler{{fill:{LINK_COLORS['coupler']};stroke:{LINK_COLORS['coupler']}}}",
        f"svg.mech .rocker{{stroke:{LINK_COLORS['rocker']}}}",
        f"svg.mech .rod{{stroke:{LINK_COLORS['rod']}}}",
        f"svg.mech .output-link{{stroke:{LINK_COLORS['output']}}}",
        f"svg.mech .block{{fill:{BLOCK}}}",
        f"svg.mech .coupler-curve{{stroke:{CURVE}}}",
    ]
    return "\n".join(rules) + "\n"


_CSS = """
:root{--ink:#222;--muted:#666;--line:#ddd}
*{box-sizing:border-box}
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,"Helvetica Neue",Arial,sans-serif;color:var(--ink)}
body{margin:0 auto;padding:1.2em 1.5em;max-width:1400px;line-height:1.35}
h1{font-size:1.5em;margin:.2em 0}
h2{font-size:1.2em;margin:.2em 0 .6em;display:flex;gap:.6em;align-items:center}
code{font-family:ui-monospace,"SFMono-Regular",Menlo,Consolas,monospace;font-size:.92em}
h2 .cid{min-width:0;overflow-wrap:anywhere}
.request{color:var(--muted);margin:.3em 0 1em}
table{border-collapse:collapse;font-size:.9em}
table.summary{width:100%;margin-bottom:1.5em;display:block;overflow-x:auto}
table.summary th,table.summary td{border-bottom:1px solid var(--line);padding:.3em .6em}
table.summary th,table.summary td{text-align:right;white-space:nowrap}
table.summary th:nth-child(2),table.summary td:nth-child(2){text-align:left}
table.summary tbody tr:hover{background:#f6f8fb}
section.candidate{border-top:2px solid var(--line);padding:1em 0 1.5em}
.badge{font-size:.7em;background:#eee;border-radius:.6em;padding:.15em .6em;color:var(--muted)}
.row{display:flex;flex-wrap:wrap;gap:1.5em;align-items:flex-start}
.anim{flex:0 1 640px;min-width:300px}
.dims{flex:1 1 320px}
table.dimensions th{text-align:left;font-weight:normal;color:var(--muted);padding:.18em 1em .18em 0;vertical-align:top}
table.dimensions td{padding:.18em 0;font-variant-numeric:tabular-nums}
svg.mech{display:block;width:100%;max-width:560px;height:auto}
svg.mech{background:#fcfcfd;border:1px solid var(--line);border-radius:6px}
svg.mech line,svg.mech polygon,svg.mech polyline,svg.mech circle,svg.mech rect{vector-effect:non-scaling-stroke}
svg.mech .coupler-curve{fill:none;stroke-width:1px;stroke-dasharray:4 3}
svg.mech .dwell-stretch{fill:none;stroke:var(--dwell);stroke-opacity:.45;stroke-width:7px}
svg.mech .dwell-stretch{stroke-linecap:round;stroke-linejoin:round}
svg.mech .q-path{fill:none;stroke:#2ca02c;stroke-opacity:.35;stroke-width:1px}
svg.mech .ground{stroke:#777;stroke-width:1px;stroke-dasharray:8 3 2 3}
svg.mech .crank,svg.mech .rocker,svg.mech .rod,svg.mech .output-link{stroke-width:5px;stroke-linecap:round}
svg.mech .coupler{fill-opacity:.22;stroke-width:4px;stroke-linejoin:round}
svg.mech .output-link.dwelling{stroke:var(--dwell);stroke-width:7px}
svg.mech .block{fill-opacity:.75;stroke:#444;stroke-width:1px}
svg.mech .ground-pivot{fill:#555}
svg.mech .pivot,svg.mech .joint{fill:#fff;stroke:#111;stroke-width:1.5px}
svg.mech .label{fill:#333;font-family:inherit}
svg.mech .label.fixed{font-weight:600}
.controls{display:flex;align-items:center;gap:.7em;margin:.5em 0}
.controls button{font:inherit;min-width:5em;padding:.25em .8em;cursor:pointer}
.controls button{border:1px solid #999;border-radius:4px;background:#fff}
.controls input[type=range]{flex:1;min-width:120px}
.phi-readout{font-variant-numeric:tabular-nums;min-width:0;overflow-wrap:anywhere}
.controls{flex-wrap:wrap}
@media (max-width:520px){body{padding:.6em .5em}.anim,.dims{min-width:0;flex-basis:100%}}
.dwell-flag{visibility:hidden;color:#fff;background:var(--dwell);border-radius:.6em;padding:.05em .6em;font-size:.85em}
section.is-dwelling .dwell-flag{visibility:visible}
svg.strip{display:block;width:100%;max-width:640px;height:auto;cursor:pointer}
svg.strip .frame{fill:none;stroke:#bbb}
svg.strip .dwell-band{fill:var(--dwell);fill-opacity:.14}
svg.strip .psi-curve{fill:none;stroke:#9467bd;stroke-width:1.6}
svg.strip .cursor{stroke:#333;stroke-width:1}
svg.strip .psi-dot{fill:#9467bd;stroke:#fff;stroke-width:1.5}
section.is-dwelling svg.strip .psi-dot{fill:var(--dwell)}
svg.strip .tick{stroke:#999}
svg.strip .tick-label,svg.strip .axis-label{font-size:11px;fill:#555;font-family:inherit}
details.plots summary{cursor:pointer;color:var(--muted);margin:.8em 0 .4em}
.plot-row{display:flex;flex-wrap:wrap;gap:1em}
figure.plot{margin:0;flex:1 1 300px;min-width:0;max-width:620px}
figure.plot svg{width:100%;height:auto}
figure.plot svg *{stroke-linejoin:round;stroke-linecap:butt}
.files{font-size:.85em;color:var(--muted);word-break:break-all}
pre#selftest{white-space:pre-wrap;font-size:.75em}
""" + _palette_css()

# First script in the page: records every error (script, resource, promise) and console error
# from the start, and runs the self-test when asked (see the module docstring).
_HEAD_JS = """
(function () {
  'use strict';
  var errors = window.__dwellErrors = [];
  window.addEventListener('error', function (e) {
    var t = e.target;
    if (t && t !== window && t.tagName) { errors.push('resource failed: <' + t.tagName.toLowerCase() + '>'); return; }
    errors.push(String(e.message || 'error') + (e.filename ? ' @' + e.filename + ':' + e.lineno : ''));
  }, true);
  window.addEventListener('unhandledrejection', function (e) {
    errors.push('unhandled rejection: ' + String(e.reason));
  });
  var consoleError = console.error;
  console.error = function () {
    errors.push('console.error: ' + Array.prototype.map.call(arguments, String).join(' '));
    return consoleError.apply(console, arguments);
  };
  var params = new URLSearchParams(window.location.search);
  if (!params.has('selftest')) return;
  var angles = (params.get('selftest') || '90,270').split(',')
    .filter(function (s) { return s.trim() !== ''; }).map(Number);
  var wait = Number(params.get('wait') || 600);
  function read(sec) {
    var crank = sec.querySelector('.crank'), out = sec.querySelector('.output-link');
    var slider = sec.querySelector('.phi-slider'), play = sec.querySelector('.play');
    var num = function (el, a) { return Number(el.getAttribute(a)); };
    return {crank: [num(crank, 'x2'), num(crank, 'y2')], output: [num(out, 'x2'), num(out, 'y2')],
            phi: Number(slider.dataset.phi), index: Number(slider.value), dwelling: out.classList.contains('dwelling'),
            section_dwelling: sec.classList.contains('is-dwelling'),
            playing: play.getAttribute('aria-pressed') === 'true'};
  }
  window.addEventListener('load', function () {
    var result = {errors: errors, started: !!window.dwellAtlas, wait_ms: wait, angles: angles, candidates: []};
    var finish = function () {
      var pre = document.createElement('pre');
      pre.id = 'selftest';
      pre.textContent = JSON.stringify(result);
      document.body.appendChild(pre);
    };
    var sections = Array.prototype.slice.call(document.querySelectorAll('section.candidate'));
    var first;
    try { first = sections.map(read); } catch (err) { errors.push('selftest: ' + err); finish(); return; }
    setTimeout(function () {
      try {
        sections.forEach(function (sec, i) {
          var rec = {id: sec.id, t0: first[i], t1: read(sec), slider: []};
          var slider = sec.querySelector('.phi-slider'), step = Number(slider.dataset.step);
          var n = Number(slider.max) + 1;
          angles.forEach(function (a) {
            slider.value = String(((Math.round(a / step) % n) + n) % n);
            slider.dispatchEvent(new Event('input', {bubbles: true}));
            rec.slider.push(read(sec));
          });
          sec.querySelector('.play').click();
          rec.resumed = read(sec).playing;
          result.candidates.push(rec);
        });
      } catch (err) { errors.push('selftest: ' + err); }
      finish();
    }, wait);
  });
})();
"""

_MAIN_JS = """
(function () {
  'use strict';
  var TURN_MS = __TURN_MS__;
  function setLine(el, p, q) {
    if (!el) return;
    el.setAttribute('x1', p[0]); el.setAttribute('y1', p[1]);
    el.setAttribute('x2', q[0]); el.setAttribute('y2', q[1]);
  }
  function setAt(el, p, ax, ay) { if (el) { el.setAttribute(ax, p[0]); el.setAttribute(ay, p[1]); } }
  function Animation(sec) {
    var d = JSON.parse(sec.querySelector('script.cycle-data').textContent);
    var n = d.phi.length;
    var q = function (s) { return sec.querySelector(s); };
    var crank = q('.crank'), coupler = q('.coupler'), rocker = q('.rocker'), rod = q('.rod');
    var out = q('.output-link'), block = q('.block'), mech = q('svg.mech');
    var slider = q('.phi-slider'), button = q('.play'), readout = q('.phi-readout');
    var cursor = q('.cursor'), dot = q('.psi-dot'), strip = q('svg.strip');
    var joints = {}, labels = {};
    ['A', 'B', 'P', 'Q'].forEach(function (k) { joints[k] = q('.j-' + k); labels[k] = q('.l-' + k); });
    var u = mech.viewBox.baseVal.width / 500;
    var pos = 0, timer = null, last = 0;
    function show(i) {
      i = ((Math.floor(i) % n) + n) % n;
      var A = d.A[i], B = d.B[i], P = d.P[i];
      setLine(crank, d.A0, A);
      coupler.setAttribute('points', A.join(',') + ' ' + B.join(',') + ' ' + P.join(','));
      setLine(rocker, d.B0, B);
      var at = {A: A, B: B, P: P};
      if (d.kind === 'RRR') {
        at.Q = d.Q[i];
        setLine(rod, P, at.Q);
        setLine(out, d.D, at.Q);
      } else {
        setLine(out, d.D, d.S[i]);
        block.setAttribute('transform', 'translate(' + P[0] + ',' + P[1] + ') rotate(' + (-d.psi[i]) + ')');
      }
      Object.keys(at).forEach(function (k) {
        setAt(joints[k], at[k], 'cx', 'cy');
        setAt(labels[k], [at[k][0] + 6 * u, at[k][1] - 6 * u], 'x', 'y');
      });
      var dwelling = d.dwell[i] === 1;
      out.classList.toggle('dwelling', dwelling);
      sec.classList.toggle('is-dwelling', dwelling);
      mech.classList.toggle('not-assembled', d.ok[i] !== 1);
      slider.value = String(i);
      slider.dataset.phi = String(d.phi[i]);
      sec.dataset.phi = String(d.phi[i]);
      readout.textContent = '\\u03c6 = ' + d.phi[i].toFixed(0) + '\\u00b0   ' +
        '\\u03c8 = ' + d.psi[i].toFixed(3) + '\\u00b0';
      var x = d.strip.x0 + d.phi[i] / 360 * d.strip.w;
      cursor.setAttribute('x1', x); cursor.setAttribute('x2', x);
      dot.setAttribute('cx', x); dot.setAttribute('cy', d.sy[i]);
    }
    function tick() {
      var now = performance.now();
      pos = (pos + (now - last) * n / TURN_MS) % n;
      last = now;
      show(pos);
    }
    function play() {
      if (timer !== null) return;
      last = performance.now();
      timer = setInterval(tick, 30);
      button.textContent = 'Pause';
      button.setAttribute('aria-pressed', 'true');
    }
    function pause() {
      if (timer === null) return;
      clearInterval(timer);
      timer = null;
      button.textContent = 'Play';
      button.setAttribute('aria-pressed', 'false');
    }
    button.addEventListener('click', function () { if (timer === null) play(); else pause(); });
    slider.addEventListener('input', function () { pause(); pos = Number(slider.value); show(pos); });
    strip.addEventListener('click', function (e) {
      var box = strip.getBoundingClientRect(), vb = strip.viewBox.baseVal;
      var x = (e.clientX - box.left) / box.width * vb.width;
      var phi = (x - d.strip.x0) / d.strip.w * 360;
      if (phi < 0 || phi > 360) return;
      pause(); pos = Math.round(phi / d.step) % n; show(pos);
    });
    show(0);
    var still = window.matchMedia && window.matchMedia('(prefers-reduced-motion: reduce)').matches;
    if (!still) play();
    return {show: show, play: play, pause: pause};
  }
  var api = {animations: {}};
  Array.prototype.forEach.call(document.querySelectorAll('section.candidate'), function (sec) {
    api.animations[sec.id] = Animation(sec);
  });
  window.dwellAtlas = api;
})();
""".replace("__TURN_MS__", str(TURN_MS))


def render_page(
    request: Request, entries: list[PageEntry], *, title: str = "Dwell Atlas — candidate six-bars", units: str = ""
) -> str:
    """The whole page as one string (UTF-8 text, no external resources); ``units`` names the
    length unit beside every length ('': the request's unit, unnamed)."""
    sections = "\n".join(_candidate_section(e, request.rpm, units) for e in entries)
    unit_note = (
        f"Lengths in {_esc(units)} (crank = {_esc(_length(request.crank, units))})"
        if units
        else f"Lengths in the request's unit (crank = {_esc(_num(request.crank))})"
    )
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{_esc(title)}</title>
<script>{_HEAD_JS}</script>
<style>{_CSS}</style>
</head>
<body>
<header>
<h1>{_esc(title)}</h1>
<p class="request">Request: {_request_line(request, units)}</p>
</header>
{_summary_table(entries, units)}
{sections}
<footer class="files">{unit_note}; angles in degrees;
fixed frame A0 = (0, 0), B0 = (d, 0). Every figure comes from the exact simulation of the six-bar.</footer>
<script>{_MAIN_JS}</script>
</body>
</html>
"""
