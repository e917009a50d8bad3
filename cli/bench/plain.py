"""Plain numpy closed forms: the yardstick the kinematics benchmarks divide by.

The textbook law-of-cosines positions, written the way anyone would write them in numpy (no
status flags, no derivatives, no guard against a loop that cannot close), so that a benchmark
can print "our figure ÷ plain numpy in the same run" — a ratio that means the same on any
machine. Not used by the product: :mod:`kinematics.fourbar` and :mod:`synth.mechanism.sixbar` are the
one implementation of each formula.

Conventions as the product's (README *Conventions*): A0 = 0, B0 = d, branch +1 puts B left
of A→B0 (θ = arg(B0 − A) + β) and Q left of P→D (χ = arg(D − P) + β).
"""

from __future__ import annotations

import numpy as np

__all__ = ["fourbar_positions", "sixbar_rrr_positions"]


def _angle_at_start(l1, l2, r):
    """β of the triangle with sides l1 (at the start), l2 and base r: law of cosines."""
    return np.arccos((l1 * l1 + r * r - l2 * l2) / (2 * l1 * r))


def fourbar_positions(a, b, c, d, phi, branch=1):
    """Coupler angle θ (rad) of the four-bar over crank angles ``phi`` (broadcast)."""
    A = a * np.exp(1j * phi)
    R = d - A
    return np.angle(R) + branch * _angle_at_start(b, c, np.abs(R))


def sixbar_rrr_positions(a, b, c, d, u, v, pivot, rocker, rod, phi, branch=1, dyad_branch=1):
    """Output angle ψ (rad, in (−π, π]) of a four-bar + RRR dyad driven by the coupler point
    P = A + e^{iθ}(u + iv): Q = P + ρe^{iχ} with |Q − D| = L, ψ = arg(Q − D)."""
    A = a * np.exp(1j * phi)
    R = d - A
    theta = np.angle(R) + branch * _angle_at_start(b, c, np.abs(R))
    P = A + np.exp(1j * theta) * (u + 1j * v)
    S = pivot - P
    chi = np.angle(S) + dyad_branch * _angle_at_start(rod, rocker, np.abs(S))
    return np.angle(P + rod * np.exp(1j * chi) - pivot)
