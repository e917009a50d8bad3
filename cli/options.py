"""Option definitions shared by several subcommands (one place, one meaning)."""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path

import click
import numpy as np

from kinematics.timing import crank_speed

__all__ = [
    "bounded",
    "crank_angle_options",
    "crank_angles_deg",
    "fourbar_options",
    "output_options",
    "positive",
    "probe_folder",
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


#: Lengths accepted on the command line: the square or product of any two stays a finite,
#: normal float (the closed forms square lengths; 1e308 or 1e-320 would overflow or vanish).
LENGTH_RANGE = (1e-150, 1e150)


def positive(ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
    """Callback: a finite length > 0, within :data:`LENGTH_RANGE`."""
    lo, hi = LENGTH_RANGE
    if value is not None and not (np.isfinite(value) and value > 0):
        raise click.BadParameter(f"must be a finite number > 0, got {value:g}", ctx, param)
    if value is not None and not lo <= value <= hi:
        raise click.BadParameter(f"must be between {lo:g} and {hi:g} (a length), got {value:g}", ctx, param)
    return value


def finite(ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
    if value is not None and not np.isfinite(value):
        raise click.BadParameter(f"must be a finite number, got {value:g}", ctx, param)
    return value


#: Largest input speed (rpm, rad/s, length/s) and acceleration: with lengths up to 1e150 the
#: accelerations (L·ω²) and jerks (L·ω³) of the output stay finite.
MAX_SPEED, MAX_ACCELERATION = 1e50, 1e100


def bounded(limit: float) -> Callable:
    """Callback: a finite number of magnitude at most ``limit``."""

    def check(ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
        finite(ctx, param, value)
        if value is not None and abs(value) > limit:
            raise click.BadParameter(f"must be at most {limit:g} in magnitude, got {value:g}", ctx, param)
        return value

    return check


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
    turns = (stop - start) / 360.0
    full_turns = round(turns) >= 1 and abs(turns - round(turns)) < 1e-12  # (a sliver of a degree is no turn)
    if full_turns and np.isclose(angles[-1], stop):
        angles = angles[:-1]
    return angles


speed_options = _stack(
    click.option("--rpm", type=float, default=None, callback=bounded(MAX_SPEED), help="Crank speed [rev/min] (default 60)."),
    click.option("--omega", type=float, default=None, callback=bounded(MAX_SPEED), help="Crank speed [rad/s]."),
    click.option("--cw", is_flag=True, help="Crank turns clockwise (default counter-clockwise)."),
    click.option("--alpha", "crank_alpha", type=float, default=0.0, show_default=True, callback=bounded(MAX_ACCELERATION),
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
        try:  # fail now, not after the work: open it as the writer will, then leave it as it was
            if path.exists():
                with path.open("ab"):
                    pass
            else:
                with path.open("xb"):
                    pass
                path.unlink()
        except OSError as exc:
            raise click.BadParameter(f"cannot write {value!r}: {exc.strerror}", ctx, param) from None
        return path

    return check


def probe_folder(path: Path, option: str) -> None:
    """Refuse (exit 2, before any work) an output folder that cannot be made or written into.

    Creates what is missing of ``path`` and a temporary file in it, then removes them again:
    the folder is left as it was found.
    """
    from cli.errors import InputError

    made = [p for p in (path, *path.parents) if not p.exists()]  # innermost first
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as exc:
        raise InputError(f"{option}: cannot write into {str(path)!r}: {exc.strerror}") from None
    finally:
        for folder in made:
            try:
                folder.rmdir()
            except OSError:
                break


#: The length unit's name: labels, and the DXF's ``$INSUNITS`` (report.dxf.INSUNITS).
units_option = click.option("--units", default="mm", show_default=True,
                            help="Name of the length unit (labels; mm, cm, m, in, ft … also set the DXF's units).")

output_options = _stack(
    click.option("--json", "as_json", is_flag=True, help="Print one JSON document instead of the table."),
    click.option("--plot", type=click.Path(dir_okay=False), callback=writable_file(".png", ".svg"),
                 help="Write the motion diagrams (displacement, velocity, acceleration) to FILE.png|.svg."),
    click.option("--draw", type=click.Path(dir_okay=False), callback=writable_file(".svg", ".png"),
                 help="Draw the mechanism at the first crank angle to FILE.svg."),
    units_option,
)
