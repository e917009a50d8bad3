"""A candidate six-bar as a linkage description file (``docs/linkage-files.md``), so that
``dwell analyze linkage`` — an independent solver (Assur groups, its own closed forms) — can
check it and analyse it further (velocities, accelerations, limit positions, animation).

The file names the ground pivots A0 = (0, 0), B0 = (d, 0) and D, the crank A0–A, the coupler
triangle A–B–P in its own frame (origin A, x-axis along A→B: the coupler point is (u, v)), the
rocker B0–B and the output dyad: RRR rod P–Q and output rocker D–Q; RPR a block pinned at P
sliding on the slotted output link pivoted at D. The input is the crank angle; the output the
output link's angle. The file is the candidate: its ``configuration`` key names the assembly
configuration that is the candidate's (its four-bar and dyad branches), found by solving the
file at crank angle 0 (the input's ``value``) and matching joint positions, and its ``[output]``
carries the request's band and number of dwells, so that ``dwell analyze linkage FILE --limits``
with no other option gives the candidate's swing, dwell interval(s) and transmission angles.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from synth.kinds import OutputKind
from synth.mechanism.sixbar import simulate
from synth.query.candidates import Candidate

__all__ = ["linkage_configuration", "linkage_toml", "readable_linkages"]


def _num(x: float) -> str:
    """A float as TOML writes it back exactly (repr round-trips)."""
    return repr(float(x))


def _pair(z: complex) -> str:
    return f"[{_num(z.real)}, {_num(z.imag)}]"


def _body(
    candidate: Candidate,
    units: str,
    configuration: int | None = None,
    band: float | None = None,
    dwells: int = 1,
    leave: float | None = None,
) -> list[str]:
    sb = candidate.sixbar
    rrr = sb.dyad.kind == OutputKind.RRR
    lines = [
        f"name = {_quoted(_name(candidate.id))}",
        f"units = {_quoted(units or 'mm')}",
    ]
    if configuration is not None:
        lines.append(f"configuration = {configuration}      # the candidate's assembly, numbered at crank angle 0")
    lines += [
        "",
        "[ground]",
        "A0 = [0.0, 0.0]",
        f"B0 = [{_num(sb.d)}, 0.0]",
        f"D = {_pair(sb.dyad.pivot)}",
        "",
        "[links.crank]",
        'joints = ["A0", "A"]',
        f"length = {_num(sb.a)}",
        "",
        "[links.coupler]            # frame: origin A, x-axis along A->B; P is the coupler point",
        f"points = {{ A = [0.0, 0.0], B = [{_num(sb.b)}, 0.0], P = [{_num(sb.u)}, {_num(sb.v)}] }}",
        "",
        "[links.rocker]",
        'joints = ["B0", "B"]',
        f"length = {_num(sb.c)}",
        "",
    ]
    if rrr:
        lines += [
            "[links.rod]",
            'joints = ["P", "Q"]',
            f"length = {_num(sb.dyad.rod)}",
            "",
            "[links.output]             # the output rocker: its angle is the output",
            'joints = ["D", "Q"]',
            f"length = {_num(sb.dyad.rocker)}",
            "",
        ]
    else:
        lines += [
            "[links.output]             # the slotted output link: frame origin D, x-axis along the slot",
            "points = { D = [0.0, 0.0] }",
            "",
            "[links.block]              # the slider, pinned to the coupler at P",
            "points = { P = [0.0, 0.0] }",
            "",
            "[[prismatic]]",
            'name = "slot"',
            'guide = "output"',
            'block = "block"',
            'through = "D"',
            "angle = 0",
            "",
        ]
    lines += ["[[inputs]]", 'joint = "A0"', 'link = "crank"', "value = 0.0", "", "[output]", 'link = "output"']
    if band is not None:
        lines += [
            f"band = {_num(math.degrees(band))}         # deg: the output band within which it rests",
            f"dwells = {int(dwells)}",
        ]
        if dwells == 2 and leave is not None:
            lines.append(
                f"leave = {_num(math.degrees(leave))}        # deg: how far it leaves the band between its rests"
            )
    return lines


def _name(candidate_id: str) -> str:
    """The file's name: ``six-bar <id>``, the id (an atlas's text) with controls escaped and cut
    to the length a linkage file's name may have."""
    from kinematics.assur.linkage_file import MAX_NAME
    from report.escape import terminal

    name = f"six-bar {terminal(candidate_id)}"
    return name if len(name) <= MAX_NAME else name[: MAX_NAME - 1] + "…"


def _quoted(text: str) -> str:
    """A TOML basic string (JSON's escaping is TOML-compatible for basic strings)."""
    import json

    return json.dumps(text, ensure_ascii=False)


def linkage_configuration(candidate: Candidate, text: str) -> int:
    """The number (1-based, as ``--configuration`` takes it) of the file's assembly
    configuration that is the candidate's: joint positions matched at crank angle 0."""
    from kinematics.assur import configurations, linkage_from_text

    mech = linkage_from_text(text)
    motion = simulate(candidate.sixbar, np.array([0.0]), order=0)
    want = {"B": complex(motion.fourbar.B[0]), "P": complex(motion.z[0][0])}
    if candidate.sixbar.dyad.kind == OutputKind.RRR:
        want["Q"] = complex(motion.moving_pivot[0])
    size = max(candidate.sixbar.a, candidate.sixbar.b, candidate.sixbar.c, candidate.sixbar.d)
    best, best_miss = 1, math.inf
    for k, asm in enumerate(configurations(mech, [0.0]), start=1):
        miss = 0.0
        for name, z in want.items():
            link = next(i for i, lk in enumerate(mech.links) if name in lk.points)
            miss = max(miss, abs(complex(asm.point(link, mech.links[link].points[name])[0]) - z))
        if miss < best_miss:
            best, best_miss = k, miss
    if best_miss > 1e-6 * size:
        raise ValueError(
            f"no configuration of the linkage file matches candidate {candidate.id!r} "
            f"(closest misses by {best_miss:.3g})"
        )
    return best


def readable_linkages(candidates: Sequence[Candidate], units: str = "") -> None:
    """Raise :class:`kinematics.assur.LinkageFileError` (one line, naming the candidate) if
    ``dwell analyze linkage`` could not read back the linkage file of one of ``candidates``
    at its scale: a number beyond the ±1e150 a file holds (``--crank 1e150`` wrote ground
    pivots at 3e150). The reports call it before they write anything."""
    from kinematics.assur import LinkageFileError, linkage_from_text

    for c in candidates:
        try:
            linkage_from_text("\n".join(_body(c, units)) + "\n")
        except LinkageFileError as exc:
            raise LinkageFileError(f"candidate {c.id}'s linkage file could not be read back ({exc})") from None


def linkage_toml(
    candidate: Candidate, units: str = "", *, band: float | None = None, dwells: int = 1, leave: float | None = None
) -> str:
    """The linkage description of ``candidate`` (its lengths in the user's units) with its
    assembly configuration and, given the request's ``band`` (rad) and number of ``dwells``,
    the output band its dwells are measured in (with two, ``leave``, rad: the swing tolerance
    by which the output leaves the band between its rests); a header comment gives the figures
    ``dwell analyze linkage FILE --limits`` reproduces."""
    # The configuration's number does not depend on the scale; matched at crank = 1, where the
    # assembly solver's products of lengths cannot overflow (report.cycle.unit_motion).
    unit = dataclasses.replace(candidate, sixbar=candidate.sixbar.scaled(1.0 / candidate.sixbar.a))
    config = linkage_configuration(unit, "\n".join(_body(unit, units)) + "\n")
    body = "\n".join(_body(candidate, units, config, band, dwells, leave)) + "\n"
    f = candidate.figures
    dwells = ", ".join("{:.3f}..{:.3f} deg".format(*d.ends_deg()) for d in f.dwells)
    header = [
        f"# Candidate {candidate.id!r} (rank {candidate.rank}), written by dwell report.",
        f"# swing {math.degrees(f.swing):.6f} deg; dwell(s) {dwells};",
        f"# min transmission: four-bar {math.degrees(f.transmission_fourbar):.3f} deg, "
        + (
            "output: a slot (90 deg by construction)."
            if candidate.sixbar.dyad.kind == "RPR"
            else f"output {math.degrees(f.transmission_output):.3f} deg."
        ),
        "# Reproduce with: dwell analyze linkage THIS_FILE --limits",
        "",
    ]
    return "\n".join(header) + body
