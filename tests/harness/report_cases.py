"""Candidate six-bars for report tests, built without a database the way the query builds them:
an output dyad fitted to a Ball-point line (RPR), a circle point (RRR) or a double Ball point
(two dwells), simulated crank-normalised, then scaled to the request's crank."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from kinematics.fourbar import fourbar_motion
from synth import ball_point, double_ball_points, line_scan, pole
from synth.mechanism.dyad import fit_rpr, fit_rrr, rpr_double
from synth.mechanism.figures import sixbar_figures
from synth.mechanism.sixbar import SixBar, crank_grid
from synth.query.candidates import Candidate, Request

DEG = math.pi / 180
PHI = crank_grid(720)
#: a Grashof crank-rocker (crank a = 1), its branch, and the crank angle the dwell is built at
FOURBAR = (1.0, 3.0, 3.0, 2.5, 1)
PHI0 = 1.2
#: a crank of 25 (say mm): the report is in the user's units, not the atlas's
CRANK = 25.0
#: an id a user (or a corrupted atlas) could smuggle markup through
EVIL_ID = '<script>alert("x")</script>&\'"-rpr0@30'

REQUEST = Request(
    dwell=40 * DEG,
    dwell_tol=40 * DEG,
    swing=30 * DEG,
    swing_tol=1 * DEG,
    output="any",
    band=0.2 * DEG,
    crank=CRANK,
    min_transmission=20 * DEG,
)
REQUEST2 = Request(
    dwell=30 * DEG,
    dwell_tol=40 * DEG,
    swing=30 * DEG,
    output="rpr",
    dwells=2,
    band=0.2 * DEG,
    crank=CRANK,
    min_transmission=20 * DEG,
)


def _path(a, b, c, d, br, uv: complex) -> np.ndarray:
    return fourbar_motion(a, b, c, d, PHI, br, order=0).coupler_point(uv.real, uv.imag)[0]


def _candidate(sb: SixBar, request: Request, cid: str, segment: int, rest: complex | None = None) -> Candidate:
    """Figures as the query makes them: crank-normalised, then lengths scaled to the crank."""
    f = sixbar_figures(sb, band=request.band, dwell_length=request.dwell, dwells=request.dwells, samples=720)
    s = request.crank
    f = dataclasses.replace(f, footprint=f.footprint * s**2, bounds=tuple(x * s for x in f.bounds))
    return Candidate(
        id=cid, segment_id=segment, sixbar=sb.scaled(s), figures=f, dwell_position=None if rest is None else rest * s
    )


def rpr_sixbar(
    a=FOURBAR[0], b=FOURBAR[1], c=FOURBAR[2], d=FOURBAR[3], br=FOURBAR[4], phi0=PHI0, swing=30 * DEG
) -> SixBar:
    """Slotted rocker on the line of Ball's point at φ₀ (crank units)."""
    bp = ball_point(pole(fourbar_motion(a, b, c, d, phi0, br)))
    assert bp.status == 0
    uv = complex(bp.uv)
    fit = fit_rpr(
        complex(bp.point),
        float(np.angle(bp.tangent)),
        PHI,
        _path(a, b, c, d, br, uv),
        (phi0 - 0.25, phi0 + 0.25),
        swing,
    )
    dyad = fit.dyads()[0]
    return SixBar(a, b, c, d, br, uv.real, uv.imag, dyad)


def rrr_sixbar(alpha=90 * DEG, swing=30 * DEG) -> tuple[SixBar, complex]:
    """RRR on the circle point of the ray at ``alpha`` through the pole at φ₀; and Q's rest."""
    a, b, c, d, br = FOURBAR
    scan = line_scan(pole(fourbar_motion(a, b, c, d, PHI0, br)), alpha)
    assert scan.status == 0
    uv = complex(scan.circle_point_uv)
    C0, rho = complex(scan.center_point), float(scan.radius)
    fit = fit_rrr(C0, rho, PHI, _path(a, b, c, d, br, uv), (PHI0 - 0.2, PHI0 + 0.2), swing, 20 * DEG)
    dyad = fit.dyads()[0]
    return SixBar(a, b, c, d, br, uv.real, uv.imag, dyad), C0


def double_sixbar() -> SixBar:
    """RPR about the meeting point of a double Ball point's two lines: two dwells per turn."""
    a, b, c, d, br = 1.0, 3.0, 3.0, 3.5, 1
    found = double_ball_points(a, b, c, d, br)
    k = 0
    piv = rpr_double((found.point1[k], np.angle(found.tangent1[k])), (found.point2[k], np.angle(found.tangent2[k])))
    dyad = piv.dyad()
    assert dyad is not None
    return SixBar(a, b, c, d, br, found.uv[k].real, found.uv[k].imag, dyad)


def single_dwell_candidates() -> list[Candidate]:
    """RRR (rank 1), RPR (rank 2) and an RPR whose id carries markup (rank 3)."""
    rrr, rest = rrr_sixbar()
    rpr = rpr_sixbar()
    rpr2 = rpr_sixbar(swing=25 * DEG)
    out = [
        _candidate(rrr, REQUEST, "1234500007-rrr0@30", 1234500007, rest),
        _candidate(rpr, REQUEST, "1234500003-rpr0@30", 1234500003),
        _candidate(rpr2, REQUEST, EVIL_ID, 42),
    ]
    return [dataclasses.replace(c, rank=i + 1) for i, c in enumerate(out)]


def double_dwell_candidates() -> list[Candidate]:
    return [dataclasses.replace(_candidate(double_sixbar(), REQUEST2, "77-dbl0@free", 77), rank=1)]
