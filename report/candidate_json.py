"""The JSON shape of a request and of its candidate six-bars (``dwell query --json``, the no-match
object, ``candidates.json`` of a report), and the way back to a six-bar.

Every key carries its unit as ``dwell analyze`` does (:func:`report.motion_table.unit_key`):
``_deg`` for angles, ``_<unit>`` for lengths in the user's unit (``--units``, default mm; the
document also names it as ``length_unit``), ``_cranks`` for lengths in crank lengths, rates in
``_rad_s``, ``_rad_s2``, ``_rad_s3``; a key without a suffix is a count, a ratio or a name.
Crank angles of a dwell interval lie in [0°, 360°) (the interval runs counter-clockwise from
its first to its second end, which is smaller when it passes 0°). Frame: A0 = (0, 0),
B0 = (d, 0), y up; the coupler point in the coupler frame (origin A, x along A→B).
"""

from __future__ import annotations

import math

from report.motion_table import unit_key
from synth.mechanism.figures import SixBarFigures
from synth.mechanism.sixbar import OutputDyad, SixBar
from synth.query.candidates import Candidate, Request

__all__ = ["candidate_json", "length_key", "request_json", "sixbar_from_json"]


def length_key(units: str) -> str:
    """The suffix of a length's key: the unit as :func:`report.motion_table.unit_key` spells it,
    ``unit`` for an unnamed one."""
    return unit_key(units) or "unit"


def _typed_degrees(angle: float) -> float:
    """``angle`` (rad) in degrees as the user typed it: 12 significant digits, so that 30°
    read in and converted back prints 30, not 29.999999999999996."""
    return float(f"{math.degrees(angle):.12g}")


def request_json(request: Request, units: str = "mm") -> dict:
    """The request as typed: angles in degrees, the crank in ``units``, the buildability limits
    in crank lengths (as ``--min-arm`` and ``--min-clearance`` take them)."""
    return {
        "dwell_deg": _typed_degrees(request.dwell),
        "dwell_tol_deg": _typed_degrees(request.dwell_tol),
        "swing_deg": None if request.swing is None else _typed_degrees(request.swing),
        "step_deg": None if request.step is None else _typed_degrees(request.step),
        "swing_tol_deg": _typed_degrees(request.swing_tol),
        "output": request.output,
        "dwells": request.dwells,
        "band_deg": _typed_degrees(request.band),
        f"crank_{length_key(units)}": request.crank,
        "length_unit": units,
        "min_transmission_deg": _typed_degrees(request.min_transmission),
        "max_link_ratio": request.max_link_ratio,
        "top": request.top,
        "min_arm_cranks": request.min_arm,
        "min_clearance_cranks": request.min_clearance,
        "rpm": request.rpm,
        "max_accel_rad_s2": request.max_accel,
        "refine": request.refine,
        "complete": request.complete,
        f"tolerance_{length_key(units)}": request.tolerance or None,
    }


def _xy(z: complex) -> list[float]:
    return [float(z.real), float(z.imag)]


def candidate_json(c: Candidate, rpm: float = 60.0, units: str = "mm") -> dict:
    """One candidate: the whole six-bar in ``units`` (crank = the request's crank), its figures
    from the exact simulation, and its peak output rates at ``rpm``."""
    L = length_key(units)
    sb, f = c.sixbar, c.figures
    dyad = sb.dyad
    output: dict = {"type": dyad.kind, f"pivot_{L}": _xy(dyad.pivot)}
    if dyad.kind == "RRR":
        output |= {
            f"rocker_{L}": float(dyad.rocker),
            f"rod_{L}": float(dyad.rod),
            "branch": int(dyad.branch),
            f"dwell_position_{L}": None if c.dwell_position is None else _xy(c.dwell_position),
        }
    dwells = []
    for k, d in enumerate(f.dwells):
        dwells.append(
            {
                "dwell_deg": math.degrees(d.angle),
                "interval_deg": list(d.ends_deg()),
                "output_deviation_deg": math.degrees(f.deviations[k]) if k < len(f.deviations) else None,
            }
        )
    return {
        "rank": c.rank,
        "id": c.id,
        "length_unit": units,
        "fourbar": {f"a_{L}": sb.a, f"b_{L}": sb.b, f"c_{L}": sb.c, f"d_{L}": sb.d, "branch": int(sb.branch)},
        f"coupler_point_{L}": [sb.u, sb.v],
        "output": output,
        "dwells": dwells,
        # with --tolerance: the 95th percentile of the output deviation over six-bars made
        # within it (synth.mechanism.tolerance); null without one or where too many of them do not assemble
        "toleranced_deviation_deg": None if c.toleranced_deviation is None else math.degrees(c.toleranced_deviation),
        "swing_deg": math.degrees(f.swing),
        "step_deg": None if f.step is None else math.degrees(f.step),
        # a slotted rocker's transmission angle is 90° by construction: no figure (null)
        "transmission_deg": {
            "fourbar_min": math.degrees(f.transmission_fourbar),
            "output_min": None if dyad.kind == "RPR" else math.degrees(f.transmission_output),
        },
        "link_ratio": f.link_ratio,
        f"footprint_{L}2": f.footprint,
        "buildability": _buildability_json(f, rpm, L),
        "refinement": _refinement_json(c),
        "segment_id": c.segment_id,
    }


def _summary_json(f: SixBarFigures) -> dict:
    return {
        "dwell_deg": [math.degrees(d.angle) for d in f.dwells],
        "swing_deg": math.degrees(f.swing),
        "output_deviation_deg": max(math.degrees(x) for x in f.deviations) if f.deviations else None,
    }


def _refinement_json(c: Candidate) -> dict | None:
    """Before → after figures of a refined six-bar (None if it was not refined): dwell(s), swing
    and the output deviation over the requested dwell (the largest of its dwells')."""
    if c.refined_from is None:
        return None
    return {"before": _summary_json(c.refined_from), "after": _summary_json(c.figures)}


def _buildability_json(f: SixBarFigures, rpm: float, L: str) -> dict | None:
    """The buildability figures (lengths in the user's unit) and the output's peak rates at
    ``rpm``; None where they were not computed."""
    b = f.build
    if b is None:
        return None
    speed, accel, jerk = b.dynamics(rpm)
    return {
        f"arm_{L}": b.arm,
        f"slot_used_{L}": None if b.slot is None else list(b.slot),
        f"clearance_{L}": b.clearance,
        "clearance_between": b.clearance_between,
        "rpm": rpm,
        "peak_output_speed_rad_s": speed,
        "peak_output_accel_rad_s2": accel,
        "peak_output_jerk_rad_s3": jerk,
    }


def sixbar_from_json(doc: dict) -> SixBar:
    """The six-bar of one candidate of ``candidates.json`` (or of the query's ``--json``), in
    the document's own length unit."""
    L = length_key(doc["length_unit"])
    fb, out = doc["fourbar"], doc["output"]
    u, v = doc[f"coupler_point_{L}"]
    x, y = out[f"pivot_{L}"]
    if out["type"] == "RRR":
        dyad = OutputDyad.rrr(complex(x, y), out[f"rocker_{L}"], out[f"rod_{L}"], out["branch"])
    else:
        dyad = OutputDyad.rpr(complex(x, y))
    return SixBar(fb[f"a_{L}"], fb[f"b_{L}"], fb[f"c_{L}"], fb[f"d_{L}"], fb["branch"], u, v, dyad)
