"""The full-turn motion of one candidate six-bar at uniform crank steps: the table behind the
report's JSON ``cycle``, its plots, its drawing and its animation (one simulation, four views).

Angles in radians here, degrees in :func:`cycle_json`; lengths in the six-bar's (the user's)
unit; fixed frame A0 = (0, 0), B0 = (d, 0), y up. Values at positions where the mechanism does
not assemble are the simulation's finite placeholders here and ``null`` in JSON.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinematics.status import Status
from synth.kinds import OutputKind
from synth.mechanism.figures import SixBarFigures
from synth.mechanism.sixbar import SixBar, crank_grid, simulate

__all__ = ["CYCLE_COLUMNS", "Cycle", "cycle_json", "dwell_mask", "sixbar_cycle", "unit_motion"]

F64 = NDArray[np.float64]
C128 = NDArray[np.complex128]

#: Keys of the JSON ``cycle`` table (:func:`cycle_json`): (key, unit, meaning). Every key
#: holds one list with a value per crank step.
CYCLE_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("phi_deg", "deg", "crank angle φ, counter-clockwise from +x"),
    ("theta_deg", "deg", "four-bar coupler angle θ = arg(B − A), in (−180, 180]"),
    ("gamma_deg", "deg", "four-bar rocker angle γ = arg(B − B0), in (−180, 180]"),
    ("A_x", "length", "crank pin A, x"),
    ("A_y", "length", "crank pin A, y"),
    ("B_x", "length", "coupler–rocker joint B, x"),
    ("B_y", "length", "coupler–rocker joint B, y"),
    ("P_x", "length", "coupler point P, x"),
    ("P_y", "length", "coupler point P, y"),
    ("psi_deg", "deg", "output angle ψ (RPR arg(P − D), RRR arg(Q − D)), continuous over the turn"),
    ("dpsi", "rad/rad", "ψ′ = dψ/dφ (output over crank angular velocity)"),
    ("ddpsi_per_rad", "rad/rad²", "ψ″ = d²ψ/dφ² (output angular acceleration per crank speed²)"),
    ("Q_x", "length", "RRR moving pivot Q, x (null for RPR)"),
    ("Q_y", "length", "RRR moving pivot Q, y (null for RPR)"),
    ("transmission_fourbar_deg", "deg", "four-bar transmission angle at B, folded to [0, 90]"),
    ("transmission_output_deg", "deg", "output transmission angle (RRR at Q, folded to [0, 90]; RPR 90)"),
    ("status", "", "Status flags at this position (0 = OK, 1 = not assemblable, 2 = toggle)"),
    ("dwelling", "", "true inside a reported dwell interval"),
)


@dataclass(frozen=True, slots=True)
class Cycle:
    """Exact motion of one six-bar over a crank turn, struct of arrays of shape ``(M,)``.

    Attributes
    ----------
    phi : float64
        Crank angles (rad), ``crank_grid(M)``: 0, 2π/M, …, end excluded.
    A, B, P, Q : complex128
        Crank pin, coupler–rocker joint, coupler point, and the RRR moving pivot (for RPR the
        pin P, where the block sits in the slot); fixed frame, the six-bar's length unit.
    theta, gamma : float64
        Coupler and rocker angles (rad, (−π, π]).
    psi : float64
        Output angle (rad), continuous over the turn (:attr:`SixBarMotion.psi`).
    dpsi, ddpsi : float64
        ψ′ (rad/rad) and ψ″ (rad/rad²) with respect to the crank angle.
    mu_fourbar, mu_output : float64
        Folded transmission angles (rad, [0, π/2]).
    status : uint16
        :class:`~kinematics.status.Status` flags per position.
    dwelling : bool
        Inside one of the figures' dwell intervals.
    """

    phi: F64
    A: C128
    B: C128
    P: C128
    Q: C128
    theta: F64
    gamma: F64
    psi: F64
    dpsi: F64
    ddpsi: F64
    mu_fourbar: F64
    mu_output: F64
    status: NDArray[np.uint16]
    dwelling: NDArray[np.bool_]

    @property
    def assembled(self) -> NDArray[np.bool_]:
        return (self.status & np.uint16(Status.NOT_ASSEMBLABLE)) == 0

    def __len__(self) -> int:
        return int(self.phi.shape[0])


def dwell_mask(phi: F64, figures: SixBarFigures) -> NDArray[np.bool_]:
    """True at the crank angles ``phi`` (rad) that lie in a dwell interval of ``figures``
    (intervals may pass 2π; the comparison is cyclic)."""
    phi = np.asarray(phi, dtype=float)
    inside = np.zeros(phi.shape, dtype=bool)
    for dw in figures.dwells:
        # a few ulps of slack so a grid sample on a refined end counts as inside
        inside |= np.mod(phi - dw.start, 2 * math.pi) <= dw.angle + 1e-12
    return inside


def unit_motion(sixbar: SixBar, phi: np.ndarray, order: int = 0):
    """:func:`synth.mechanism.sixbar.simulate` of ``sixbar`` scaled to crank = 1, and the crank length
    its positions are to be multiplied by (angles and ratios are the same at any scale).
    Written when the loop's Heron product overflowed beyond ~1e75 (`dwell report --crank 1e100`
    wrote NaN; found by a random-seed run). The kernel now scales that product itself
    (``kinematics.loop.HERON_SAFE``); the rest of the simulation and the linkage file's assembly
    solver were not re-checked at every scale, so the report keeps simulating at crank = 1."""
    return simulate(sixbar.scaled(1.0 / sixbar.a), phi, order=order), sixbar.a


def sixbar_cycle(sixbar: SixBar, figures: SixBarFigures, *, step_deg: float = 1.0) -> Cycle:
    """Simulate ``sixbar`` over one turn at ``step_deg`` crank steps (a divisor of 360°).

    ``figures`` supplies the dwell intervals for :attr:`Cycle.dwelling`; every value comes from
    :func:`synth.mechanism.sixbar.simulate` (order 2), nothing is interpolated.
    """
    samples = 360.0 / float(step_deg)
    if not (math.isfinite(samples) and abs(samples - round(samples)) < 1e-9 and round(samples) >= 8):
        raise ValueError(f"step_deg must divide 360 into at least 8 steps, got {step_deg!r}")
    phi = crank_grid(round(samples))
    m, scale = unit_motion(sixbar, phi, order=2)
    fb = m.fourbar
    A = np.broadcast_to(fb.A, phi.shape).astype(complex) * scale
    return Cycle(
        phi=phi,
        A=A,
        B=np.asarray(fb.B, complex) * scale,
        P=np.asarray(m.z[0], complex) * scale,
        Q=np.asarray(m.moving_pivot, complex) * scale,
        theta=np.asarray(fb.theta, float),
        gamma=np.asarray(fb.gamma, float),
        psi=m.psi,
        dpsi=m.dpsi[0],
        ddpsi=m.dpsi[1],
        mu_fourbar=m.transmission_fourbar,
        mu_output=m.transmission_output,
        status=m.status.astype(np.uint16),
        dwelling=dwell_mask(phi, figures),
    )


def _values(x: np.ndarray, valid: NDArray[np.bool_]) -> list[Any]:
    """Plain floats, ``None`` where not ``valid`` or not finite (JSON has no NaN)."""
    ok = valid & np.isfinite(x)
    return [float(v) if k else None for v, k in zip(x.tolist(), ok.tolist())]


def cycle_json(cycle: Cycle, kind: str) -> dict[str, list]:
    """The cycle as JSON columns (:data:`CYCLE_COLUMNS`), angles in degrees.

    ``kind`` is the dyad's (``"RPR"`` or ``"RRR"``): an RPR has no moving pivot Q, so its
    ``Q_x``/``Q_y`` are null. Positions (and their angles) are null where the mechanism does not
    assemble, derivatives also at toggles (the simulation's placeholders are not values).
    """
    every = np.ones(len(cycle), dtype=bool)
    pos = cycle.assembled
    deriv = cycle.status == 0
    has_q = pos if kind == OutputKind.RRR else np.zeros(len(cycle), dtype=bool)
    deg = np.degrees
    out = {
        # the nominal step angles (k·step), not their round trip through radians
        "phi_deg": _values(np.round(deg(cycle.phi), 9), every),
        "theta_deg": _values(deg(cycle.theta), pos),
        "gamma_deg": _values(deg(cycle.gamma), pos),
        "A_x": _values(cycle.A.real, every),
        "A_y": _values(cycle.A.imag, every),
        "B_x": _values(cycle.B.real, pos),
        "B_y": _values(cycle.B.imag, pos),
        "P_x": _values(cycle.P.real, pos),
        "P_y": _values(cycle.P.imag, pos),
        "psi_deg": _values(deg(cycle.psi), pos),
        "dpsi": _values(cycle.dpsi, deriv),
        "ddpsi_per_rad": _values(cycle.ddpsi, deriv),
        "Q_x": _values(cycle.Q.real, has_q),
        "Q_y": _values(cycle.Q.imag, has_q),
        "transmission_fourbar_deg": _values(deg(cycle.mu_fourbar), pos),
        "transmission_output_deg": _values(deg(cycle.mu_output), pos),
        "status": [int(s) for s in cycle.status.tolist()],
        "dwelling": [bool(s) for s in cycle.dwelling.tolist()],
    }
    assert tuple(out) == tuple(k for k, _, _ in CYCLE_COLUMNS)  # the documented keys, in order
    return out
