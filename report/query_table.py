"""The query's default table: what a person reads first, in 120 columns.

Rank, short id (:mod:`report.short_id`), output dyad, dwell, output deviation (and the toleranced
one with ``--tolerance``), swing, transmission, link ratio and peak acceleration; the legend under
it, one line per column. ``dwell query --wide`` shows every column and the full ids
(``cli/query.py``); the JSON, the CSV and the report always carry the full ids.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence

from report.short_id import short_id
from synth.kinds import OutputKind
from synth.query.candidates import Candidate, Request

__all__ = ["WIDTH", "fit_lines", "legend_lines", "short_table"]

#: Columns of a terminal the default table fits (head, rows and legend).
WIDTH = 120


def fit_lines(text: str, indent: int = 0, width: int = WIDTH) -> list[str]:
    """``text`` wrapped at spaces to lines of at most ``width`` characters, the second and later
    lines indented by ``indent`` spaces (a single word longer than a line is broken)."""
    return textwrap.wrap(text, width=width, subsequent_indent=" " * indent, break_on_hyphens=False) or [""]


def legend_lines(entries: Sequence[tuple[str, str]], width: int = WIDTH) -> list[str]:
    """One line per column (``name  meaning``), names aligned, each wrapped to ``width``."""
    pad = max(len(name) for name, _ in entries) + 2
    return [line for name, meaning in entries for line in fit_lines(f"{name:<{pad}}{meaning}", pad, width)]


def _transmission(c: Candidate) -> float:
    """The smaller transmission angle (rad), four-bar or output dyad (a slotted rocker's is
    90° by construction: the four-bar's)."""
    f = c.figures
    if c.sixbar.dyad.kind == OutputKind.RPR:
        return f.transmission_fourbar
    return min(f.transmission_fourbar, f.transmission_output)


def _accel(c: Candidate, rpm: float) -> str:
    b = c.figures.build
    return "-" if b is None else f"{b.dynamics(rpm)[1]:.4g}"


def short_table(candidates: Sequence[Candidate], request: Request, head: str, units: str = "") -> str:
    """The ranked ``candidates`` for ``request`` as the default table: ``head`` (the answer's
    summary line, wrapped), one row per candidate, and the legend, every line at most
    :data:`WIDTH` characters.

    Parameters
    ----------
    candidates : sequence of Candidate
        Ranked (``rank`` from 1), lengths in the user's unit.
    request : Request
        The request they answer (its number of dwells, tolerance and rpm name the columns).
    head : str
        The line above the table (what was asked and searched).
    units : str
        Name of the length unit ('' for "your unit").
    """
    req = request
    toleranced = req.tolerance > 0
    ids = [short_id(c.id) for c in candidates]
    dwells = [
        "/".join(f"{math.degrees(d.angle):.2f}" for d in c.figures.dwells[: req.dwells]) or "-" for c in candidates
    ]
    id_w = max([2, *map(len, ids)])
    dwell_w = max([7, *map(len, dwells)])
    tol_head = f" {'tol dev °':>9}" if toleranced else ""
    lines = fit_lines(head, 2)
    lines.append(
        f"{'rank':>4}  {'id':<{id_w}} {'out':<3} {'dwell °':>{dwell_w}} {'dev °':>7}{tol_head} "
        f"{'swing °':>8} {'μ °':>5} {'ratio':>6} {'α rad/s²':>9}"
    )
    for c, sid, dw in zip(candidates, ids, dwells):
        f = c.figures
        dev = max(f.deviations) if f.deviations else 0.0
        tol = ""
        if toleranced:
            t = c.toleranced_deviation
            tol = f" {'fails' if t is None else f'{math.degrees(t):.3f}':>9}"
        lines.append(
            f"{c.rank:>4}  {sid:<{id_w}} {c.sixbar.dyad.kind:<3} {dw:>{dwell_w}} {math.degrees(dev):>7.3f}{tol} "
            f"{math.degrees(f.swing):>8.2f} {math.degrees(_transmission(c)):>5.1f} {f.link_ratio:>6.2f} "
            f"{_accel(c, req.rpm):>9}"
        )
    unit = units or "your unit"
    entries = [
        ("rank", "Pareto layer, then score, over dwell error, deviation, transmission, footprint, acceleration"),
        ("id", "short id: dwell report takes it or the full id (--wide and --json show the full id)"),
        ("out", "output dyad: RRR rocker and rod, or RPR slotted rocker"),
        (
            "dwell",
            f"the output's rest{'s' if req.dwells > 1 else ''} within the {math.degrees(req.band):g}° band, "
            "crank degrees",
        ),
        ("dev", "output deviation over the requested dwell (peak to peak)"),
    ]
    if toleranced:
        entries.append(
            (
                "tol dev",
                f"95th percentile of dev over 256 six-bars made within ±{req.tolerance:g} {unit} "
                "of each length and pivot coordinate: the ranking's deviation (fails: more than "
                "5 % of them do not assemble)",
            )
        )
    entries += [
        ("swing", "the output's whole swing over the turn"),
        ("μ", "smallest transmission angle, four-bar or output dyad (a slotted rocker's is 90°)"),
        ("ratio", "link ratio: longest link over shortest, every link counted"),
        ("α", f"peak output acceleration at {req.rpm:g} rpm"),
        (
            "--wide",
            f"every column: both transmission angles, slider arm, clearance, refinement and the six-bar's "
            f"dimensions (lengths in {unit}, crank = {req.crank:g})",
        ),
    ]
    return "\n".join(lines + legend_lines(entries))
