"""``dwell analyze slider-crank``: positions, velocities, accelerations of an offset slider-crank."""

from __future__ import annotations

import math
from typing import Any

import click
import numpy as np

from cli.analyze.emit import emit_motion
from cli.options import (
    ANGLE_DEG,
    COORDINATE,
    LENGTH,
    crank_angle_options,
    crank_angles_deg,
    output_options,
    speed_from_options,
    speed_options,
)
from kinematics.slider_crank import SliderLimits, slider_crank_limits, slider_crank_motion, slider_crank_range
from kinematics.timing import time_derivatives
from report.drawing import Sketch
from report.motion_table import Column, MotionTable, unit_key

BRANCH_HELP = "Assembly branch: 1 puts the slider ahead of the rod's other joint along the guide (cos > 0), -1 behind."


def limits_summary(lim: SliderLimits, slider: str, unit: str) -> dict[str, Any]:
    """The summary entries every slider mechanism shows: limit positions, stroke, time ratio."""
    u = unit_key(unit)
    return {
        "limit_positions": {
            "phi1_max_deg": float(np.degrees(lim.phi_max)),
            f"{slider}_max_{u}": lim.s_max,
            "phi1_min_deg": float(np.degrees(lim.phi_min)),
            f"{slider}_min_{u}": lim.s_min,
        },
        f"stroke_{u}": lim.stroke,
        "time_ratio": lim.time_ratio,
        "reversals_per_turn": lim.reversals,
    }


def xy(z: complex) -> tuple[float, float]:
    """A complex point as the (x, y) pair a :class:`Sketch` wants."""
    return (float(z.real), float(z.imag))


@click.command("slider-crank")
@click.option("--crank", "l1", type=LENGTH, required=True, help="Crank length AB (l1).")
@click.option("--rod", "l2", type=LENGTH, required=True, help="Connecting rod length BC (l2).")
@click.option(
    "--offset",
    "e",
    type=COORDINATE,
    default=0.0,
    show_default=True,
    help="Guide offset e: the guide is y = -e (positive: below the crank pivot A).",
)
@click.option(
    "--guide-angle",
    type=ANGLE_DEG,
    default=0.0,
    show_default=True,
    help="Inclination of the guide [deg]; the offset is then to the right of the guide direction.",
)
@click.option("--branch", type=click.Choice(["1", "-1"]), default="1", show_default=True, help=BRANCH_HELP)
@crank_angle_options
@speed_options
@output_options
def slider_crank(
    l1,
    l2,
    e,
    guide_angle,
    branch,
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
):
    """Analyse an offset slider-crank: crank pivot A=(0,0), slider C=(s3,-e); angles CCW from +x.

    Formulas: docs/cases/classic_mechanisms.md section 2 (phi1 crank, phi2 rod, s3 slider).
    """
    br = int(branch)
    # whole turns off first, exactly (fmod by 360 is exact): in radians, 1e18 degrees would
    # swamp the dead-centre angles added to it
    alpha = float(np.radians(guide_angle if abs(guide_angle) <= 360.0 else math.fmod(guide_angle, 360.0)))
    w = speed_from_options(rpm, omega, cw)
    angles = crank_angles_deg(phi, phi_from, phi_to, phi_step)
    L = units

    def evaluate(phi_deg: np.ndarray) -> MotionTable:
        m = slider_crank_motion(l1, l2, e, np.radians(phi_deg), br, guide_angle=alpha, order=2, on_degenerate="raise")
        rod = time_derivatives(m.dphi2, w, crank_alpha)
        slider = time_derivatives(m.ds3, w, crank_alpha)
        B, C = m.B, m.C
        cols = [
            Column("phi1", "deg", phi_deg, "crank angle"),
            Column("phi2", "deg", np.degrees(m.phi2), "connecting rod angle"),
            Column("s3", L, m.s3, "slider displacement"),
            Column("omega2", "rad/s", rod[0], "rod angular velocity"),
            Column("v3", f"{L}/s", slider[0], "slider velocity"),
            Column("eps2", "rad/s^2", rod[1], "rod angular acceleration"),
            Column("a3", f"{L}/s^2", slider[1], "slider acceleration"),
            Column("Bx", L, B.real),
            Column("By", L, B.imag),
            Column("Cx", L, C.real),
            Column("Cy", L, C.imag),
        ]
        return MotionTable(mechanism, cols, summary)

    mechanism = {
        "type": "slider-crank",
        "l1": l1,
        "l2": l2,
        "e": e,
        "guide_angle_deg": guide_angle,
        "branch": br,
        "length_unit": L,
        "crank_speed_rad_s": w,
        "crank_acceleration_rad_s2": crank_alpha,
    }
    reach = slider_crank_range(l1, l2, e, guide_angle=alpha)
    summary: dict[str, Any] = {
        "full_turn": l1 + abs(e) <= l2,
        "crank_range_deg": [[float(np.degrees(lo)), float(np.degrees(hi))] for lo, hi in reach],
    }
    if summary["full_turn"]:
        summary |= limits_summary(slider_crank_limits(l1, l2, e, br, guide_angle=alpha), "s3", L)
    table = evaluate(angles)

    def sketch() -> Sketch:
        m = slider_crank_motion(l1, l2, e, np.radians(angles[:1]), br, guide_angle=alpha, order=0)
        B, C = complex(m.B[0]), complex(m.C[0])
        along = np.exp(1j * alpha)
        reach_s = l1 + l2
        guide = [xy((s - 1j * e) * along) for s in (-reach_s, reach_s)]
        return Sketch(
            links=[("crank l1", [(0.0, 0.0), xy(B)]), ("rod l2", [xy(B), xy(C)])],
            ground_pivots=[("A", (0.0, 0.0))],
            joints=[("B", xy(B))],
            sliders=[("C", xy(C), alpha)],
            guides=[(guide[0], guide[1])],
        )

    emit_motion(
        table,
        as_json=as_json,
        plot=plot,
        draw=draw,
        plot_columns=["s3", "v3", "a3"],
        evaluate=evaluate,
        sketch=sketch,
        title=f"Slider-crank l1={l1:g} l2={l2:g} e={e:g} guide {guide_angle:g} deg branch {br:+d}",
    )
