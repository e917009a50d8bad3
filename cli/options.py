"""Option definitions shared by several subcommands (one place, one meaning)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import click
import numpy as np

from kinematics.timing import crank_speed

__all__ = [
    "crank_angle_options",
    "crank_angles_deg",
    "fourbar_options",
    "output_options",
    "positive",
    "speed_options",
    "speed_from_options",
    "writable_file",
]


def _stack(*decorators: Callable) -> Callable:
    def apply(f: Callable) -> Callable:
        for dec in reversed(decorators):
            f = dec(f)
        return f

    return apply


def positive(ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
    """Callback: a finite length > 0."""
    if value is not None and not (np.isfinite(value) and value > 0):
        raise click.BadParameter(f"must be a finite number > 0, got {value:g}", ctx, param)
    return value


def finite(ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
    if value is not None and not np.isfinite(value):
        raise click.BadParameter(f"must be a finite number, got {value:g}", ctx, param)
    return value


fourbar_options = _stack(
    click.option("--a", type=float, required=True, callback=positive, help="Crank length A0-A."),
    click.option("--b", type=float, required=True, callback=positive, help="Coupler length A-B."),
    click.option("--c", type=float, required=True, callback=positive, help="Rocker length B0-B."),
    click.option("--d", type=float, required=True, callback=positive, help="Ground length A0-B0."),
    click.option("--branch", type=click.Choice(["1", "-1"]), default="1", show_default=True,
                 help="Assembly branch: 1 puts B left of the line A->B0, -1 right."),
)

crank_angle_options = _stack(
    click.option("--phi", type=float, default=None, callback=finite, help="One crank angle [deg]."),
    click.option("--from", "phi_from", type=float, default=None, callback=finite, help="First crank angle [deg] (default 0)."),
    click.option("--to", "phi_to", type=float, default=None, callback=finite, help="Last crank angle [deg] (default 360, excluded when a full turn)."),
    click.option("--step", "phi_step", type=float, default=None, callback=finite, help="Crank angle step [deg] (default 30)."),
)


def crank_angles_deg(phi: float | None, phi_from: float | None, phi_to: float | None, phi_step: float | None) -> np.ndarray:
    """Crank angles in degrees from ``--phi`` or ``--from/--to/--step`` (default 0..330 by 30).

    ``--to`` is included unless the range is a whole number of turns (its end repeats its start).
    """
    if phi is not None:
        if any(x is not None for x in (phi_from, phi_to, phi_step)):
            raise click.UsageError("give either --phi or --from/--to/--step, not both")
        return np.array([phi])
    start = 0.0 if phi_from is None else phi_from
    stop = start + 360.0 if phi_to is None else phi_to
    step = 30.0 if phi_step is None else phi_step
    if step <= 0:
        raise click.BadParameter(f"--step must be > 0, got {step:g}")
    if stop < start:
        raise click.BadParameter(f"--to ({stop:g}) must not be below --from ({start:g})")
    count = int(np.floor((stop - start) / step + 1e-9)) + 1
    if count > 1_000_000:
        raise click.BadParameter(f"--from/--to/--step give {count} crank angles; at most 1000000")
    angles = start + step * np.arange(count)
    full_turns = (stop - start) > 0 and abs(((stop - start) / 360.0) - round((stop - start) / 360.0)) < 1e-12
    if full_turns and np.isclose(angles[-1], stop):
        angles = angles[:-1]
    return angles


speed_options = _stack(
    click.option("--rpm", type=float, default=None, callback=finite, help="Crank speed [rev/min] (default 60)."),
    click.option("--omega", type=float, default=None, callback=finite, help="Crank speed [rad/s]."),
    click.option("--cw", is_flag=True, help="Crank turns clockwise (default counter-clockwise)."),
    click.option("--alpha", "crank_alpha", type=float, default=0.0, show_default=True, callback=finite,
                 help="Crank angular acceleration [rad/s^2], signed like the speed."),
)


def speed_from_options(rpm: float | None, omega: float | None, cw: bool) -> float:
    """Signed crank speed in rad/s from ``--rpm``/``--omega``/``--cw`` (default 60 rpm)."""
    if rpm is not None and omega is not None:
        raise click.UsageError("give either --rpm or --omega, not both")
    if rpm is None and omega is None:
        rpm = 60.0
    if (rpm is not None and rpm <= 0) or (omega is not None and omega <= 0):
        raise click.BadParameter("crank speed must be > 0 (use --cw for clockwise)")
    return crank_speed(rpm=rpm, omega=omega, clockwise=cw)


def writable_file(*suffixes: str) -> Callable:
    """Callback: a path whose folder exists and whose suffix is one of ``suffixes``."""

    def check(ctx: click.Context, param: click.Parameter, value: str | None) -> Path | None:
        if value is None:
            return None
        path = Path(value)
        if path.suffix.lower() not in suffixes:
            raise click.BadParameter(f"{value!r} must end in {' or '.join(suffixes)}", ctx, param)
        if not path.parent.exists() or not path.parent.is_dir():
            raise click.BadParameter(f"folder {str(path.parent)!r} does not exist", ctx, param)
        if path.exists() and path.is_dir():
            raise click.BadParameter(f"{value!r} is a folder", ctx, param)
        return path

    return check


output_options = _stack(
    click.option("--json", "as_json", is_flag=True, help="Print one JSON document instead of the table."),
    click.option("--plot", type=click.Path(dir_okay=False), callback=writable_file(".png", ".svg"),
                 help="Write the motion diagrams (displacement, velocity, acceleration) to FILE.png|.svg."),
    click.option("--draw", type=click.Path(dir_okay=False), callback=writable_file(".svg", ".png"),
                 help="Draw the mechanism at the first crank angle to FILE.svg."),
    click.option("--units", default="mm", show_default=True, help="Name of the length unit (labels only)."),
)
