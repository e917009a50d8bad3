"""``dwell analyze fourbar``: positions, velocities, accelerations of a four-bar."""

from __future__ import annotations

import click
import numpy as np

from cli.analyze.emit import emit_motion
from cli.analyze.fourbar_stats import run_stats, stats_options
from cli.options import (
    COORDINATE,
    crank_angle_options,
    crank_angles_deg,
    fourbar_options,
    output_options,
    speed_from_options,
    speed_options,
)
from kinematics.fourbar import (
    GrashofType,
    check_lengths,
    crank_range,
    fourbar_motion,
    grashof_type,
    rocker_limits,
    transmission_angle,
)
from kinematics.timing import time_derivatives
from report.drawing import Sketch
from report.motion_table import Column, MotionTable


@click.command("fourbar")
@fourbar_options
@click.option(
    "--point",
    nargs=2,
    type=COORDINATE,
    default=None,
    metavar="U V",
    help="Coupler point in the coupler frame (origin A, x-axis along A->B).",
)
@crank_angle_options
@speed_options
@output_options
@stats_options
def fourbar(
    a,
    b,
    c,
    d,
    branch,
    point,
    phi,
    phi_from,
    phi_to,
    phi_step,
    rpm,
    omega,
    cw,
    crank_alpha,
    as_json,
    plot,
    draw,
    units,
    stats,
    crank_lengths,
    rpms,
    phases,
    clutch,
    cv_bounds,
):
    """Analyse a four-bar: ground pivots A0=(0,0), B0=(d,0); crank angle CCW from +x."""
    check_lengths(a=a, b=b, c=c, d=d)
    if stats:
        return run_stats(
            a,
            b,
            c,
            d,
            int(branch),
            stats,
            crank_lengths,
            rpms,
            as_json,
            plot,
            rpm=rpm,
            phases=phases,
            clutch=clutch,
            cv_bounds=cv_bounds,
            units=units,
        )
    if point is not None and not np.all(np.isfinite(point)):
        raise click.BadParameter("--point must be two finite numbers")
    br = int(branch)
    w = speed_from_options(rpm, omega, cw)
    angles = crank_angles_deg(phi, phi_from, phi_to, phi_step)
    L = units

    def evaluate(phi_deg: np.ndarray) -> MotionTable:
        m = fourbar_motion(a, b, c, d, np.radians(phi_deg), br, order=3, on_degenerate="raise")
        th = time_derivatives(m.dtheta, w, crank_alpha)
        ga = time_derivatives(m.dgamma, w, crank_alpha)
        B = m.B
        cols = [
            Column("phi", "deg", phi_deg, "crank angle"),
            Column("theta", "deg", np.degrees(m.theta), "coupler angle"),
            Column("gamma", "deg", np.degrees(m.gamma), "rocker angle"),
            Column("omega_coupler", "rad/s", th[0], "coupler angular velocity"),
            Column("omega_rocker", "rad/s", ga[0], "rocker angular velocity"),
            Column("alpha_coupler", "rad/s^2", th[1], "coupler angular acceleration"),
            Column("alpha_rocker", "rad/s^2", ga[1], "rocker angular acceleration"),
            Column("transmission", "deg", np.degrees(transmission_angle(m)), "transmission angle"),
            Column("Bx", L, B.real),
            Column("By", L, B.imag),
        ]
        if point is not None:
            z = m.coupler_point(point[0], point[1], order=2)
            zt = time_derivatives(z[1:], w, crank_alpha)
            cols += [
                Column("Px", L, z[0].real),
                Column("Py", L, z[0].imag),
                Column("vPx", f"{L}/s", zt[0].real),
                Column("vPy", f"{L}/s", zt[0].imag),
                Column("aPx", f"{L}/s^2", zt[1].real),
                Column("aPy", f"{L}/s^2", zt[1].imag),
            ]
        return MotionTable(mechanism, cols, summary)

    kind = GrashofType(int(grashof_type(a, b, c, d)))
    mechanism = {
        "type": "fourbar",
        "a": a,
        "b": b,
        "c": c,
        "d": d,
        "branch": br,
        "point": list(point) if point is not None else None,
        "length_unit": L,
        "crank_speed_rad_s": w,
        "crank_acceleration_rad_s2": crank_alpha,
    }
    summary = {
        "grashof": kind.label,
        "crank_range_deg": [[float(np.degrees(lo)), float(np.degrees(hi))] for lo, hi in crank_range(a, b, c, d)],
    }
    if kind is GrashofType.CRANK_ROCKER:
        lim = rocker_limits(a, b, c, d, br)
        summary["rocker_limits"] = {
            "phi_extended_deg": float(np.degrees(lim.phi_extended)),
            "gamma_extended_deg": float(np.degrees(lim.gamma_extended)),
            "phi_folded_deg": float(np.degrees(lim.phi_folded)),
            "gamma_folded_deg": float(np.degrees(lim.gamma_folded)),
        }
        summary["swing_deg"] = float(np.degrees(lim.swing))
        summary["time_ratio"] = lim.time_ratio
        turn = fourbar_motion(a, b, c, d, np.radians(np.arange(0.0, 360.0, 0.25)), br, order=0)
        mu = np.degrees(transmission_angle(turn))
        summary["transmission_deg_range"] = [float(mu.min()), float(mu.max())]
    table = evaluate(angles)

    def sketch() -> Sketch:
        m = fourbar_motion(a, b, c, d, np.radians(angles[:1]), br, order=0)
        A, B = complex(m.A[0]), complex(m.B[0])
        xy = lambda z: (float(z.real), float(z.imag))  # noqa: E731
        coupler = [xy(A), xy(B)]
        paths = []
        joints = [("A", xy(A)), ("B", xy(B))]
        if point is not None:
            P = complex(m.coupler_point(*point)[0][0])
            coupler = [xy(A), xy(B), xy(P), xy(A)]
            joints.append(("P", xy(P)))
            reach = crank_range(a, b, c, d)
            lo, hi = reach[0] if reach else (0.0, 0.0)
            full = fourbar_motion(a, b, c, d, np.linspace(lo, hi, 721), br, order=0)
            ok = full.ok
            paths.append(("coupler curve of P", [xy(z) for z in full.coupler_point(*point)[0][ok]]))
        return Sketch(
            links=[("crank a", [(0.0, 0.0), xy(A)]), ("coupler b", coupler), ("rocker c", [(d, 0.0), xy(B)])],
            ground_pivots=[("A0", (0.0, 0.0)), ("B0", (d, 0.0))],
            joints=joints,
            paths=paths,
        )

    emit_motion(
        table,
        as_json=as_json,
        plot=plot,
        draw=draw,
        plot_columns=["gamma", "omega_rocker", "alpha_rocker"],
        evaluate=evaluate,
        sketch=sketch,
        title=f"Four-bar a={a:g} b={b:g} c={c:g} d={d:g} branch {br:+d} ({kind.label})",
    )
