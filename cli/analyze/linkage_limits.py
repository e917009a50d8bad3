"""``dwell analyze linkage --limits``: what a designer checks about a reciprocating output over
its cycle — limit positions, swing (or stroke) and time ratio; the smallest transmission angle
of every RRR dyad; and, given an output band, the dwells: the longest crank interval(s) on which
the output stays within the band.

The dwells are measured as ``dwell query`` measures a six-bar's (:func:`synth.mechanism.output_range.dwell_intervals`
on the query's 0.5° grid, ends refined on the exact path), but on the output of the Assur-group
solver (:func:`kinematics.assur.output_at`), so that a report's linkage file reproduces the
candidate's dwell ends (to well under 0.01°) from an independent solution of the mechanism.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from kinematics.assur import (
    Assembly,
    Decomposition,
    Linkage,
    Output,
    OutputLimits,
    TransmissionMinimum,
    limit_positions,
    output_at,
    transmission_minima,
)
from kinematics.status import AssemblyError

#: Crank samples of the dwell search: the query's grid (synth.mechanism.figures' default), so that a
#: candidate's dwell ends are found again by the same refinement from the same samples.
DWELL_SAMPLES = 720


@dataclass(frozen=True, slots=True)
class Rest:
    """One dwell of the output: crank interval [start, end] (deg, each in [0, 360); end < start
    when it passes 0), its length (deg) and the output's rest angle, the middle of its band (deg)."""

    start: float
    end: float
    length: float
    rest: float


@dataclass(frozen=True, slots=True)
class CycleLimits:
    """Everything ``--limits`` reports (angles in radians, except the :class:`Rest` items)."""

    limits: OutputLimits
    transmission: tuple[TransmissionMinimum, ...]
    band: float | None
    dwells: tuple[Rest, ...] | None
    #: why the dwells were not measured although a band was given (None: measured or no band)
    no_dwells: str | None = None
    #: two dwells: how far the output had to leave the band between them (rad); else None
    leave: float | None = None


def cycle_limits(
    mech: Linkage,
    dec: Decomposition,
    start: Assembly,
    output: Output,
    inputs: np.ndarray,
    x_from: float | None,
    x_to: float | None,
    band: float | None,
    dwells: int,
    leave: float | None = None,
) -> CycleLimits:
    """Limit positions over a full turn of an angle input (else over the sweep's range), the
    RRR dyads' smallest transmission angles over the same range, and the dwells within
    ``band`` (rad) when the output is an angle and the input turns fully; two dwells are two
    rests when the output leaves the band by ``leave`` (rad; None: the dwell finder's default)
    between them."""
    first = mech.inputs[0] if mech.inputs else None
    if first is None:
        raise AssemblyError("--limits needs an input to vary")
    if first.kind == "angle" and x_from is None and x_to is None and first.sweep is None:
        try:
            lim = limit_positions(mech, start, output)
        except AssemblyError as exc:
            raise AssemblyError(f"{exc}; give --from/--to where it assembles") from None
        lo, hi = float(start.inputs[0, 0]), float(start.inputs[0, 0]) + 2 * math.pi
    else:
        lo = float(inputs[0, 0])
        hi = float(inputs[-1, 0])
        if x_to is not None:
            hi = float(np.radians(x_to)) if first.kind == "angle" else float(x_to)
        lim = limit_positions(mech, start, output, first=lo, last=hi)
    transmission = tuple(transmission_minima(mech, start, lo, hi, decomposition=dec))
    found, why = None, None
    if band is not None:
        if output.kind != "angle":
            why = "the output is a slide (a band is an angle)"
        elif not lim.full_turn:
            why = "the input does not make a full turn"
        else:
            found = rests([(mech, dec, start, output)], band, dwells, leave)[0]
    if band is not None and dwells == 2 and leave is None:
        from synth.mechanism.output_range import REST_LEAVE  # numba: imported when asked for

        leave = REST_LEAVE
    return CycleLimits(lim, transmission, band, found, why, leave if band is not None and dwells == 2 else None)


def rests(
    items: Sequence[tuple[Linkage, Decomposition, Assembly, Output]],
    band: float,
    count: int,
    leave: float | None = None,
) -> list[tuple[Rest, ...]]:
    """Per item (a linkage, its decomposition, the configuration's start pose and an angle
    output), the ``count`` longest disjoint crank intervals of one turn from the start on
    which the output stays within ``band`` (rad), two of them separated by ``leave`` (rad;
    None: :data:`~synth.mechanism.output_range.REST_LEAVE`) of output outside both bands. One
    dwell search for all items (the exact output of each row evaluated by its own solver)."""
    from synth.mechanism.output_range import (  # numba: imported when asked for
        REST_LEAVE,
        crank_degrees,
        dwell_intervals,
    )
    from synth.mechanism.sixbar import crank_grid

    if not items:
        return []
    x0 = {float(start.inputs[0, 0]) for _, _, start, _ in items}
    if len(x0) != 1:
        raise ValueError("the items' turns must start at the same input angle")
    phi = crank_grid(DWELL_SAMPLES, x0.pop())
    exact = [output_at(mech, start, output, decomposition=dec) for mech, dec, start, output in items]
    # unwrapped along the turn; ψ′ is left out: it would only pick the 2π branch of the step
    # that closes the turn, which a 0.5° step of a rocking output cannot leave
    psi = np.unwrap(np.stack([f(phi) for f in exact]), axis=1)

    def psi_at(at: np.ndarray) -> np.ndarray:
        return np.stack([f(x) for f, x in zip(exact, at)])

    found = dwell_intervals(phi, psi, band, count=count, psi_at=psi_at, leave=REST_LEAVE if leave is None else leave)
    out = []
    for row in range(len(items)):
        mine = []
        for d in found.dwells((row,)):
            rest = math.degrees(d.rest) % 360.0
            mine.append(
                Rest(
                    crank_degrees(d.start),
                    crank_degrees(d.end),
                    math.degrees(d.angle),
                    rest - 360.0 if rest > 180.0 else rest,
                )
            )
        out.append(tuple(mine))
    return out


def limits_json(mech: Linkage, cyc: CycleLimits) -> dict:
    """The ``summary.limits`` object of ``--json``."""
    lim = cyc.limits
    out_unit = "deg" if lim.output.kind == "angle" else mech.units
    conv = (lambda v: float(np.degrees(v))) if lim.output.kind == "angle" else float  # noqa: E731
    in_key = "input_deg" if mech.inputs[0].kind == "angle" else f"input_{mech.units}"
    in_conv = (lambda v: float(np.degrees(v))) if mech.inputs[0].kind == "angle" else float  # noqa: E731
    doc = {
        "output": lim.output.name,
        "positions": [
            {in_key: in_conv(p.input), f"output_{out_unit}": conv(p.output), "kind": p.kind} for p in lim.positions
        ],
        ("swing_deg" if lim.output.kind == "angle" else f"stroke_{mech.units}"): conv(lim.stroke),
        f"output_min_{out_unit}": conv(lim.output_min),
        f"output_max_{out_unit}": conv(lim.output_max),
        "full_turn": lim.full_turn,
    }
    if lim.time_ratio is not None:
        doc.update(
            time_ratio=lim.time_ratio,
            advance_deg=float(np.degrees(lim.advance)),
            return_deg=float(np.degrees(lim.return_)),
        )
    doc["transmission"] = [
        {"joint": t.joint, "min_deg": float(np.degrees(t.angle)), in_key: in_conv(t.input)} for t in cyc.transmission
    ]
    if cyc.band is not None:
        doc["band_deg"] = float(np.degrees(cyc.band))
        doc["dwells"] = (
            None
            if cyc.dwells is None
            else [{"interval_deg": [d.start, d.end], "dwell_deg": d.length, "rest_deg": d.rest} for d in cyc.dwells]
        )
        if cyc.leave is not None:
            doc["leave_deg"] = float(np.degrees(cyc.leave))
        if cyc.no_dwells is not None:
            doc["dwells_not_measured"] = cyc.no_dwells
    return doc


def limits_text(mech: Linkage, cyc: CycleLimits, units: str) -> str:
    """The lines ``--limits`` prints after the tables."""
    lim = cyc.limits
    out_unit = "deg" if lim.output.kind == "angle" else units
    in_unit = "deg" if mech.inputs[0].kind == "angle" else units
    conv = np.degrees if lim.output.kind == "angle" else (lambda v: v)  # noqa: E731
    in_conv = np.degrees if mech.inputs[0].kind == "angle" else (lambda v: v)  # noqa: E731
    lines = [f"limit positions of {lim.output.name} ({'angle' if lim.output.kind == 'angle' else 'slide'}):"]
    if not lim.positions:
        lines.append("  none: the output velocity does not vanish on the range")
    for p in lim.positions:
        lines.append(
            f"  input {float(in_conv(p.input)):.10g} {in_unit}: {p.kind} {float(conv(p.output)):.10g} {out_unit}"
        )
    word = "swing" if lim.output.kind == "angle" else "stroke"
    lines.append(f"{word}: {float(conv(lim.stroke)):.10g} {out_unit}")
    if lim.time_ratio is not None:
        lines.append(
            f"time ratio: {lim.time_ratio:.10g} (advance {np.degrees(lim.advance):.6g} deg, "
            f"return {np.degrees(lim.return_):.6g} deg of input)"
        )
    for t in cyc.transmission:
        lines.append(
            f"smallest transmission angle at {t.joint}: {np.degrees(t.angle):.10g} deg "
            f"(input {float(in_conv(t.input)):.10g} {in_unit})"
        )
    if cyc.band is not None:
        band = f"{np.degrees(cyc.band):.6g} deg"
        if cyc.dwells is None:
            lines.append(f"dwells within a {band} band: not measured ({cyc.no_dwells})")
        for k, d in enumerate(cyc.dwells or (), start=1):
            lines.append(
                f"dwell {k} within a {band} band: input {d.start:.10g}..{d.end:.10g} deg "
                f"({d.length:.10g} deg), output at rest near {d.rest:.6g} deg"
            )
    return "\n".join(lines)
