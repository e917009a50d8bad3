"""``dwell curvature``: the curvature geometry of a four-bar's coupler plane at one crank angle.

Pole, pole tangent and normal, inflection circle, Ball's point, conjugate pairs by line
scanning on N rays evenly spaced over 180°, and optionally the double Ball points of the
linkage. xy: fixed frame (A0 = (0, 0), B0 = (d, 0)); uv: coupler frame (origin A, x-axis
along A→B). Degenerate geometry is reported under ``skipped`` with its reason; a point at
infinity is ``null``.
"""

from __future__ import annotations

import json

import click
import numpy as np

from cli.options import ANGLE_DEG, fourbar_options, writable_file
from kinematics.fourbar import GrashofType, crank_range, fourbar_motion, grashof_type
from kinematics.status import Status, describe_status, reason
from synth.curvature.ball import ball_point
from synth.curvature.double_ball import double_ball_points
from synth.curvature.inflection import inflection_circle
from synth.curvature.line_scan import line_scan
from synth.curvature.pole import pole
from synth.types import INVALID

#: Rays of the dense fan drawn by ``--plot`` (the circle-point and centre-point curves).
PLOT_RAYS = 2048
#: Crank samples of the Ball point's coupler curve in the plot.
PLOT_TURN_SAMPLES = 1441


def _xy(z: complex) -> list[float]:
    return [float(z.real), float(z.imag)]


def _deg(z: complex) -> float:
    return float(np.degrees(np.angle(z)))


def _skips(what: str, flags: int) -> list[dict[str, str]]:
    return [{"what": what, "reason": reason(Status[name.upper()])} for name in describe_status(int(flags))]


@click.command("curvature")
@fourbar_options
@click.option("--phi", type=ANGLE_DEG, required=True, help="Crank angle [deg], CCW from +x.")
@click.option(
    "--rays",
    type=click.IntRange(0, 100_000),
    default=12,
    show_default=True,
    help="Rays through the pole for line scanning, evenly spaced over 180 deg from +x.",
)
@click.option(
    "--double-ball", "with_double_ball", is_flag=True, help="Also search the whole turn for double Ball points."
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document instead of the text summary.")
@click.option(
    "--plot",
    type=click.Path(dir_okay=False),
    callback=writable_file(".png", ".svg"),
    help="Draw the coupler plane at this instant to FILE.png|.svg.",
)
def curvature(a, b, c, d, branch, phi, rays, with_double_ball, as_json, plot):
    """Instantaneous invariants of a four-bar's coupler motion at crank angle --phi."""
    br = int(branch)
    phi_rad = float(np.radians(phi))
    motion = fourbar_motion(a, b, c, d, phi_rad, br, order=3)
    if motion.status & Status.NOT_ASSEMBLABLE:
        fourbar_motion(a, b, c, d, phi_rad, br, order=0, on_degenerate="raise")  # raises, naming the reach
    pl = pole(motion)
    circle = inflection_circle(pl)
    ball = ball_point(pl)
    alpha = np.pi * np.arange(rays) / max(rays, 1)
    pairs = line_scan(pl, alpha)
    found = double_ball_points(a, b, c, d, br) if with_double_ball else None

    skipped = _skips("pole", pl.status)
    collapsed = bool(pl.status & Status.INFLECTION_CIRCLE_COLLAPSED)
    pole_ok = not (pl.status & INVALID & ~Status.INFLECTION_CIRCLE_COLLAPSED)  # the pole itself is known
    usable = not (pl.status & INVALID)  # the instant has an inflection circle and a circle-point cubic
    doc = {
        "linkage": {"a": a, "b": b, "c": c, "d": d, "branch": br},
        "phi_deg": phi,
        "grashof": GrashofType(int(grashof_type(a, b, c, d))).label,
        "pole": _xy(complex(pl.point)) if pole_ok else None,
        "pole_tangent_deg": _deg(complex(pl.tangent)) if pole_ok and not collapsed else None,
        "pole_normal_deg": _deg(complex(pl.normal)) if pole_ok and not collapsed else None,
        "coupler_angle_deg": float(np.degrees(motion.theta)),
    }
    circle_ok = circle.status == 0
    doc["inflection_circle"] = {
        "center": _xy(complex(circle.center)) if circle_ok else None,
        "diameter": float(circle.diameter) if circle_ok else None,
        "inflection_pole": _xy(complex(circle.inflection_pole)) if circle_ok else None,
    }
    skipped += _skips("inflection circle", circle.status & ~pl.status)
    ball_ok = ball.status == 0
    doc["ball_point"] = {
        "xy": _xy(complex(ball.point)) if ball_ok else None,
        "uv": _xy(complex(ball.uv)) if ball_ok else None,
        "tangent_deg": _deg(complex(ball.tangent)) if ball_ok else None,
    }
    skipped += _skips("Ball's point", ball.status & ~pl.status)
    doc["conjugate_pairs"] = []
    for k in range(rays):
        flags = int(pairs.status[k])
        circle_inf = flags & (Status.CIRCLE_POINT_AT_INFINITY | Status.RAY_ALONG_POLE_TANGENT | Status.AT_POLE)
        centre_inf = flags & (Status.CENTER_POINT_AT_INFINITY | Status.RAY_ALONG_POLE_TANGENT | Status.AT_POLE)
        ray_deg = float(180.0 * k / rays)
        doc["conjugate_pairs"].append(
            {
                "ray_deg": ray_deg,
                "circle_point": {
                    "xy": _xy(complex(pairs.circle_point[k])),
                    "uv": _xy(complex(pairs.circle_point_uv[k])),
                }
                if usable and not circle_inf
                else None,
                "center_point": _xy(complex(pairs.center_point[k])) if usable and not centre_inf else None,
                "radius": float(pairs.radius[k]) if usable and flags == 0 else None,
            }
        )
        if pole_ok:
            skipped += _skips(f"conjugate pair on ray {ray_deg:g} deg", flags & ~int(pl.status))
    if found is not None:
        doc["double_ball_points"] = [
            {
                "uv": _xy(complex(found.uv[k])),
                "phi_deg": [float(np.degrees(found.phi1[k])), float(np.degrees(found.phi2[k]))],
                "tangent_lines": [
                    {"point": _xy(complex(z)), "direction_deg": _deg(complex(t))}
                    for z, t in ((found.point1[k], found.tangent1[k]), (found.point2[k], found.tangent2[k]))
                ],
            }
            for k in range(len(found))
        ]
        if found.false_crossings[0]:
            skipped.append(
                {
                    "what": f"{int(found.false_crossings[0])} crossing(s) of the Ball-point track at B",
                    "reason": "rocker dead-centre: Ball's point is the pole = B there, not a double Ball point",
                }
            )
        if found.unconverged[0]:
            skipped.append(
                {
                    "what": f"{int(found.unconverged[0])} crossing(s) of the sampled Ball-point track",
                    "reason": "Newton refinement did not converge to two distinct crank angles",
                }
            )
        skipped += _skips("double Ball point search", found.status[0])
    doc["skipped"] = skipped

    scene = _scene(motion, pl, circle, ball, found, a, b, c, d, br) if plot is not None else None
    if as_json:
        click.echo(json.dumps(doc, indent=1, allow_nan=False))
    else:
        click.echo(_text(doc))
    if scene is not None:
        from report.curvature_plot import plot_curvature

        plot_curvature(scene, plot, title=f"Four-bar a={a:g} b={b:g} c={c:g} d={d:g} branch {br:+d}, phi = {phi:g} deg")
        click.echo(f"wrote {plot}", err=True)


def _scene(motion, pl, circle, ball, found, a, b, c, d, br):
    """Fixed-frame geometry for :func:`report.curvature_plot.plot_curvature`."""
    from report.curvature_plot import CurvatureScene

    fan = line_scan(pl, np.pi * np.arange(PLOT_RAYS) / PLOT_RAYS)
    keep_c = (fan.status & ~(Status.CENTER_POINT_AT_INFINITY | Status.AT_POLE)) == 0
    keep_0 = (fan.status & ~(Status.CIRCLE_POINT_AT_INFINITY | Status.AT_POLE)) == 0
    pole_ok = not (pl.status & INVALID & ~Status.INFLECTION_CIRCLE_COLLAPSED)
    ball_ok = ball.status == 0
    path = np.zeros(0, complex)
    if ball_ok:
        parts = []
        for lo, hi in crank_range(a, b, c, d):
            turn = fourbar_motion(a, b, c, d, np.linspace(lo, hi, PLOT_TURN_SAMPLES), br, order=0)
            z = turn.coupler_point(float(ball.uv.real), float(ball.uv.imag))[0]
            parts.append(np.where(turn.ok, z, np.nan))  # NaN only as matplotlib's line break
        path = np.concatenate(parts) if parts else path
    circle_ok = circle.status == 0
    return CurvatureScene(
        ground=(0j, complex(d)),
        joints=(complex(motion.A), complex(motion.B)),
        pole=complex(pl.point) if pole_ok else None,
        pole_tangent=complex(pl.tangent) if pl.status == 0 else None,
        inflection_center=complex(circle.center) if circle_ok else None,
        inflection_diameter=float(circle.diameter) if circle_ok else None,
        circle_curve=fan.circle_point,
        circle_mask=keep_c,
        center_curve=fan.center_point,
        center_mask=keep_0,
        ball_point=complex(ball.point) if ball_ok else None,
        ball_tangent=complex(ball.tangent) if ball_ok else None,
        ball_path=path,
        double_ball=[complex(pl.to_fixed(p)) for p in found.uv] if found is not None and pole_ok else [],
    )


def _text(doc: dict) -> str:
    """The JSON document as a short human-readable summary."""
    f = lambda v: "-" if v is None else (f"({v[0]:.6g}, {v[1]:.6g})" if isinstance(v, list) else f"{v:.6g}")  # noqa: E731
    link = doc["linkage"]
    skipped = [f"  {s['what']}: {s['reason']}" for s in doc["skipped"]]
    lines = [
        f"Four-bar a={link['a']:g} b={link['b']:g} c={link['c']:g} d={link['d']:g} branch {link['branch']:+d}"
        f" ({doc['grashof']}) at phi = {doc['phi_deg']:g} deg",
    ]
    if doc["pole"] is None:
        # nothing at this instant is defined (a toggle, a pole at infinity): the reason first,
        # not a page of dashes; the double Ball points belong to the whole turn and follow
        lines += ["no pole at this instant, so no inflection circle, Ball's point or circle points:"] + skipped
        skipped = []
    else:
        lines += [
            f"pole               {f(doc['pole'])}   tangent {f(doc['pole_tangent_deg'])} deg, normal {f(doc['pole_normal_deg'])} deg",
            f"inflection circle  centre {f(doc['inflection_circle']['center'])}, diameter {f(doc['inflection_circle']['diameter'])}",
            f"Ball's point       xy {f(doc['ball_point']['xy'])}  uv {f(doc['ball_point']['uv'])}",
        ]
    if doc["conjugate_pairs"] and doc["pole"] is not None:
        lines += [
            "",
            f"{'ray[deg]':>9s}  {'circle point xy':>26s}  {'circle point uv':>26s}  {'centre point xy':>26s}  {'radius':>10s}",
        ]
        for p in doc["conjugate_pairs"]:
            cp = p["circle_point"] or {"xy": None, "uv": None}
            lines.append(
                f"{p['ray_deg']:9.4g}  {f(cp['xy']):>26s}  {f(cp['uv']):>26s}  {f(p['center_point']):>26s}  {f(p['radius']):>10s}"
            )
    if "double_ball_points" in doc:
        lines += ["", f"double Ball points: {len(doc['double_ball_points'])}"]
        for p in doc["double_ball_points"]:
            lines.append(f"  uv {f(p['uv'])} at phi = {p['phi_deg'][0]:.6f} and {p['phi_deg'][1]:.6f} deg")
    if skipped:
        lines += ["", "skipped:"] + skipped
    return "\n".join(lines)
