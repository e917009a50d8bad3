"""Class II Assur groups (dyads) in closed form, both assembly branches, vectorized.

A dyad is two unknown bodies L1, L2 with an external pair E1 (L1 to a known body), an internal
pair I (L1–L2) and an external pair E2 (L2 to a known body); its name lists the pair types in
that order. Each solver takes the pairs as seen from the unknown side
(:mod:`kinematics.assur.pairs`), arrays broadcast over the input positions, and returns the
poses ``(r1, e1, r2, e2)`` of both bodies (origin and unit phasor of the frame) and a
:class:`~kinematics.status.Status` array. Positions that cannot assemble get finite
placeholders and ``NOT_ASSEMBLABLE``; a double solution (the two branches meet) is ``TOGGLE``.

Branch conventions (``branch`` = +1 or −1; single-solution dyads ignore it):

* RRR — +1 puts the internal joint B to the left of the directed line A→C from the external
  joint of L1 to that of L2 (the four-bar convention of :class:`~kinematics.status.Branch`).
* RRP — B runs on a line (the guide, seen from L2); +1 puts B ahead of the foot of the
  perpendicular from A, in the guide's direction (slider-crank: rod pointing forward).
* RPR — +1 takes the larger slide s of the internal prismatic pair.
* PRP, RPP — linear: one solution.

Geometry: RRR is the intersection of two circles (:func:`kinematics.loop.circle_intersection`,
Heron's form for the height, no cancellation near toggles), RRP a line and a circle, RPR a
quadratic in the slide, PRP and RPP two lines (:func:`kinematics.loop.line_intersection`).

References
----------
I. I. Artobolevsky, *Theory of Mechanisms and Machines*, §§ 11–13 (kinematics of dyads).
"""

from __future__ import annotations

import numpy as np

from kinematics.assur.pairs import Joint, Pin, Sleeve, Slide, link_from_two_points, unit
from kinematics.loop import circle_intersection, line_intersection
from kinematics.status import Status

__all__ = [
    "line_circle",
    "solve_prp",
    "solve_rpp",
    "solve_rpr",
    "solve_rrp",
    "solve_rrr",
]

#: Relative size of a discriminant's square root below which the two branches coincide.
DOUBLE_ROOT_EPS = 1e-12

_NA = np.uint8(Status.NOT_ASSEMBLABLE)
_TG = np.uint8(Status.TOGGLE)


def _flags(bad: np.ndarray, double: np.ndarray) -> np.ndarray:
    return np.where(bad, _NA, np.where(double, _TG, np.uint8(0))).astype(np.uint8)


def line_circle(base, U, A, l, branch) -> tuple[np.ndarray, np.ndarray]:
    """t with |base + t·U − A| = l (U a unit phasor); ``branch`` +1 takes the larger t."""
    w = np.conj(U) * (np.asarray(A, complex) - base)
    foot, h = w.real, w.imag  # along and across the line
    disc = (l - h) * (l + h)
    root = np.sqrt(np.maximum(disc, 0.0))
    double = root < DOUBLE_ROOT_EPS * l
    return foot + branch * root, _flags(disc < 0, double & (disc >= 0))


def solve_rrr(pin1: Pin, joint: Joint, pin2: Pin, branch):
    """RRR dyad: circle about A = ``pin1.at`` through B meets circle about C = ``pin2.at``."""
    l1 = np.abs(joint.p1 - pin1.local)
    l2 = np.abs(joint.p2 - pin2.local)
    A = np.asarray(pin1.at, complex)
    loop = circle_intersection(np.asarray(pin2.at, complex) - A, l1, l2, branch, rates=False)
    B, status = A + l1 * loop.e1, loop.status
    r1, e1 = link_from_two_points(pin1.at, pin1.local, B, joint.p1)
    r2, e2 = link_from_two_points(pin2.at, pin2.local, B, joint.p2)
    return r1, e1, r2, e2, status


def solve_rrp(pin1: Pin, joint: Joint, slide2: Slide, branch):
    """RRP dyad: B runs on L2's line (from the slide) at distance l1 = |B − A| from A."""
    l1 = np.abs(joint.p1 - pin1.local)
    base, U = slide2.line(joint.p2)
    t, status = line_circle(base, U, pin1.at, l1, branch)
    B = base + t * U
    r1, e1 = link_from_two_points(pin1.at, pin1.local, B, joint.p1)
    e2 = slide2.e * np.ones_like(B)
    return r1, e1, B - e2 * joint.p2, e2, status


def solve_rpr(pin1: Pin, sleeve: Sleeve, pin2: Pin, branch):
    """RPR dyad: C − A = e1·(m + s·v) with |C − A| known gives s² + 2s·Re(m v̄) + |m|² − |C − A|² = 0."""
    A, C = np.asarray(pin1.at, complex), np.asarray(pin2.at, complex)
    m = sleeve.offset(pin1.local, pin2.local)
    mv = m * np.conj(sleeve.v)
    D = np.abs(C - A)
    disc = (D - mv.imag) * (D + mv.imag)
    root = np.sqrt(np.maximum(disc, 0.0))
    s = -mv.real + branch * root
    w = m + s * sleeve.v
    degenerate = (np.abs(w) == 0) | (D == 0)
    e1 = unit((C - A) * np.conj(w))
    r1 = A - e1 * pin1.local
    e2 = e1 * sleeve.rho
    double = root < DOUBLE_ROOT_EPS * np.maximum(D, np.abs(m))
    status = _flags((disc < 0) | degenerate, double & (disc >= 0))
    return r1, e1, C - e2 * pin2.local, e2, status


def solve_prp(slide1: Slide, joint: Joint, slide2: Slide, branch=None):
    """PRP dyad: both orientations fixed by the slides; B on both lines."""
    b1, U1 = slide1.line(joint.p1)
    b2, U2 = slide2.line(joint.p2)
    t, _, status = line_intersection(b1, U1, b2, U2)
    B = b1 + t * U1
    e1 = slide1.e * np.ones_like(B)
    e2 = slide2.e * np.ones_like(B)
    return B - e1 * joint.p1, e1, B - e2 * joint.p2, e2, status


def solve_rpp(pin1: Pin, sleeve: Sleeve, slide2: Slide, branch=None):
    """RPP dyad: L2's orientation from the slide, L1's from the sleeve (e1 = e2·conj ρ); L1 hangs
    from A; L2's origin lies on the sleeve's line (fixed in L1) and on the slide's line."""
    A = np.asarray(pin1.at, complex)
    e2 = slide2.e * np.ones_like(A)
    e1 = e2 * np.conj(sleeve.rho)
    r1 = A - e1 * pin1.local
    base_a = r1 + e1 * sleeve.offset(0.0, 0.0)
    base_b, U_b = slide2.line(0.0)
    t, _, status = line_intersection(base_a, e1 * sleeve.v, base_b, U_b)
    return r1, e1, base_a + t * e1 * sleeve.v, e2, status
