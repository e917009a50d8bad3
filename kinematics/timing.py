"""From crank-angle derivatives to time derivatives, for a crank speed and acceleration.

For any coordinate q(φ(t)) with crank speed ω = φ̇ and crank acceleration α = φ̈ (taken
constant over the instant, so that the third time derivative of φ vanishes):

    q̇ = q′ω,   q̈ = q″ω² + q′α,   q⃛ = q‴ω³ + 3q″ωα.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["crank_speed", "time_derivatives"]


def crank_speed(*, rpm: float | None = None, omega: float | None = None, clockwise: bool = False) -> float:
    """Signed crank angular velocity in rad/s (counter-clockwise positive).

    Give exactly one of ``rpm`` (revolutions per minute, ω = π·n/30) or ``omega`` (rad/s,
    its magnitude is used). ``clockwise`` flips the sign.
    """
    if (rpm is None) == (omega is None):
        raise ValueError("give exactly one of rpm or omega")
    w = abs(np.pi * rpm / 30.0) if rpm is not None else abs(float(omega))
    return -w if clockwise else w


def time_derivatives(
    derivs: tuple[ArrayLike, ...], omega: float, alpha: float = 0.0
) -> tuple[NDArray[np.float64] | NDArray[np.complex128], ...]:
    """Time derivatives (q̇, q̈, q⃛)[: len(derivs)] from crank-angle derivatives (q′, q″, q‴).

    Works for real coordinates (angles, displacements) and complex points alike. Units: those
    of q per second^k for ω in rad/s and α in rad/s².
    """
    out = []
    d = [np.asarray(x) for x in derivs]
    if len(d) >= 1:
        out.append(d[0] * omega)
    if len(d) >= 2:
        out.append(d[1] * omega**2 + d[0] * alpha)
    if len(d) >= 3:
        out.append(d[2] * omega**3 + 3.0 * d[1] * omega * alpha)
    return tuple(out)
