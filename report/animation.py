"""Self-contained animations of a mechanism: an SVG that plays by itself (SMIL) or an HTML page
with inline SVG and a few lines of JavaScript (play/pause and a position slider).

No network resources, no external files: the frames are written into the document. A frame is
plain geometry in the mechanism's length unit (y up); this module only draws.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from report.escape import script_json, text
from report.folder import staged_file

__all__ = ["Animation", "Frame", "write_animation"]

Point = tuple[float, float]

_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22")


@dataclass(frozen=True, slots=True)
class Frame:
    """One position: link outlines (same order and count in every frame), joint points, the
    outlines of slider blocks, and a caption (e.g. ``"phi = 30°"``)."""

    links: list[list[Point]]
    joints: list[Point]
    blocks: list[list[Point]] = field(default_factory=list)
    caption: str = ""


@dataclass(frozen=True, slots=True)
class Animation:
    """Frames plus what does not move: ground pivots, guide lines, traced paths."""

    frames: list[Frame]
    link_labels: list[str]
    ground_pivots: list[tuple[str, Point]] = field(default_factory=list)
    guides: list[tuple[Point, Point]] = field(default_factory=list)
    paths: list[list[Point]] = field(default_factory=list)
    title: str = ""
    seconds: float = 4.0  #: duration of one pass through the frames


def write_animation(animation: Animation, path: str | Path) -> Path:
    """Write ``animation`` to ``path``: ``.svg`` (plays by itself) or ``.html`` (with controls)."""
    path = Path(path)
    if not animation.frames:
        raise ValueError("an animation needs at least one frame")
    text = _html(animation) if path.suffix.lower() == ".html" else _svg(animation, smil=True)
    with staged_file(path) as tmp:  # a killed run leaves the old file or the new one (report/folder.py)
        tmp.write_text(text, encoding="utf-8")
    return path


def _box(animation: Animation) -> tuple[float, float, float, float]:
    pts: list[Point] = [p for f in animation.frames for poly in f.links + f.blocks for p in poly]
    pts += [p for _, p in animation.ground_pivots] + [p for g in animation.guides for p in g]
    pts += [p for path in animation.paths for p in path]
    xs, ys = [p[0] for p in pts], [p[1] for p in pts]
    x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    pad = 0.08 * max(x1 - x0, y1 - y0, 1e-9)
    return x0 - pad, y0 - pad, x1 + pad, y1 + pad


def _pts(poly: list[Point]) -> str:
    return " ".join(f"{x:.6g},{-y:.6g}" for x, y in poly)  # SVG y points down


def _svg(animation: Animation, smil: bool) -> str:
    x0, y0, x1, y1 = _box(animation)
    w, h = x1 - x0, y1 - y0
    unit = max(w, h) / 400.0  # one "pixel" of a 400-pixel drawing
    first = animation.frames[0]
    n = len(animation.frames)
    dur = f"{animation.seconds:g}s"
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" id="mech" viewBox="{x0:.6g} {-y1:.6g} {w:.6g} {h:.6g}" '
        f'width="640" height="{640 * h / w:.0f}" style="background:#fff">',
        f"<title>{text(animation.title)}</title>",
    ]
    for path in animation.paths:
        out.append(
            f'<polyline points="{_pts(path)}" fill="none" stroke="#999" stroke-dasharray="{3 * unit:.3g}" stroke-width="{unit:.3g}"/>'
        )
    for a, b in animation.guides:
        out.append(
            f'<polyline points="{_pts([a, b])}" stroke="#555" stroke-width="{1.2 * unit:.3g}" stroke-dasharray="{8 * unit:.3g},{3 * unit:.3g}"/>'
        )

    def animate(attr: str, values: list[str]) -> str:
        if not smil or n == 1:
            return ""
        return f'<animate attributeName="{attr}" values="{";".join(values)}" dur="{dur}" repeatCount="indefinite" calcMode="discrete"/>'

    for k, poly in enumerate(first.links):
        color = _COLORS[k % len(_COLORS)]
        closed = len(poly) > 2
        tag = "polygon" if closed else "polyline"
        fill = f'fill="{color}" fill-opacity="0.25"' if closed else 'fill="none"'
        frames = [_pts(f.links[k]) for f in animation.frames]
        out.append(
            f'<{tag} class="link" points="{frames[0]}" {fill} stroke="{color}" stroke-width="{5 * unit:.3g}" '
            f'stroke-linejoin="round" stroke-linecap="round">{animate("points", frames)}'
            f"<title>{text(animation.link_labels[k])}</title></{tag}>"
        )
    for k, _ in enumerate(first.blocks):
        frames = [_pts(f.blocks[k]) for f in animation.frames]
        out.append(
            f'<polygon class="block" points="{frames[0]}" fill="#bcbd22" fill-opacity="0.6" stroke="#444" '
            f'stroke-width="{unit:.3g}">{animate("points", frames)}</polygon>'
        )
    for label, (x, y) in animation.ground_pivots:
        s = 6 * unit
        out.append(f'<polygon points="{_pts([(x, y), (x - s, y - 1.6 * s), (x + s, y - 1.6 * s)])}" fill="#555"/>')
        out.append(f'<text x="{x + s:.6g}" y="{-y + 3 * s:.6g}" font-size="{11 * unit:.3g}">{text(label)}</text>')
    for k, _ in enumerate(first.joints):
        xs = [f"{f.joints[k][0]:.6g}" for f in animation.frames]
        ys = [f"{-f.joints[k][1]:.6g}" for f in animation.frames]
        out.append(
            f'<circle class="joint" cx="{xs[0]}" cy="{ys[0]}" r="{3.5 * unit:.3g}" fill="#fff" stroke="#000" '
            f'stroke-width="{unit:.3g}">{animate("cx", xs)}{animate("cy", ys)}</circle>'
        )
    # SMIL cannot change text, so the self-playing SVG shows no per-frame caption
    caption = "" if smil and n > 1 else text(first.caption)
    out.append(
        f'<text id="caption" x="{x0 + 4 * unit:.6g}" y="{-y1 + 14 * unit:.6g}" font-size="{12 * unit:.3g}">{caption}</text>'
    )
    out.append("</svg>")
    return "\n".join(out)


def _html(animation: Animation) -> str:
    svg = _svg(animation, smil=False)
    data = {
        "links": [[_pts(poly) for poly in f.links] for f in animation.frames],
        "blocks": [[_pts(poly) for poly in f.blocks] for f in animation.frames],
        "joints": [[[round(x, 9), round(-y, 9)] for x, y in f.joints] for f in animation.frames],
        "captions": [f.caption for f in animation.frames],
        "ms": 1000.0 * animation.seconds / len(animation.frames),
    }
    script = """
const D = %s;
const svg = document.getElementById('mech');
const links = svg.querySelectorAll('.link'), blocks = svg.querySelectorAll('.block');
const joints = svg.querySelectorAll('.joint'), caption = document.getElementById('caption');
const range = document.getElementById('pos'), button = document.getElementById('play');
let k = 0, timer = null;
function show(i) {
  k = i; range.value = i;
  links.forEach((el, j) => el.setAttribute('points', D.links[i][j]));
  blocks.forEach((el, j) => el.setAttribute('points', D.blocks[i][j]));
  joints.forEach((el, j) => { el.setAttribute('cx', D.joints[i][j][0]); el.setAttribute('cy', D.joints[i][j][1]); });
  caption.textContent = D.captions[i];
}
function play() {
  if (timer) { clearInterval(timer); timer = null; button.textContent = 'Play'; return; }
  button.textContent = 'Pause';
  timer = setInterval(() => show((k + 1) %% D.links.length), D.ms);
}
range.max = D.links.length - 1;
range.addEventListener('input', () => show(Number(range.value)));
button.addEventListener('click', play);
play();
""" % script_json(data)
    title = text(animation.title)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{title}</title>
<style>body{{font-family:sans-serif;margin:1em}} input[type=range]{{width:640px}}</style></head>
<body><h3>{title}</h3>
{svg}
<div><button id="play">Play</button> <input id="pos" type="range" min="0" value="0" step="1"></div>
<script>{script}</script>
</body></html>
"""
