"""Ball's point: the coupler point whose path has four-point contact with its tangent line.

It is the intersection (other than the pole) of the inflection circle (κ = 0) and the cubic of
stationary curvature (dκ/dφ = 0), so its path is straight to third order: deviation from the
tangent line ∝ Δφ⁴. It is the seed of every straight-line dwell of the atlas.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from kinematics.status import Status, check_on_degenerate, raise_on_flags
from synth.curvature.pole import Pole
from synth.types import ANY_FLAG, C128, FAR, INVALID, RAY_EPS, U16

__all__ = ["BallPoint", "ball_point", "ball_point_offset", "ball_point_offset_rate"]


@dataclass(frozen=True, slots=True)
class BallPoint:
    """Ball's point at each instant, struct of arrays (the pole's shape).

    Attributes
    ----------
    point : complex128
        Fixed-frame position.
    uv : complex128
        Coupler-frame position (origin A, x-axis along A→B): the coupler point to use.
    tangent : complex128
        Unit direction of its path z′/|z′| (the straight line it follows near this instant).
    status : uint16
        The pole's flags, plus ``AT_POLE`` (Ball's point within RAY_EPS·diameter of the pole:
        a rocker dead-centre, where the point is the pole and its path a cusp) and
        ``AT_INFINITY`` (farther than FAR × linkage size from the crank pin). Flagged values
        are 0 (tangent 1).
    """

    point: C128
    uv: C128
    tangent: C128
    status: U16


def ball_point_offset(t1: ArrayLike, t2: ArrayLike, t3: ArrayLike) -> tuple[C128, C128]:
    """Ball's point relative to the crank, as numerator and denominator ŵ = n/m.

    The Ball point is z = A + E·ŵ with E = a·e^{iφ}: in a frame that turns with the crank and
    has the crank as unit length, it depends on θ′, θ″, θ‴ only.

    Returns
    -------
    n, m : complex128
        n = θ′G + iθ″H and m = θ′(iθ″(G − H) − θ′²G), with
        G = (θ′³ − θ′ − θ‴)(θ′ − 1) + 3θ″², H = 2θ′³ − 3θ′² + θ′ + θ‴.
        m = 0 puts the point at infinity (θ′ = 0, the pole at infinity), G = 0 at the pole.

    Notes
    -----
    Ball's point makes z″ and z‴ parallel to z′ (κ = 0 and dκ/dφ = 0, docs/curvature.md §1), i.e.
    z″ = λz′ and z‴ = μz′ with real λ, μ. With z′ = iE(1 + θ′ŵ), z″ = E(c₂ŵ − 1),
    z‴ = E(c₃ŵ − i), c₂ = iθ″ − θ′², c₃ = iθ‴ − 3θ′θ″ − iθ′³, eliminating ŵ cancels the
    λμ term and leaves a real 2×2 linear system for (λ, μ); back-substitution gives ŵ = n/m.
    Unlike I + r_B·u_B (docs/curvature.md §2) it needs no angle and no division by θ′ before the
    end, so the Ball-point track stays smooth up to the pole at infinity. The two forms agree
    to rounding (tests/synth/test_contract.py).
    """
    _, _, n, m = _ball_terms(t1, t2, t3)
    return n, m


def _ball_terms(t1, t2, t3):
    """G, H, n, m of :func:`ball_point_offset` (float64 / complex128 arrays)."""
    t1, t2, t3 = (np.asarray(x, float) for x in (t1, t2, t3))
    g = (t1 * t1 * t1 - t1 - t3) * (t1 - 1.0) + 3.0 * t2 * t2
    h = 2.0 * t1 * t1 * t1 - 3.0 * t1 * t1 + t1 + t3
    return g, h, t1 * g + 1j * (t2 * h), t1 * (1j * (t2 * (g - h)) - t1 * t1 * g)


def ball_point_offset_rate(t1: ArrayLike, t2: ArrayLike, t3: ArrayLike, t4: ArrayLike) -> tuple[C128, C128]:
    """ŵ and its crank-angle derivative dŵ/dφ (chain rule through θ′…θ⁗), see :func:`ball_point_offset`.

    Used to refine double Ball points by Newton's method (the coupler-frame Ball point is
    p_B = e^{i(φ−θ)}·a·ŵ, so p_B′ = e^{i(φ−θ)}·a·(i(1 − θ′)ŵ + ŵ′)). Where m = 0 (Ball's
    point at infinity) both values are finite placeholders; callers test m or θ′ first.
    """
    g, h, n, m = _ball_terms(t1, t2, t3)
    t1, t2, t3, t4 = (np.asarray(x, float) for x in (t1, t2, t3, t4))
    dg = (3.0 * t1 * t1 * t2 - t2 - t4) * (t1 - 1.0) + (t1**3 - t1 - t3) * t2 + 6.0 * t2 * t3
    dh = 6.0 * t1 * t1 * t2 - 6.0 * t1 * t2 + t2 + t4
    dn = t2 * g + t1 * dg + 1j * (t3 * h + t2 * dh)
    k = 1j * (t2 * (g - h)) - t1 * t1 * g  # m = θ′k
    dk = 1j * (t3 * (g - h) + t2 * (dg - dh)) - 2.0 * t1 * t2 * g - t1 * t1 * dg
    dm = t2 * k + t1 * dk
    safe = np.where(m == 0, 1.0, m)
    w = n / safe
    return w, (dn - w * dm) / safe


def ball_point(pole: Pole, *, on_degenerate: str = "flag") -> BallPoint:
    """Ball's point at each instant of ``pole``.

    Returns
    -------
    BallPoint
        Arrays of ``pole.shape``.

    Notes
    -----
    Computed as z_B = A + E·n/m (:func:`ball_point_offset`), the same point as
    docs/curvature.md's α_B = arg(θ′Z3 − 3θ″Z2) + π/2, r_B = R2(α_B)/θ′². Its velocity is
    z′ = iE·G(θ′ − θ′² + iθ″)/k with m = θ′k, and its distance from the pole over the
    inflection-circle diameter is |sin(α_B − pole tangent)| = θ′²|G|/|m|.

    References
    ----------
    ``docs/curvature.md`` §2, "Ball's point".
    """
    mode = check_on_degenerate(on_degenerate)
    t1, t2, t3 = pole.dtheta
    E = pole.crank_pin
    g, _, n, m = _ball_terms(t1, t2, t3)
    bad = (pole.status & INVALID) != 0
    abs_m = np.abs(m)
    at_inf = (np.abs(E) * np.abs(n) > FAR * pole.size * abs_m) & ~bad
    at_pole = ((t1 * t1) * np.abs(g) <= RAY_EPS * abs_m) & ~bad & ~at_inf
    flagged = bad | at_inf | at_pole
    status = (
        pole.status
        | np.where(at_inf, np.uint16(Status.AT_INFINITY), np.uint16(0))
        | np.where(at_pole, np.uint16(Status.AT_POLE), np.uint16(0))
    ).astype(np.uint16)
    w = E * np.divide(n, m, out=np.zeros_like(n * E), where=~flagged)
    # z′ = iE(1 + θ′ŵ) = iE·G(θ′ − θ′² + iθ″)/k with m = θ′k
    velocity = 1j * E * (t1 * g) * ((t1 - t1 * t1) + 1j * t2) / np.where(flagged, 1.0, m)
    speed = np.abs(velocity)
    tangent = np.divide(velocity, speed, out=np.ones_like(velocity), where=~flagged & (speed > 0))
    point = np.where(flagged, 0j, E + w)
    uv = np.where(flagged, 0j, np.conj(pole.e_theta) * w)
    out = BallPoint(point, uv, tangent, status)
    if mode == "raise":
        raise_on_flags(status, "Ball's point", ANY_FLAG)
    return out
