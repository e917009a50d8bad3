"""``dwell analyze shaper``: the crank / guide-rod / slider (quick-return shaper) mechanism."""

from __future__ import annotations

from typing import Any

import click
import numpy as np

from cli.analyze.emit import emit_motion
from cli.analyze.slider_crank import BRANCH_HELP, limits_summary, xy
from cli.options import (
    COORDINATE,
    LENGTH,
    crank_angle_options,
    crank_angles_deg,
    output_options,
    speed_from_options,
    speed_options,
)
from kinematics.shaper import check_shaper, shaper_limits, shaper_motion
from kinematics.timing import time_derivatives
from report.drawing import Sketch
from report.motion_table import Column, MotionTable


@click.command("shaper")
@click.option("--crank", "l1", type=LENGTH, required=True, help="Crank length AB (l1).")
@click.option("--rod", "l3", type=LENGTH, required=True, help="Guide rod length CD (l3).")
@click.option("--link", "l4", type=LENGTH, required=True, help="Link length DE (l4).")
@click.option(
    "--height", "h", type=LENGTH, required=True, help="Height h of the crank pivot A above the rod pivot C=(0,-h)."
)
@click.option(
    "--offset",
    "e",
    type=COORDINATE,
    default=0.0,
    show_default=True,
    help="Slider line y = -e (positive: below the crank pivot A).",
)
@click.option("--branch", type=click.Choice(["1", "-1"]), default="1", show_default=True, help=BRANCH_HELP)
@crank_angle_options
@speed_options
@output_options
def shaper(
    l1, l3, l4, h, e, branch, phi, phi_from, phi_to, phi_step, rpm, omega, cw, crank_alpha, as_json, plot, draw, units
):
    """Analyse a quick-return shaper: crank pivot A=(0,0), rod pivot C=(0,-h), slider E=(s5,-e).

    Formulas: docs/cases/classic_mechanisms.md section 1 (s2 block on the rod, phi3 rod,
    phi4 link DE, s5 slider); angles CCW from +x.
    """
    br = int(branch)
    check_shaper(l1, l3, l4, h, e, br)
    w = speed_from_options(rpm, omega, cw)
    angles = crank_angles_deg(phi, phi_from, phi_to, phi_step)
    L = units

    def evaluate(phi_deg: np.ndarray) -> MotionTable:
        m = shaper_motion(l1, l3, l4, h, e, np.radians(phi_deg), br, order=2, on_degenerate="raise")
        block, rod, link, slider = (time_derivatives(d, w, crank_alpha) for d in (m.ds2, m.dphi3, m.dphi4, m.ds5))
        B, D = m.B, m.D
        cols = [
            Column("phi1", "deg", phi_deg, "crank angle"),
            Column("s2", L, m.s2, "block 2 along the guide rod"),
            Column("phi3", "deg", np.degrees(m.phi3), "guide rod angle"),
            Column("phi4", "deg", np.degrees(m.phi4), "link DE angle"),
            Column("s5", L, m.s5, "slider displacement"),
            Column("v2", f"{L}/s", block[0], "block 2 velocity along the rod"),
            Column("omega3", "rad/s", rod[0], "guide rod angular velocity"),
            Column("omega4", "rad/s", link[0], "link DE angular velocity"),
            Column("v5", f"{L}/s", slider[0], "slider velocity"),
            Column("a2", f"{L}/s^2", block[1], "block 2 acceleration along the rod"),
            Column("eps3", "rad/s^2", rod[1], "guide rod angular acceleration"),
            Column("eps4", "rad/s^2", link[1], "link DE angular acceleration"),
            Column("a5", f"{L}/s^2", slider[1], "slider acceleration"),
            Column("Bx", L, B.real),
            Column("By", L, B.imag),
            Column("Dx", L, D.real),
            Column("Dy", L, D.imag),
        ]
        return MotionTable(mechanism, cols, summary)

    mechanism = {
        "type": "shaper",
        "l1": l1,
        "l3": l3,
        "l4": l4,
        "h": h,
        "e": e,
        "branch": br,
        "length_unit": L,
        "crank_speed_rad_s": w,
        "crank_acceleration_rad_s2": crank_alpha,
    }
    lim = shaper_limits(l1, l3, l4, h, e, br)
    summary: dict[str, Any] = {"rod_swing_deg": float(np.degrees(2.0 * np.arcsin(l1 / h)))}
    summary |= limits_summary(lim, "s5", L)
    table = evaluate(angles)

    def sketch() -> Sketch:
        m = shaper_motion(l1, l3, l4, h, e, np.radians(angles[:1]), br, order=0)
        B, C, D, E = (complex(p[0]) for p in (m.B, m.C, m.D, m.E))
        margin = 0.25 * max(lim.stroke, l4)
        return Sketch(
            links=[("crank l1", [(0.0, 0.0), xy(B)]), ("guide rod l3", [xy(C), xy(D)]), ("link l4", [xy(D), xy(E)])],
            ground_pivots=[("A", (0.0, 0.0)), ("C", xy(C))],
            joints=[("B", xy(B)), ("D", xy(D))],
            sliders=[("2", xy(B), float(m.phi3[0])), ("5", xy(E), 0.0)],
            guides=[((lim.s_min - margin, -e), (lim.s_max + margin, -e))],
        )

    emit_motion(
        table,
        as_json=as_json,
        plot=plot,
        draw=draw,
        plot_columns=["s5", "v5", "a5"],
        evaluate=evaluate,
        sketch=sketch,
        title=f"Shaper l1={l1:g} l3={l3:g} l4={l4:g} h={h:g} e={e:g} branch {br:+d}",
    )
