"""Inflection circle (κ = 0) and the Euler–Savary centre of curvature of any moving point."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from kinematics.status import Status, check_on_degenerate, raise_on_flags
from synth.curvature.pole import Pole
from synth.types import ANY_FLAG, C128, F64, FAR, INVALID, RAY_EPS, U16

__all__ = ["CurvatureCentre", "InflectionCircle", "euler_savary", "inflection_circle"]


@dataclass(frozen=True, slots=True)
class InflectionCircle:
    """Locus of the coupler points whose paths have zero curvature at this instant.

    Attributes
    ----------
    center : complex128
        Centre I + Z2/(2θ′²), fixed frame.
    diameter : float64
        |Z2|/θ′² (length), the pole speed |I′| over |θ′|.
    inflection_pole : complex128
        J = I + Z2/θ′², the end of the diameter through the pole (along the pole normal).
    status : uint16
        The pole's flags, plus ``AT_INFINITY`` where the diameter exceeds FAR × linkage size
        (the circle is then practically the pole tangent line). Flagged values are 0.
    """

    center: C128
    diameter: F64
    inflection_pole: C128
    status: U16


def inflection_circle(pole: Pole, *, on_degenerate: str = "flag") -> InflectionCircle:
    """Inflection circle at each instant of ``pole`` (same shape).

    Notes
    -----
    A point I + r·u (u = e^{iα}) has z′ = iθ′r·u and Im(conj(z′)z″) = −θ′r(R2 − θ′²r),
    R2 = Re(conj(u)·Z2), so κ = 0 on r_i(α) = R2/θ′²: the circle through the pole with
    diameter Z2/θ′².

    References
    ----------
    ``docs/curvature.md`` §2, "Inflection circle".
    """
    mode = check_on_degenerate(on_degenerate)
    t1 = pole.dtheta[0]
    status = pole.status.copy()
    bad = (status & INVALID) != 0
    t1sq = np.where(bad, 1.0, t1 * t1)
    diam_vec = np.where(bad, 0j, pole.z2 / t1sq)
    diameter = np.abs(diam_vec)
    far = diameter > FAR * pole.size
    status |= np.where(far, np.uint16(Status.AT_INFINITY), np.uint16(0))
    diam_vec = np.where(far, 0j, diam_vec)
    base = np.where(bad | far, 0j, pole.point)
    out = InflectionCircle(base + 0.5 * diam_vec, np.where(far, 0.0, diameter), base + diam_vec, status)
    if mode == "raise":
        raise_on_flags(status, "inflection circle", ANY_FLAG)
    return out


@dataclass(frozen=True, slots=True)
class CurvatureCentre:
    """Centre and radius of curvature of the paths of given moving points at one instant.

    Attributes
    ----------
    center : complex128
        Centre of curvature (the conjugate point of Euler–Savary), fixed frame.
    radius : float64
        Radius of curvature |z − center| ≥ 0 (length).
    status : uint16
        The pole's flags, plus ``AT_POLE`` for a point within RAY_EPS·(diameter) of the pole
        (cusp) and ``CENTER_POINT_AT_INFINITY`` for a point on the inflection circle (centre
        FAR × linkage size or more from the pole). Flagged values are 0.
    """

    center: C128
    radius: F64
    status: U16


def euler_savary(pole: Pole, z: ArrayLike, *, on_degenerate: str = "flag") -> CurvatureCentre:
    """Centre of curvature of the path of the coupler point now at fixed-frame position ``z``.

    Parameters
    ----------
    pole : Pole
        Instantaneous invariants; broadcast against ``z``.
    z : array_like of complex
        Current fixed-frame positions of coupler points (use :meth:`Pole.to_fixed` for
        coupler-frame points).

    Notes
    -----
    With d = z − I = r·u, Euler–Savary 1/r₀ = 1/r − 1/r_i, r_i = Re(conj(u)Z2)/θ′², reads

    .. math::  c = I + d\\,\\frac{q}{q - θ'^2|d|^2}, \\qquad q = \\operatorname{Re}(\\bar d\\,Z_2),

    with no square root or angle. The pole itself (d = 0) is a cusp of its path.

    References
    ----------
    ``docs/curvature.md`` §2, "Centre point" (Euler–Savary).
    """
    mode = check_on_degenerate(on_degenerate)
    z = np.asarray(z, np.complex128)
    t1 = pole.dtheta[0]
    bad = (pole.status & INVALID) != 0
    d = z - pole.point
    q = (np.conj(d) * pole.z2).real
    d2 = (d * np.conj(d)).real
    den = q - (t1 * t1) * d2
    shift = d * q
    # |d| ≤ RAY_EPS·diameter: the point is the pole; |c − I| ≥ FAR·L: on the inflection circle.
    at_pole = d2 * (t1 * t1) ** 2 <= (RAY_EPS**2) * (pole.z2 * np.conj(pole.z2)).real
    at_inf = np.abs(shift) >= (FAR * pole.size) * np.abs(den)
    status = pole.status | np.where(
        bad,
        np.uint16(0),
        np.where(at_pole, np.uint16(Status.AT_POLE), np.uint16(0))
        | np.where(at_inf & ~at_pole, np.uint16(Status.CENTER_POINT_AT_INFINITY), np.uint16(0)),
    )
    flagged = bad | at_pole | at_inf
    center = pole.point + np.divide(shift, den, out=np.zeros_like(shift), where=~flagged)
    center = np.where(flagged, 0j, center)
    radius = np.where(flagged, 0.0, np.abs(z - center))
    out = CurvatureCentre(center, radius, status.astype(np.uint16))
    if mode == "raise":
        raise_on_flags(out.status, "centre of curvature", ANY_FLAG)
    return out
