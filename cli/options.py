"""Option definitions shared by several subcommands (one place, one meaning)."""

from __future__ import annotations

import os
import re
import stat
import sys
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import click
import numpy as np

from atlas.sweep import CRANK_STEP_RANGE_DEG, PROPORTION_RANGE, RAYS_RANGE
from cli.errors import InputError
from kinematics.timing import crank_speed

__all__ = [
    "ANGLE_DEG",
    "AUTO",
    "COORDINATE",
    "DEFAULT_DB",
    "LENGTH",
    "SEED",
    "STEP_DEG",
    "BandOrAuto",
    "Bounded",
    "Count",
    "crank_angle_options",
    "crank_angles_deg",
    "check_engine",
    "db_option",
    "engine_options",
    "flag_names",
    "fourbar_options",
    "output_options",
    "probe_folder",
    "request_errors",
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


#: The atlas used when neither ``--db`` nor ``$DWELL_ATLAS`` is given (relative to the cwd).
DEFAULT_DB = "atlas.sqlite"


def db_option(
    *,
    dest: str = "db",
    default: str | None = DEFAULT_DB,
    required: bool = False,
    envvar: str | None = "DWELL_ATLAS",
    help: str = "The atlas: an SQLite file or an SQLAlchemy URL.",
) -> Callable:
    """``--db PATH|URL``, the atlas a command reads or writes, into its parameter ``dest``:
    ``default`` (shown in ``--help``) when neither the option nor ``envvar`` is given, or with
    ``required`` one of them must be (no default)."""
    return click.option(
        "--db",
        dest,
        default=None if required else default,
        required=required,
        show_default=default is not None and not required,
        envvar=envvar,
        show_envvar=envvar is not None,
        metavar="PATH|URL",
        help=help,
    )


#: ``--engine``'s choices: local processes, or a running dask.distributed cluster.
ENGINES = ("local", "dask")


def engine_options(work: str, writer: str) -> Callable:
    """``--engine local|dask`` and ``--scheduler ADDR`` (checked by :func:`check_engine`):
    where ``work`` runs (``shards``, ``the complete search's batches``); ``writer`` says what
    this process does either way."""
    return _stack(
        click.option(
            "--engine",
            type=click.Choice(ENGINES),
            default="local",
            show_default=True,
            help=f"Where {work} are computed: local processes, or a dask.distributed cluster (needs "
            f"--scheduler and the dask extra). {writer}",
        ),
        click.option(
            "--scheduler",
            metavar="ADDR",
            default=None,
            help="Address of a running dask scheduler (tcp://host:8786), with --engine dask.",
        ),
    )


def check_engine(engine: str, scheduler: str | None) -> None:
    """A scheduler exactly with ``--engine dask``: else a usage error (one line, exit 2)."""
    if engine == "dask" and scheduler is None:
        raise click.UsageError("--engine dask needs --scheduler ADDR (a running dask scheduler, e.g. tcp://host:8786)")
    if engine != "dask" and scheduler is not None:
        raise click.UsageError("--scheduler needs --engine dask")


def flag_names(message: str) -> str:
    """``message`` with each field of a request named in backticks (`` `swing_tol` ``, as
    :class:`~synth.query.candidates.Request` names them) as the option that sets it
    (``--swing-tol``): every field is set by the option of its name."""
    return re.sub(r"`([a-z_]+)`", lambda m: "--" + m.group(1).replace("_", "-"), message)


@contextmanager
def request_errors() -> Iterator[None]:
    """A request's ValueError inside the block is the user's error: one line naming the
    options (:func:`flag_names`), exit 2."""
    try:
        yield
    except ValueError as exc:
        raise InputError(flag_names(str(exc))) from None


#: Lengths accepted on the command line: the square or product of any two stays a finite,
#: normal float (the closed forms square lengths; 1e308 or 1e-320 would overflow or vanish).
LENGTH_RANGE = (1e-150, 1e150)


class Bounded(click.FloatRange):
    """A finite float in a range, shown in ``--help`` (click prints the bounds) and checked at
    the command line: ``nan``, ``inf``, subnormal and out-of-range values are one line naming
    the option, its range and what it means (``what``), exit 2.

    One instance per kind of value below (:data:`LENGTH`, :data:`ANGLE_DEG`, …): every numeric
    option takes its range from here, so a kind has one range everywhere."""

    def __init__(
        self, low: float | None, high: float | None, what: str, *, low_open: bool = False, high_open: bool = False
    ) -> None:
        super().__init__(low, high, min_open=low_open, max_open=high_open)
        self.what = what

    def convert(self, value, param, ctx):
        number = click.FLOAT.convert(value, param, ctx)
        if not np.isfinite(number):
            self.fail(f"must be a finite number ({self.what}), got {value!r}", param, ctx)
        try:
            number = super().convert(number, param, ctx)
        except click.BadParameter:
            lo = "" if self.min is None else f"{self.min:g} {'<' if self.min_open else '<='} "
            hi = "" if self.max is None else f" {'<' if self.max_open else '<='} {self.max:g}"
            self.fail(f"must be {lo}x{hi} ({self.what}), got {number:g}", param, ctx)
        if number != 0 and abs(number) < sys.float_info.min:  # subnormal: no precision left
            zero = "" if self.min == 0 and self.min_open else "0 or "
            self.fail(
                f"must be {zero}at least {sys.float_info.min:.3g} in magnitude ({self.what}), got {number:g}",
                param,
                ctx,
            )
        return number


#: The value of an option that takes a number or lets the program search for it (``--band auto``).
AUTO = "auto"


class BandOrAuto(Bounded):
    """An output band in degrees (a :class:`Bounded` number) or ``auto``: the tightest band
    the request can be met at, searched for (``synth.query.band_search``). Anything else is one
    line naming both forms, exit 2."""

    def get_metavar(self, param, ctx=None) -> str:
        return "DEG|auto"

    def convert(self, value, param, ctx):
        if isinstance(value, str) and value.strip().lower() == AUTO:
            return AUTO
        if isinstance(value, str):
            try:
                float(value)
            except ValueError:
                self.fail(f"must be a number of degrees or 'auto' ({self.what}), got {value[:40]!r}", param, ctx)
        return super().convert(value, param, ctx)


class Count(click.IntRange):
    """A whole number in a range (shown in ``--help``); a huge or malformed integer is one line."""

    def __init__(self, low: int, high: int, what: str) -> None:
        super().__init__(low, high)
        self.what = what

    def convert(self, value, param, ctx):
        text = str(value).strip()
        if len(text) > 30:  # '9' * 400: not parsed (Python limits int() to 4300 digits anyway)
            self.fail(
                f"must be a whole number from {self.min} to {self.max} ({self.what}), got {text[:20]}…", param, ctx
            )
        try:
            return super().convert(value, param, ctx)
        except click.BadParameter:
            self.fail(f"must be a whole number from {self.min} to {self.max} ({self.what}), got {text!r}", param, ctx)


#: A length (link, offset magnitude): squares and products of two stay finite, normal floats.
LENGTH = Bounded(*LENGTH_RANGE, "a length")
#: A signed coordinate or offset (your length unit).
COORDINATE = Bounded(-1e150, 1e150, "a coordinate")
#: A crank angle or other angle in degrees: ±100 turns (more is a typing error, and keeps the
#: number of steps of a --from/--to/--step range a small integer).
ANGLE_DEG = Bounded(-36_000.0, 36_000.0, "an angle in degrees, ±100 turns")
#: A step of crank angles (degrees): at least 1e-6° (a million steps per degree at most).
STEP_DEG = Bounded(1e-6, 36_000.0, "a step in degrees")
#: A value of a linkage file's input (degrees for an angle, your unit for a slide) and its step.
INPUT_VALUE = Bounded(-1e12, 1e12, "an angle in degrees or a length")
INPUT_STEP = Bounded(1e-9, 1e12, "a step in degrees or a length")
#: A sweep's proportions (crank = 1), the search's crank step and rays (atlas/sweep.py's ranges).
PROPORTION = Bounded(*PROPORTION_RANGE, "a length in cranks")
SEARCH_STEP_DEG = Bounded(*CRANK_STEP_RANGE_DEG, "a crank step of the search in degrees")
#: An output swing's tolerance, which is also how far two rests' bands must be left between them.
#: The swing a request allows (> 0: the swing is measured by simulation, and an exact one is a
#: no-match found only after the whole refinement's reach has run).
SWING_TOL_DEG = Bounded(0.0, 180.0, "a swing error in degrees, > 0", low_open=True, high_open=True)
#: How far the output leaves the band between two rests (0: any departure splits them).
LEAVE_DEG = Bounded(0.0, 180.0, "a swing in degrees", high_open=True)
RAYS = Count(*RAYS_RANGE, "rays through the pole")
#: A seed of a random generator.
SEED = Count(0, 2**63 - 1, "a seed")


#: Largest input speed (rpm, rad/s, length/s) and acceleration: with lengths up to 1e150 the
#: accelerations (L·ω²) and jerks (L·ω³) of the output stay finite.
MAX_SPEED, MAX_ACCELERATION = 1e50, 1e100
#: Speeds (rpm, rad/s, length/s) and accelerations on the command line (signed).
SPEED = Bounded(-MAX_SPEED, MAX_SPEED, "a speed")
ACCELERATION = Bounded(-MAX_ACCELERATION, MAX_ACCELERATION, "an acceleration")
#: A positive crank speed in rev/min (lists of speeds to compare).
RPM = Bounded(1e-6, MAX_SPEED, "a speed in rev/min")


fourbar_options = _stack(
    click.option("--a", type=LENGTH, required=True, help="Crank length A0-A."),
    click.option("--b", type=LENGTH, required=True, help="Coupler length A-B."),
    click.option("--c", type=LENGTH, required=True, help="Rocker length B0-B."),
    click.option("--d", type=LENGTH, required=True, help="Ground length A0-B0."),
    click.option(
        "--branch",
        type=click.Choice(["1", "-1"]),
        default="1",
        show_default=True,
        help="Assembly branch: 1 puts B left of the line A->B0, -1 right.",
    ),
)

crank_angle_options = _stack(
    click.option("--phi", type=ANGLE_DEG, default=None, help="One crank angle [deg]."),
    click.option("--from", "phi_from", type=ANGLE_DEG, default=None, help="First crank angle [deg] (default 0)."),
    click.option(
        "--to",
        "phi_to",
        type=ANGLE_DEG,
        default=None,
        help="Last crank angle [deg] (default 360, excluded when a full turn).",
    ),
    click.option("--step", "phi_step", type=STEP_DEG, default=None, help="Crank angle step [deg] (default 30)."),
)


def crank_angles_deg(
    phi: float | None, phi_from: float | None, phi_to: float | None, phi_step: float | None
) -> np.ndarray:
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
    steps = (stop - start) / step
    if not steps < 1_000_000:  # checked as a float: a tiny step must not overflow the count
        raise click.BadParameter(f"--from/--to/--step give {steps + 1:.3g} crank angles; at most 1000000")
    count = int(np.floor(steps + 1e-9)) + 1
    angles = start + step * np.arange(count)
    turns = (stop - start) / 360.0
    full_turns = round(turns) >= 1 and abs(turns - round(turns)) < 1e-12  # (a sliver of a degree is no turn)
    if full_turns and np.isclose(angles[-1], stop):
        angles = angles[:-1]
    return angles


speed_options = _stack(
    click.option("--rpm", type=SPEED, default=None, help="Crank speed [rev/min] (default 60)."),
    click.option("--omega", type=SPEED, default=None, help="Crank speed [rad/s]."),
    click.option("--cw", is_flag=True, help="Crank turns clockwise (default counter-clockwise)."),
    click.option(
        "--alpha",
        "crank_alpha",
        type=ACCELERATION,
        default=0.0,
        show_default=True,
        help="Crank angular acceleration [rad/s^2], signed like the speed.",
    ),
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


def special_file(path: Path) -> str | None:
    """What ``path`` is if it exists and is not a regular file or a folder ("a FIFO", "a
    device", "a socket"), else None. Reading or writing such a file blocks or never ends, so
    every user path is checked with ``os.stat`` (which opens nothing) first."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return None


def readable_text(path: Path, option: str, limit: int) -> str:
    """The UTF-8 text of the regular file ``path`` of at most ``limit`` bytes, or one
    :class:`~cli.errors.InputError` naming ``option``: not a regular file, too large,
    unreadable or not UTF-8."""
    from cli.errors import InputError

    kind = special_file(path)
    if kind is not None:
        raise InputError(f"{option} {str(path)!r} is {kind}, not a file")
    try:
        size = path.stat().st_size
        if size > limit:
            raise InputError(f"{option} {str(path)!r} has {size:,} bytes; at most {limit:,}")
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {str(path)!r}: {exc}") from None


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
        kind = special_file(path)
        if kind is not None:  # opening it would block until another process reads
            raise click.BadParameter(f"{value!r} is {kind}, not a file", ctx, param)
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


def _unit_name(ctx, param, value: str | None) -> str | None:
    """``--units`` is a label in every table, drawing and file: plain text, as a linkage file's
    names (a control character would reach the terminal, the TOML and the SVG). The default
    is plain: only a name given is checked (the check's module takes ~80 ms to import, which
    every command with lengths would otherwise pay)."""
    if value is not None and ctx.get_parameter_source(param.name) is not click.core.ParameterSource.DEFAULT:
        from kinematics.assur.linkage_file import plain_text_problem

        problem = plain_text_problem(value)
        if problem:
            raise click.BadParameter(problem, param_hint="--units")
    return value


#: The length unit's name: labels, and the DXF's ``$INSUNITS`` (report.dxf.INSUNITS).
units_option = click.option(
    "--units",
    default="mm",
    show_default=True,
    callback=_unit_name,
    help="Name of the length unit (labels; mm, cm, m, in, ft … also set the DXF's units).",
)

output_options = _stack(
    click.option("--json", "as_json", is_flag=True, help="Print one JSON document instead of the table."),
    click.option(
        "--plot",
        type=click.Path(dir_okay=False),
        callback=writable_file(".png", ".svg"),
        help="Write the motion diagrams (displacement, velocity, acceleration) to FILE.png|.svg.",
    ),
    click.option(
        "--draw",
        type=click.Path(dir_okay=False),
        callback=writable_file(".svg", ".png"),
        help="Draw the mechanism at the first crank angle to FILE.svg.",
    ),
    units_option,
)
