"""An independent six-bar solution: a plain loop over crank angles with the textbook circle
intersection (cmath, no numpy, no code of ``synth``), the yardstick of the simulation tests
(``tests/synth/test_sixbar.py``) and of the query's answers (``tests/cli/test_query.py``)."""

from __future__ import annotations

import cmath
import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from synth.mechanism.sixbar import SixBar


def circle_meet(c1: complex, r1: float, c2: complex, r2: float, left: bool) -> complex | None:
    """Intersection of circles (c1, r1) and (c2, r2) to the left (or right) of c1 → c2."""
    dist = abs(c2 - c1)
    if dist == 0:
        return None
    along = (r1 * r1 - r2 * r2 + dist * dist) / (2 * dist)
    h2 = r1 * r1 - along * along
    if h2 < 0:
        return None
    ex = (c2 - c1) / dist
    ey = 1j * ex  # points to the left of c1 → c2
    return c1 + along * ex + (math.sqrt(h2) if left else -math.sqrt(h2)) * ey


def reference_psi(sb: SixBar, phi: float) -> tuple[float, complex, complex] | None:
    """(ψ wrapped, coupler point P, moving pivot Q) at one crank angle, or None."""
    A = sb.a * cmath.exp(1j * phi)
    B = circle_meet(A, sb.b, complex(sb.d), sb.c, sb.branch > 0)
    if B is None:
        return None
    P = A + (B - A) / sb.b * complex(sb.u, sb.v)
    D = sb.dyad.pivot
    if sb.dyad.kind == "RPR":
        return cmath.phase(P - D), P, P
    Q = circle_meet(P, sb.dyad.rod, D, sb.dyad.rocker, sb.dyad.branch > 0)
    if Q is None:
        return None
    return cmath.phase(Q - D), P, Q
