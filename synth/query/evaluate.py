"""A fitted six-bar's exact figures and the request's test of them: :func:`simulate` (the
screen, then the full figures), :func:`meets` and :func:`violations` (how far each constraint
is missed), and what a candidate is made of (:func:`candidate_of`, :func:`distinct`,
:func:`toleranced`). :mod:`synth.query.refine` takes :func:`meets` from here.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from synth.kinds import OutputKind
from synth.mechanism.figures import SixBarFigures, footprints, sixbar_figures
from synth.mechanism.sixbar import SixBar, SixBars
from synth.mechanism.sixbar import simulate as simulate_motion
from synth.query.candidates import SAMPLES, Candidate, Request, screen
from synth.query.fitting import Fitted
from synth.query.result import CONSTRAINTS


def violations(request: Request, f: SixBarFigures) -> dict[str, float]:
    """How far the figures ``f`` (crank-normalised) miss each constraint of ``request``: 0 where
    met. ``assembly`` is 1 for a six-bar that does not assemble over the turn, toggles or
    revolves, or has fewer dwells than asked — two rests not separated by the swing tolerance
    are one (:func:`_missing_dwell`) — (then nothing else is measured); the angles'
    excesses in degrees; the link ratio's in percent of the limit."""
    out = dict.fromkeys(CONSTRAINTS, 0.0)
    if not f.acceptable or _missing_dwell(request, f):
        out["assembly"] = 1.0
        return out
    out["dwell"] = float(max(dwell_excess(request, d.angle) for d in f.dwells[: request.dwells]))
    if request.step is not None:
        out["step"] = max(0.0, math.degrees(abs(f.step - request.step) - request.swing_tol))
    b = f.build  # without it (no buildability figures) the arm, clearance and acceleration are not measured
    limits = limit_excesses(
        request,
        swing=f.swing,
        transmission=min(f.transmission_fourbar, f.transmission_output),
        link_ratio=f.link_ratio,
        arm=math.inf if b is None or b.arm is None else b.arm,
        clearance=math.inf if b is None else b.clearance,
        accel=-math.inf if b is None else b.dynamics(request.rpm)[1],
    )
    out.update((c, float(x)) for c, x in limits.items())
    return out


def limit_excesses(request: Request, *, swing, transmission, link_ratio, arm, clearance, accel) -> dict:
    """The excesses of :func:`violations` but the dwell's, the step's and the assembly's, of
    figures given one at a time (floats) or as arrays of a batch — the one statement of these
    formulas (:func:`synth.query.diagnosis.bounded_excess` gives them for a batch): ``swing``
    (rad), ``transmission`` the worse of the two transmission angles (rad), ``link_ratio``,
    ``arm`` and ``clearance`` (crank lengths: the figures are crank-normalised; +inf where
    there is none, as an RRR has no torque arm), ``accel`` the peak output acceleration
    (rad/s², −inf where not measured). Angles' excesses in degrees, the link ratio's in percent
    of the limit, the shortfalls in crank lengths, the acceleration's in rad/s²; only the
    constraints ``request`` sets (the swing and the acceleration are optional)."""
    out = {}
    if request.swing is not None:
        out["swing"] = np.maximum(0.0, np.degrees(np.abs(swing - request.swing) - request.swing_tol))
    out["transmission"] = np.maximum(0.0, np.degrees(request.min_transmission - transmission))
    out["link_ratio"] = np.maximum(0.0, 100.0 * (link_ratio / request.max_link_ratio - 1.0))
    out["arm"] = np.maximum(0.0, request.min_arm - arm)
    out["clearance"] = np.maximum(0.0, request.min_clearance - clearance)
    if request.max_accel is not None:
        out["acceleration"] = np.maximum(0.0, accel - request.max_accel)
    return out


def _missing_dwell(request: Request, f: SixBarFigures) -> bool:
    """Fewer dwells than ``request`` asks for, two rests counting as two only with motion
    between them (:meth:`~synth.mechanism.figures.SixBarFigures.rests_apart` at the swing tolerance)."""
    if len(f.dwells) < request.dwells:
        return True
    return request.dwells == 2 and not f.rests_apart(request.swing_tol)


def dwell_excess(request: Request, angle):
    """How far (°) a dwell of ``angle`` (rad; a float or an array) is outside the request's
    dwell ± tolerance."""
    return np.maximum(0.0, np.degrees(np.abs(angle - request.dwell) - request.dwell_tol))


def meets(request: Request, f: SixBarFigures) -> bool:
    """Whether the figures ``f`` (crank-normalised) meet ``request`` and its constraints."""
    if not f.acceptable or _missing_dwell(request, f):
        return False
    if any(abs(d.angle - request.dwell) > request.dwell_tol for d in f.dwells[: request.dwells]):
        return False
    if request.step is not None and abs(f.step - request.step) > request.swing_tol:
        return False
    return meets_but_dwells(request, f)


def meets_but_dwells(request: Request, f: SixBarFigures) -> bool:
    """Whether the figures ``f`` (crank-normalised) meet every constraint of ``request`` that
    does not depend on its band: the six-bar assembles over the turn without toggling or
    revolving, and its swing, transmission, buildability and link ratio meet the request (the
    dwells, and the step between two rests, are measured at the band)."""
    if not f.acceptable:
        return False
    if request.swing is not None and abs(f.swing - request.swing) > request.swing_tol:
        return False
    if min(f.transmission_fourbar, f.transmission_output) < request.min_transmission:
        return False
    b = f.build
    if b is not None:
        if (b.arm is not None and b.arm < request.min_arm) or b.clearance < request.min_clearance:
            return False
        if request.max_accel is not None and b.dynamics(request.rpm)[1] > request.max_accel:
            return False
    return f.link_ratio <= request.max_link_ratio


def total_excess(excess: dict[str, float]) -> float:
    """How far a six-bar is from meeting a request: the sum of its excesses (inf if it does not
    assemble)."""
    return math.inf if excess["assembly"] else sum(excess.values())


def scaled_figures(f: SixBarFigures, scale: float) -> SixBarFigures:
    return dataclasses.replace(
        f,
        footprint=f.footprint * scale**2,
        bounds=tuple(x * scale for x in f.bounds),
        build=None if f.build is None else f.build.scaled(scale),
    )


def candidate_of(request: Request, fitted: Fitted, f: SixBarFigures) -> Candidate:
    r = fitted.row
    return Candidate(
        id=fitted.candidate_id(request.swing),
        segment_id=r.segment_id,
        sixbar=fitted.sixbar().scaled(request.crank),
        figures=scaled_figures(f, request.crank),
        dwell_position=None if fitted.rest is None else fitted.rest * request.crank,
    )


def figures_of(request: Request, sixbars: list[SixBar], *, footprint: bool = True) -> list[SixBarFigures]:
    return sixbar_figures(
        SixBars.from_sixbars(sixbars),
        band=request.band,
        dwell_length=request.dwell,
        dwells=request.dwells,
        samples=SAMPLES,
        footprint=footprint,
        leave=request.swing_tol,
    )


def simulate(request: Request, fitted: Sequence[Fitted]) -> tuple[list[Candidate], int]:
    """The candidates among ``fitted`` that meet ``request`` (unranked), and how many six-bars
    were simulated."""
    screened, n = screened_figures(request, fitted)
    return [candidate_of(request, f, fig) for f, fig in screened if meets(request, fig)], n


def screened_figures(request: Request, fitted: Sequence[Fitted]) -> tuple[list[tuple[Fitted, SixBarFigures]], int]:
    """The six-bars among ``fitted`` that pass the screen, with their full figures (the
    footprint, a ranking figure, only for those that meet ``request``; 0 for the others), and
    how many six-bars were simulated (screened)."""
    if not fitted:
        return [], 0
    sixbars = [f.sixbar() for f in fitted]
    # the full figures only for six-bars that pass the (necessary) test on the crank grid
    passed = screen(request, SixBars.from_sixbars(sixbars), SAMPLES)
    kept = [(f, sb) for f, sb, p in zip(fitted, sixbars, passed) if p]
    if not kept:
        return [], len(passed)
    figures = figures_of(request, [sb for _, sb in kept], footprint=False)
    meeting = [k for k, fig in enumerate(figures) if meets(request, fig)]
    if meeting:  # the same positions as the figures' own simulation: the same areas
        areas = footprints(SixBars.from_sixbars([kept[k][1] for k in meeting]), SAMPLES)
        for k, area in zip(meeting, areas):
            figures[k] = dataclasses.replace(figures[k], footprint=float(area))
    return [(f, fig) for (f, _), fig in zip(kept, figures)], len(passed)


def distinct(ranked: Sequence[Candidate]) -> list[Candidate]:
    """One six-bar per segment and output type (the best-ranked), and one of a mirror pair: the
    two assembly branches of a four-bar are mirror images with the same figures."""
    seen: set = set()
    unique = []
    for c in ranked:
        kind = c.sixbar.dyad.kind
        mirror = (*c.sixbar.fourbar.mirror_key(), kind)
        key = (c.segment_id, kind)  # a segment's six-bars have one output (its kind's)
        if key not in seen and mirror not in seen:
            seen.update((key, mirror))
            unique.append(c)
    return unique


def rest_position(sixbar: SixBar, f: SixBarFigures) -> complex | None:
    """RRR: the moving pivot Q at the middle of the first dwell (None for an RPR)."""
    if sixbar.dyad.kind != OutputKind.RRR or not f.dwells:
        return None
    d = f.dwells[0]
    return complex(simulate_motion(sixbar, np.array([0.5 * (d.start + d.end)]), order=0).moving_pivot[0])


def toleranced(request: Request, candidates: list[Candidate]) -> list[Candidate]:
    """With ``request.tolerance``: each candidate with its toleranced deviation
    (:func:`synth.mechanism.tolerance.toleranced_deviation` over the middles of its dwells, the request's
    dwell length; the candidates split over threads, :func:`~synth.mechanism.tolerance.toleranced_deviations`),
    worked out afresh (a refined six-bar is another six-bar); else as they are."""
    if request.tolerance <= 0:
        return candidates
    from synth.mechanism.tolerance import toleranced_deviations

    centres = [[0.5 * (d.start + d.end) for d in c.figures.dwells[: request.dwells]] for c in candidates]
    resting = [k for k, cs in enumerate(centres) if cs]  # a candidate without a dwell has no figure
    values: list[float | None] = [None] * len(candidates)
    found = toleranced_deviations(
        [candidates[k].sixbar for k in resting], request.tolerance, [centres[k] for k in resting], request.dwell
    )
    for k, value in zip(resting, found):
        values[k] = value
    return [dataclasses.replace(c, toleranced_deviation=v) for c, v in zip(candidates, values)]
