"""Pairs as an Assur group's solver sees them: from the unknown bodies' side, in their frames.

Points are complex (x + iy); a pose (r, e) maps a body-frame point p to r + e·p. Every field
broadcasts over the input positions (shape ``(M,)`` or scalar): a body fused from several links
by a driven pair has points that move in its frame with the input.

* :class:`Pin` — external revolute pair: the joint's global position (on the known side) and
  its point in the unknown body.
* :class:`Slide` — external prismatic pair: the unknown body's orientation is fixed by it and
  each of its points runs on a known line.
* :class:`Joint` — internal revolute pair between two unknown bodies.
* :class:`Sleeve` — internal prismatic pair from unknown body 1 to unknown body 2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "Joint",
    "Pin",
    "Sleeve",
    "Slide",
    "link_from_two_points",
    "sleeve",
    "slide_from_block",
    "slide_from_guide",
    "unit",
]


def unit(z: np.ndarray) -> np.ndarray:
    """z/|z| with a finite placeholder (1) where z = 0."""
    z = np.asarray(z, dtype=complex)
    m = np.abs(z)
    return np.divide(z, m, out=np.ones_like(z), where=m > 0)


def link_from_two_points(P, p_local, Q, q_local):
    """Pose (r, e) of a body whose local points p, q sit at P, Q (|P − Q| = |p − q|)."""
    e = unit((Q - P) * np.conj(q_local - p_local))
    return P - e * p_local, e


@dataclass(frozen=True, slots=True)
class Pin:
    """External revolute pair: global position ``at`` = the unknown body's point ``local``."""

    at: np.ndarray
    local: np.ndarray


@dataclass(frozen=True, slots=True)
class Joint:
    """Internal revolute pair: point ``p1`` of body 1 = point ``p2`` of body 2 (body frames)."""

    p1: np.ndarray
    p2: np.ndarray


@dataclass(frozen=True, slots=True)
class Slide:
    """External prismatic pair seen from its unknown body.

    The body's orientation is ``e``; its point p runs on the global line
    ``origin + e·(p − anchor) + t·direction`` (t real, ``direction`` a unit phasor).
    """

    e: np.ndarray
    origin: np.ndarray
    anchor: np.ndarray
    direction: np.ndarray

    def line(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(base, direction) of the line the body's point ``p`` runs on."""
        return self.origin + self.e * (p - self.anchor), self.direction


@dataclass(frozen=True, slots=True)
class Sleeve:
    """Internal prismatic pair from body 1 to body 2.

    Orientation e₂ = e₁·ρ. For points p₁ of body 1 and p₂ of body 2:
    B₂(p₂) − B₁(p₁) = e₁·(c₁ − p₁ + ρ·(p₂ − c₂) + s·v), s the slide, v a unit direction in
    body 1's frame.
    """

    rho: np.ndarray
    c1: np.ndarray
    c2: np.ndarray
    v: np.ndarray

    def offset(self, p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
        """m(p₁, p₂) = c₁ − p₁ + ρ·(p₂ − c₂), the slide-free part of B₂ − B₁ in body 1's frame."""
        return self.c1 - p1 + self.rho * (p2 - self.c2)


def slide_from_guide(Q: np.ndarray, U: np.ndarray, block_point: np.ndarray, block_direction: np.ndarray) -> Slide:
    """The unknown body is the block; the known guide's line is Q + s·U (global).

    The block keeps ``block_direction`` (body frame) parallel to U: e = U·conj(w); its point
    ``block_point`` runs on the line.
    """
    e = U * np.conj(block_direction)
    return Slide(e, Q, block_point, U)


def slide_from_block(O: np.ndarray, W: np.ndarray, through: np.ndarray, direction: np.ndarray) -> Slide:
    """The unknown body carries the guide (``through``, ``direction`` in its frame); the known
    block's point is at O with direction W (global). Then e = W·conj(u) and the guide's point p
    runs on O + e·(p − through) − s·e·u."""
    e = W * np.conj(direction)
    return Slide(e, O, through, e * direction)


def sleeve(guide_is_1: bool, through, direction, block_point, block_direction) -> Sleeve:
    """Internal prismatic pair in body frames (guide data in the guide body's frame, block data
    in the block body's frame). See :class:`Sleeve`."""
    if guide_is_1:
        rho = direction * np.conj(block_direction)
        return Sleeve(rho, through, block_point, direction)
    rho = block_direction * np.conj(direction)
    return Sleeve(rho, block_point, through, -rho * direction)
