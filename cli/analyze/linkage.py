"""``dwell analyze linkage FILE``: any planar linkage of dyads and class III triads.

The mechanism comes from a description file (``docs/linkage-files.md``). The command prints
every joint's position, velocity and acceleration over a sweep of the first input in one
assembly configuration, or every configuration at each position (``--all-configurations``),
and the limit positions of the output (``--limits``); it draws motion diagrams (``--plot``), the
mechanism (``--draw``) and an animation (``--animate``).
"""

from __future__ import annotations

import json
from pathlib import Path

import click
import numpy as np

from cli.analyze.linkage_limits import cycle_limits, limits_json, limits_text
from cli.options import (
    INPUT_STEP,
    INPUT_VALUE,
    LEAVE_DEG,
    SPEED,
    Bounded,
    output_options,
    readable_text,
    speed_from_options,
    speed_options,
    writable_file,
)
from kinematics.assur import (
    MAX_CONFIGURATIONS,
    Assembly,
    Linkage,
    LinkageMotion,
    Output,
    PrismaticPair,
    assemble,
    configurations,
    decompose,
    linkage_from_text,
    linkage_motion,
    loop_closure,
    output_series,
)
from kinematics.assur.linkage_file import MAX_CHARS
from kinematics.status import AssemblyError, Status
from report.animation import Animation, Frame, write_animation
from report.drawing import Sketch, draw_sketch
from report.escape import terminal
from report.motion_table import Column, MotionTable
from report.plots import plot_motion

#: An output band in degrees (as `dwell query --band` takes it).
BAND_DEG = Bounded(1e-4, 180.0, "an output band in degrees", high_open=True)
#: Default sweep of an angle input [deg] and the number of positions of a slide input's range.
DEFAULT_STEP_DEG = 30.0
DEFAULT_SLIDE_POSITIONS = 13
#: Positions of the dense evaluations behind --plot (1° for a turn) and --animate (2°).
PLOT_POSITIONS = 361
ANIMATION_POSITIONS = 181


@click.command("linkage")
@click.argument("file", type=click.Path(exists=True, dir_okay=False))
@click.option(
    "--input",
    "input_values",
    type=INPUT_VALUE,
    multiple=True,
    metavar="DEG|LEN",
    help="Value of an input ([[inputs]] order; deg for angles). Repeat for several inputs. "
    "With --from/--to/--step the first input sweeps and --input gives the others.",
)
@click.option(
    "--from", "x_from", type=INPUT_VALUE, default=None, help="First value of the first input [deg or length]."
)
@click.option("--to", "x_to", type=INPUT_VALUE, default=None, help="Last value of the first input [deg or length].")
@click.option(
    "--step",
    "x_step",
    type=INPUT_STEP,
    default=None,
    help="Step of the first input (default 30 deg, or 1/12 of a slide's range).",
)
@click.option(
    "--configuration",
    type=click.IntRange(1, MAX_CONFIGURATIONS),
    default=None,
    help="Assembly configuration to follow, numbered as --all-configurations lists them at the first position "
    "(default: the file's 'configuration', else 1).",
)
@click.option(
    "--all-configurations",
    "all_configurations",
    is_flag=True,
    help="List every assembly configuration at each position.",
)
@click.option("--limits", is_flag=True, help="Find the limit positions of the output (where its velocity vanishes).")
@click.option(
    "--output",
    "output_name",
    default=None,
    metavar="NAME",
    help="Output for --limits and --plot: a link (its angle) or a prismatic pair (its slide). Default: [output] of the file.",
)
@click.option(
    "--band",
    type=BAND_DEG,
    default=None,
    metavar="DEG",
    help="With --limits, also the dwells: crank intervals on which the output angle stays within a band "
    "this wide (default: the file's [output] band).",
)
@click.option(
    "--dwells",
    type=click.IntRange(1, 2),
    default=None,
    help="Dwells per turn to find with --band: 1, or 2 (the two longest) (default: the file's, else 1).",
)
@click.option(
    "--leave",
    type=LEAVE_DEG,
    default=None,
    metavar="DEG",
    help="With --dwells 2: how far the output must leave the band between two rests for them to count as "
    "two, as dwell query's --swing-tol (default: the file's [output] leave, else 0.5).",
)
@speed_options
@click.option(
    "--speed",
    "slide_speed",
    type=SPEED,
    default=1.0,
    show_default=True,
    help="Speed of a slide input [length/s] (angle inputs use --rpm/--omega).",
)
@output_options
@click.option(
    "--animate",
    type=click.Path(dir_okay=False),
    callback=writable_file(".html", ".svg"),
    help="Write an animation over the input range to FILE.html (with controls) or FILE.svg.",
)
@click.pass_context
def linkage(
    ctx,
    file,
    input_values,
    x_from,
    x_to,
    x_step,
    configuration,
    all_configurations,
    limits,
    output_name,
    band,
    dwells,
    leave,
    rpm,
    omega,
    cw,
    crank_alpha,
    slide_speed,
    as_json,
    plot,
    draw,
    units,
    animate,
):
    """Analyse the planar linkage described in FILE (TOML, or JSON if it ends in .json)."""
    path = Path(file)
    text = readable_text(path, "FILE", 4 * MAX_CHARS)  # UTF-8: up to 4 bytes a character
    try:
        mech = linkage_from_text(text, "json" if path.suffix.lower() == ".json" else "toml")
        dec = decompose(mech)
    except AssemblyError as exc:
        raise AssemblyError(f"{file}: {exc}") from None
    if ctx.get_parameter_source("units") == click.core.ParameterSource.DEFAULT:
        units = mech.units
    sweep_given = any(v is not None for v in (x_from, x_to, x_step))
    inputs = _input_grid(mech, input_values, x_from, x_to, x_step, sweep_given)
    first = mech.inputs[0] if mech.inputs else None
    rate = slide_speed if first is not None and first.kind == "slide" else speed_from_options(rpm, omega, cw)
    accel = 0.0 if first is not None and first.kind == "slide" else crank_alpha
    k = len(mech.inputs)
    rates = np.eye(1, k)[0] * rate if k else np.zeros(0)
    accels = np.eye(1, k)[0] * accel if k else np.zeros(0)
    output = _pick_output(mech, output_name) if (limits or plot is not None) else None
    groups = [g.describe(mech, dec) for g in dec.groups]
    found = configurations(mech, inputs[0], decomposition=dec)
    if not found:
        raise AssemblyError(f"{mech.name}: cannot assemble at {_inputs_text(mech, inputs[0])}")
    mechanism = {
        "name": mech.name,
        "file": str(file),
        "length_unit": units,
        "dof": mech.dof,
        "inputs": [_input_info(mech, i) for i in range(k)],
        "groups": groups,
        "configurations_at_first_position": len(found),
        # True when the listing stopped at MAX_CONFIGURATIONS (a chain of n dyads has 2^n)
        "configurations_capped": len(found) >= MAX_CONFIGURATIONS,
    }

    if all_configurations:
        if limits or plot is not None or draw is not None or animate is not None:
            raise click.UsageError(
                "--limits, --plot, --draw and --animate follow one configuration; leave out --all-configurations"
            )
        if len(found) >= MAX_CONFIGURATIONS:
            raise click.UsageError(
                f"{mech.name} has more than {MAX_CONFIGURATIONS} assembly configurations at "
                f"{_inputs_text(mech, inputs[0])}: --all-configurations lists at most "
                f"{MAX_CONFIGURATIONS}; follow one with --configuration N"
            )
        table = _configurations_table(mech, dec, inputs, units, mechanism)
        _print(table, as_json, f"{mech.name}: every assembly configuration", key="configurations")
        return

    configuration, source, start = configuration_start(mech, dec, inputs, found, configuration, file)
    asm = assemble(mech, inputs, start, decomposition=dec)
    _require_assembled(mech, asm, configuration)
    motion = linkage_motion(mech, asm, rates, accels)
    mechanism.update(
        configuration=configuration,
        configuration_from=source,
        choice=list(start.choice),
        input_speed=rate,
        input_acceleration=accel,
    )
    summary: dict = {
        "loop_closure_max": float(loop_closure(mech, asm).max()),
        "singular_positions": [_input_value(mech, x) for x in inputs[motion.status & Status.TOGGLE != 0, 0]]
        if k
        else [],
    }
    lim = None
    if limits:
        own = output_name is None and mech.output is not None  # the file's band is its output's
        lim = cycle_limits(
            mech,
            dec,
            start,
            output,
            inputs,
            x_from,
            x_to,
            np.radians(band) if band is not None else (mech.output.band if own else None),
            dwells or (mech.output.dwells if own else 1),
            np.radians(leave) if leave is not None else (mech.output.leave if own else None),
        )
        summary["limits"] = limits_json(mech, lim)
    table = _motion_table(mech, motion, units, mechanism, summary)

    dense = anim = drawing = None
    if plot is not None or animate is not None or draw is not None:
        fine = _dense(mech, dec, start, inputs, sweep_given, PLOT_POSITIONS)
        if plot is not None:
            dense = _output_table(mech, linkage_motion(mech, fine, rates, accels), output, units)
        if animate is not None:
            anim = _animation(
                mech, fine.rows(slice(None, None, max(1, (PLOT_POSITIONS - 1) // (ANIMATION_POSITIONS - 1))))
            )
        if draw is not None:
            drawing = _sketch(mech, asm.at(0), fine)

    title = f"{mech.name} (configuration {configuration})"
    _print(table, as_json, title)
    if lim is not None and not as_json:
        click.echo("")
        click.echo("\n".join(map(terminal, limits_text(mech, lim, units).split("\n"))))
    if dense is not None:
        plot_motion(dense, [c.name for c in dense.columns[1:]], plot, title=title)
        click.echo(f"wrote {plot}", err=True)
    if drawing is not None:
        draw_sketch(drawing, draw, title=title)
        click.echo(f"wrote {draw}", err=True)
    if anim is not None:
        write_animation(anim, animate)
        click.echo(f"wrote {animate}", err=True)


# -- inputs ---------------------------------------------------------------------------------


def _input_grid(mech: Linkage, values, x_from, x_to, x_step, sweep_given) -> np.ndarray:
    """Input positions (M × k) in internal units (rad, length)."""
    k = len(mech.inputs)
    base = np.array([i.value for i in mech.inputs], float)
    user = [_to_internal(mech, i, v) for i, v in enumerate(values, start=1 if sweep_given else 0)]
    if len(user) > (k - 1 if sweep_given else k):
        raise click.BadParameter(
            f"{len(values)} --input value(s) given but the linkage has {k} input(s)"
            + (" and the first one sweeps" if sweep_given else ""),
            param_hint="--input",
        )
    offset = 1 if sweep_given else 0
    base[offset : offset + len(user)] = user
    if k == 0:
        if sweep_given:
            raise click.UsageError("the linkage has no input to sweep")
        return np.zeros((1, 0))
    if values and not sweep_given:
        return base[None, :]
    inp = mech.inputs[0]
    angle = inp.kind == "angle"
    if angle:
        lo_d, hi_d = np.degrees(inp.sweep) if inp.sweep else (None, None)
        start = x_from if x_from is not None else (lo_d if lo_d is not None else 0.0)
        stop = x_to if x_to is not None else (hi_d if hi_d is not None else start + 360.0)
        step = x_step if x_step is not None else (DEFAULT_STEP_DEG if inp.sweep is None else (stop - start) / 12)
    else:
        lo, hi = inp.sweep if inp.sweep else (None, None)
        start = x_from if x_from is not None else lo
        stop = x_to if x_to is not None else hi
        if start is None or stop is None:
            if sweep_given:
                raise click.UsageError("a slide input sweeps only with --from and --to (or a 'range' in the file)")
            return base[None, :]
        step = x_step if x_step is not None else (stop - start) / (DEFAULT_SLIDE_POSITIONS - 1)
    if step <= 0:
        raise click.BadParameter(f"--step must be > 0, got {step:g}", param_hint="--step")
    if stop < start:
        raise click.BadParameter(f"--to ({stop:g}) must not be below --from ({start:g})", param_hint="--to")
    steps = (stop - start) / step if stop > start else 0.0
    if not steps < 100_000:  # checked as a float: a tiny step must not overflow the count
        raise click.BadParameter(f"--from/--to/--step give {steps:.3g} positions; at most 100000", param_hint="--step")
    count = int(np.floor(steps + 1e-9)) + 1
    grid = start + step * np.arange(count)
    turns = (stop - start) / 360.0
    if angle and round(turns) >= 1 and abs(turns - round(turns)) < 1e-12 and np.isclose(grid[-1], stop):
        grid = grid[:-1]  # a whole turn: the end repeats the start
    out = np.repeat(base[None, :], grid.size, axis=0)
    out[:, 0] = np.radians(grid) if angle else grid
    return out


def _to_internal(mech: Linkage, i: int, value: float) -> float:
    if i >= len(mech.inputs):
        return value
    return float(np.radians(value)) if mech.inputs[i].kind == "angle" else value


def _input_value(mech: Linkage, x: float, i: int = 0) -> float:
    return float(np.degrees(x)) if mech.inputs[i].kind == "angle" else float(x)


def _typed_degrees(x: np.ndarray) -> np.ndarray:
    """Degrees of input angles the user typed in degrees, without the radian round trip's last bit."""
    d = np.degrees(x)
    r = np.round(d, 9)
    return np.where(np.abs(d - r) < 1e-9, r, d)


def _input_info(mech: Linkage, i: int) -> dict:
    inp = mech.inputs[i]
    pair = mech.pairs[inp.pair]
    info = {
        "joint": pair.joint,
        "kind": inp.kind,
        "link": mech.links[inp.link].name,
        "relative_to": mech.links[inp.relative_to].name,
    }
    return info


def _inputs_text(mech: Linkage, row) -> str:
    parts = []
    for i, x in enumerate(np.ravel(row)):
        unit = "deg" if mech.inputs[i].kind == "angle" else mech.units
        parts.append(f"input {mech.pairs[mech.inputs[i].pair].joint} = {_input_value(mech, x, i):g} {unit}")
    return ", ".join(parts) or "its only position"


def configuration_start(
    mech: Linkage, dec, inputs: np.ndarray, found: list[Assembly], option: int | None, file: str
) -> tuple[int, str, Assembly]:
    """The configuration to follow, where its number came from, and its pose at the first
    position: ``--configuration`` (numbered at the first position), else the file's
    ``configuration`` (numbered at the inputs' ``value``, then followed to the first
    position), else 1."""
    if option is not None or mech.configuration is None:
        number, source = (option, "option") if option is not None else (1, "default")
        if number > len(found):
            raise AssemblyError(
                f"{mech.name}: configuration {number} does not exist at "
                f"{_inputs_text(mech, inputs[0])} (there are {len(found)}; see --all-configurations)"
            )
        return number, source, found[number - 1]
    number = mech.configuration
    anchor = np.array([[i.value for i in mech.inputs]], float).reshape(1, len(mech.inputs))
    listed = found if np.array_equal(anchor, inputs[:1]) else configurations(mech, anchor[0], decomposition=dec)
    if number > len(listed):
        raise AssemblyError(
            f"{file}: 'configuration' is {number} but {mech.name} has {len(listed)} assembly "
            f"configuration(s) at {_inputs_text(mech, anchor[0])} (see --all-configurations)"
        )
    start = listed[number - 1]
    if not np.array_equal(anchor, inputs[:1]):
        start = assemble(mech, inputs[:1], start, decomposition=dec)
        if np.any(start.status & Status.NOT_ASSEMBLABLE):
            raise AssemblyError(
                f"{mech.name}: configuration {number} of the file (numbered at "
                f"{_inputs_text(mech, anchor[0])}) does not reach {_inputs_text(mech, inputs[0])}"
            )
    return number, "file", start


def _require_assembled(mech: Linkage, asm: Assembly, configuration: int) -> None:
    bad = (asm.status & Status.NOT_ASSEMBLABLE) != 0
    if not np.any(bad):
        return
    i = int(np.flatnonzero(bad)[0])
    reach = ""
    if i > 0:
        reach = f" (it follows the sweep only up to {_inputs_text(mech, asm.inputs[i - 1])})"
    raise AssemblyError(
        f"{mech.name}: configuration {configuration} cannot assemble at "
        f"{_inputs_text(mech, asm.inputs[i])}{reach}; {int(bad.sum())} position(s) affected"
    )


def _pick_output(mech: Linkage, name: str | None) -> Output:
    """The output named on the command line, the file's [output], or a guess (see docs)."""
    if name is not None:
        for i, link in enumerate(mech.links[1:], start=1):
            if link.name == name:
                return Output("angle", i, name)
        for i, pair in enumerate(mech.pairs):
            if isinstance(pair, PrismaticPair) and pair.joint == name:
                return Output("slide", i, name)
        raise click.BadParameter(f"no link or prismatic pair named {name!r}", param_hint="--output")
    if mech.output is not None:
        return mech.output
    driven = {i.pair for i in mech.inputs}
    inputs = {i.link for i in mech.inputs}
    for i in reversed(range(len(mech.pairs))):
        pair = mech.pairs[i]
        if i in driven or 0 not in pair.links:
            continue
        if isinstance(pair, PrismaticPair):
            return Output("slide", i, pair.joint)
        link = pair.links[1] if pair.links[0] == 0 else pair.links[0]
        if link not in inputs:
            return Output("angle", link, mech.links[link].name)
    last = len(mech.links) - 1
    return Output("angle", last, mech.links[last].name)


# -- tables -------------------------------------------------------------------------------------


def _pose_columns(mech: Linkage, asm: Assembly, s: np.ndarray, units: str) -> list[Column]:
    cols = [
        Column(f"theta_{link.name}", "deg", np.degrees(asm.theta[:, i]), f"angle of {link.name}")
        for i, link in enumerate(mech.links)
        if i
    ]
    prism = [p for p in mech.pairs if isinstance(p, PrismaticPair)]
    cols += [Column(f"s_{p.joint}", units, s[:, c], f"slide {p.joint}") for c, p in enumerate(prism)]
    for name, link, p in mech.moving_points():
        z = asm.point(link, p)
        cols += [Column(f"{name}x", units, z.real), Column(f"{name}y", units, z.imag)]
    return cols


def _input_columns(mech: Linkage, inputs: np.ndarray, units: str) -> list[Column]:
    cols = []
    for i, inp in enumerate(mech.inputs):
        name = "input" if i == 0 else f"input{i + 1}"
        unit = "deg" if inp.kind == "angle" else units
        vals = _typed_degrees(inputs[:, i]) if inp.kind == "angle" else inputs[:, i]
        cols.append(Column(name, unit, vals, f"input at joint {mech.pairs[inp.pair].joint}"))
    return cols


def _motion_table(mech: Linkage, motion: LinkageMotion, units: str, mechanism: dict, summary: dict) -> MotionTable:
    asm = motion.assembly
    cols = _input_columns(mech, asm.inputs, units) or [Column("position", "", np.arange(1, asm.r.shape[0] + 1.0))]
    cols += _pose_columns(mech, asm, motion.s, units)
    singular = (motion.status & Status.TOGGLE) != 0
    shown = lambda v: np.where(singular, np.nan, v)  # noqa: E731 - display only: "-" in text, null in JSON
    t_unit = "s"
    for i, link in enumerate(mech.links):
        if i:
            cols += [
                Column(
                    f"omega_{link.name}", f"rad/{t_unit}", shown(motion.omega[:, i]), f"angular velocity of {link.name}"
                ),
                Column(
                    f"alpha_{link.name}",
                    f"rad/{t_unit}^2",
                    shown(motion.alpha[:, i]),
                    f"angular acceleration of {link.name}",
                ),
            ]
    prism = [p for p in mech.pairs if isinstance(p, PrismaticPair)]
    for c, p in enumerate(prism):
        cols += [
            Column(f"v_{p.joint}", f"{units}/s", shown(motion.ds[:, c]), f"slide velocity {p.joint}"),
            Column(f"a_{p.joint}", f"{units}/s^2", shown(motion.dds[:, c]), f"slide acceleration {p.joint}"),
        ]
    for name, link, p in mech.moving_points():
        _, v, a = motion.point(link, p)
        cols += [
            Column(f"v{name}x", f"{units}/s", shown(v.real)),
            Column(f"v{name}y", f"{units}/s", shown(v.imag)),
            Column(f"a{name}x", f"{units}/s^2", shown(a.real)),
            Column(f"a{name}y", f"{units}/s^2", shown(a.imag)),
        ]
    return MotionTable(mechanism, cols, summary)


def _configurations_table(mech: Linkage, dec, inputs: np.ndarray, units: str, mechanism: dict) -> MotionTable:
    rows: list[Assembly] = []
    numbers: list[int] = []
    for row in inputs:
        found = configurations(mech, row, decomposition=dec)
        rows += found
        numbers += list(range(1, len(found) + 1))
    if not rows:
        raise AssemblyError(f"{mech.name}: cannot assemble at any of the {len(inputs)} position(s)")
    cat = lambda name: np.concatenate([getattr(a, name) for a in rows])  # noqa: E731
    asm = Assembly(cat("inputs"), cat("r"), cat("e"), cat("status"), ())
    prism = [p for p in mech.pairs if isinstance(p, PrismaticPair)]
    s = np.zeros((len(rows), len(prism)))
    for c, p in enumerate(prism):
        U = asm.e[:, p.guide] * p.direction
        s[:, c] = (np.conj(U) * (asm.point(p.block, p.block_point) - asm.point(p.guide, p.through))).real
    cols = _input_columns(mech, asm.inputs, units)
    cols.append(Column("configuration", "", np.asarray(numbers, float)))
    for g, group in enumerate(dec.groups):
        label = "branch" if group.is_dyad else "root"
        cols.append(
            Column(
                f"{label}{g + 1}",
                "",
                np.array([a.choice[g] for a in rows], float),
                f"group {g + 1}: {mechanism['groups'][g]}",
            )
        )
    cols += _pose_columns(mech, asm, s, units)
    cols.append(Column("loop_closure", units, loop_closure(mech, asm), "largest pair violation"))
    return MotionTable(mechanism, cols, {"configurations": len(rows)})


def _print(table: MotionTable, as_json: bool, title: str, key: str = "positions") -> None:
    if as_json:
        doc = table.to_json()
        doc = {"mechanism": doc["mechanism"], key: doc["positions"], "summary": doc["summary"]}
        click.echo(json.dumps(doc, indent=1, allow_nan=False))
        return
    click.echo(terminal(title))  # names were refused with control characters; shown escaped anyway
    for k, v in table.mechanism.items():
        click.echo(f"  {k}: {terminal(v)}")
    lead = [c for c in table.columns if c.name.startswith(("input", "position", "configuration", "branch", "root"))]
    rest = [c for c in table.columns if c not in lead]
    blocks = {
        "positions": [c for c in rest if not c.unit.endswith(("/s", "/s^2"))],
        "velocities": [c for c in rest if c.unit.endswith("/s")],
        "accelerations": [c for c in rest if c.unit.endswith("/s^2")],
    }
    for name, cols in blocks.items():
        if cols:
            click.echo(f"\n{name}:")
            click.echo("\n".join(map(terminal, MotionTable(table.mechanism, lead + cols).to_text().split("\n"))))
    if table.summary:
        click.echo("")
        for k, v in table.summary.items():
            if k != "limits":
                click.echo(f"{k}: {v}")


# -- dense evaluations: plot, drawing, animation -------------------------------------------------


def _dense(mech: Linkage, dec, start: Assembly, inputs: np.ndarray, sweep_given: bool, count: int) -> Assembly:
    """The configuration on a fine grid of the first input: a whole turn if it makes one (and
    no sweep was asked for), else the sweep's range or the file's; positions that do not
    assemble are left out."""
    if not mech.inputs:
        return assemble(mech, inputs, start, decomposition=dec)
    first = mech.inputs[0]
    lo, hi = float(inputs[0, 0]), float(inputs[-1, 0])
    grid = np.repeat(inputs[:1], count, axis=0)
    if first.kind == "angle" and not sweep_given:
        grid[:, 0] = lo + np.linspace(0, 2 * np.pi, count)
        turn = assemble(mech, grid, start, decomposition=dec)
        if not np.any(turn.status & Status.NOT_ASSEMBLABLE):
            return turn
        if first.sweep is not None:
            lo, hi = first.sweep
    if hi <= lo and first.sweep is not None:
        lo, hi = first.sweep
    if hi <= lo:
        return assemble(mech, inputs[:1], start, decomposition=dec)
    grid[:, 0] = np.linspace(lo, hi, count)
    fine = assemble(mech, grid, start, decomposition=dec)
    ok = (fine.status & Status.NOT_ASSEMBLABLE) == 0
    return fine.rows(ok) if np.any(ok) else assemble(mech, inputs[:1], start, decomposition=dec)


def _output_table(mech: Linkage, motion: LinkageMotion, output: Output, units: str) -> MotionTable:
    y, dy, ddy = output_series(mech, motion, output)
    # time derivatives: the motion was computed with the actual rates
    angle = output.kind == "angle"
    u = "deg" if angle else units
    conv = np.degrees if angle else (lambda v: v)  # noqa: E731
    singular = (motion.status & Status.TOGGLE) != 0
    cols = _input_columns(mech, motion.assembly.inputs, units)[:1]
    cols += [
        Column("y", u, conv(y), f"{output.name} {'angle' if angle else 'slide'}"),
        Column("dy", "rad/s" if angle else f"{units}/s", np.where(singular, np.nan, dy), "velocity"),
        Column("ddy", "rad/s^2" if angle else f"{units}/s^2", np.where(singular, np.nan, ddy), "acceleration"),
    ]
    return MotionTable({}, cols)


def _outline(mech: Linkage, asm: Assembly, row: int) -> tuple[list[list[tuple[float, float]]], list[str]]:
    """Each moving link as a polyline through its points (a closed polygon for 3+ points)."""
    polys, labels = [], []
    for i, link in enumerate(mech.links):
        if not i:
            continue
        local = list(link.points.values())
        for pair in mech.pairs:  # a guide without points is drawn along its line, past the block
            if isinstance(pair, PrismaticPair) and pair.guide == i and len(local) < 2:
                block = asm.point(pair.block, pair.block_point)[row]
                s = (
                    np.conj(pair.direction) * np.conj(asm.e[row, i]) * (block - asm.r[row, i])
                    - np.conj(pair.direction) * pair.through
                ).real
                reach = s + np.copysign(0.15 * mech.length_scale, s)
                local += [pair.through, pair.through + pair.direction * reach]
        if not local:
            local = [0j]
        if len(local) > 2:  # a plate: its points around their centroid
            centre = np.mean(local)
            local = sorted(local, key=lambda p: np.angle(p - centre))
        z = asm.r[row, i] + asm.e[row, i] * np.asarray(local)
        pts = [(float(p.real), float(p.imag)) for p in z]
        if len(pts) > 2:
            pts.append(pts[0])
        polys.append(pts)
        labels.append(link.name)
    return polys, labels


def _blocks(
    mech: Linkage, asm: Assembly, row: int
) -> list[tuple[str, tuple[float, float], float, list[tuple[float, float]]]]:
    size = 0.04 * mech.length_scale
    out = []
    for pair in mech.pairs:
        if isinstance(pair, PrismaticPair):
            c = complex(asm.point(pair.block, pair.block_point)[row])
            U = complex(asm.e[row, pair.guide] * pair.direction)
            corners = [
                c + U * complex(dx, dy)
                for dx, dy in ((-1.5 * size, -size), (1.5 * size, -size), (1.5 * size, size), (-1.5 * size, size))
            ]
            out.append(
                (
                    pair.joint,
                    (c.real, c.imag),
                    float(np.angle(U)),
                    [(z.real, z.imag) for z in corners] + [(corners[0].real, corners[0].imag)],
                )
            )
    return out


def _guides(mech: Linkage, dense: Assembly) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """Fixed guide lines, long enough for the block's travel."""
    out = []
    for pair in mech.pairs:
        if isinstance(pair, PrismaticPair) and pair.guide == 0:
            c = dense.point(pair.block, pair.block_point)
            s = (np.conj(pair.direction) * (c - pair.through)).real
            lo, hi = float(s.min()), float(s.max())
            pad = 0.15 * max(hi - lo, 0.2 * mech.length_scale)
            a, b = pair.through + (lo - pad) * pair.direction, pair.through + (hi + pad) * pair.direction
            out.append(((a.real, a.imag), (b.real, b.imag)))
    return out


def _tracer_paths(mech: Linkage, dense: Assembly) -> list[tuple[str, list[tuple[float, float]]]]:
    shared = {}
    for link in mech.links:
        for name in link.points:
            shared[name] = shared.get(name, 0) + 1
    out = []
    for name, link, p in mech.moving_points():
        if shared[name] == 1 and dense.r.shape[0] > 1:
            z = dense.point(link, p)[(dense.status & Status.NOT_ASSEMBLABLE) == 0]
            out.append((f"path of {name}", [(float(w.real), float(w.imag)) for w in z]))
    return out


def _sketch(mech: Linkage, asm: Assembly, dense: Assembly) -> Sketch:
    polys, labels = _outline(mech, asm, 0)
    joints = []
    for name, link, p in mech.moving_points():
        z = complex(asm.point(link, p)[0])
        joints.append((name, (z.real, z.imag)))
    ground = [(name, (p.real, p.imag)) for name, p in mech.links[0].points.items()]
    blocks = _blocks(mech, asm, 0)
    return Sketch(
        links=list(zip(labels, polys)),
        ground_pivots=ground,
        joints=joints,
        sliders=[(name, centre, angle) for name, centre, angle, _ in blocks],
        guides=_guides(mech, dense),
        paths=_tracer_paths(mech, dense),
    )


def _animation(mech: Linkage, asm: Assembly) -> Animation:
    frames = []
    points = mech.moving_points()
    for row in range(asm.r.shape[0]):
        polys, labels = _outline(mech, asm, row)
        joints = [(float(z.real), float(z.imag)) for z in (complex(asm.point(link, p)[row]) for _, link, p in points)]
        blocks = [corners for *_, corners in _blocks(mech, asm, row)]
        caption = _inputs_text(mech, asm.inputs[row]) if mech.inputs else ""
        frames.append(Frame(polys, joints, blocks, caption))
    ground = [(name, (p.real, p.imag)) for name, p in mech.links[0].points.items()]
    return Animation(
        frames,
        labels,
        ground,
        _guides(mech, asm),
        [path for _, path in _tracer_paths(mech, asm)],
        title=mech.name,
        seconds=max(2.0, 0.04 * len(frames)),
    )
