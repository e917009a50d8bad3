"""Transmission angles of a general linkage: at the middle joint of every RRR dyad.

An RRR dyad (:mod:`~kinematics.assur.topology`) is two binary bodies joined at a middle joint
I, each pinned to a known body at an external joint (E₁, E₂). Its transmission angle is the
angle at I between the lines I→E₁ and I→E₂ — for a four-bar, between coupler and rocker —
folded to [0°, 90°] (:func:`~kinematics.loop.transmission_fold`: μ and 180° − μ transmit
equally well). :func:`transmission_minima` gives each dyad's smallest angle over a range of the
first input: the smallest of a dense sample, refined to the parabola's vertex and evaluated on
the exact solution there.
Other groups have no single transmission angle here (an RPR slot transmits at 90° by
construction) and are left out. Angles in radians.

References
----------
R. L. Norton, *Design of Machinery*, §3.3 and §4.10 (transmission angle of a four-bar).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinematics.assur.model import Linkage, RevolutePair
from kinematics.assur.positions import Assembly, assemble
from kinematics.assur.topology import AssurGroup, Decomposition, decompose
from kinematics.loop import transmission_fold
from kinematics.status import Status

__all__ = ["TransmissionMinimum", "transmission_angles", "transmission_minima"]


@dataclass(frozen=True, slots=True)
class TransmissionMinimum:
    """The smallest transmission angle of one RRR dyad over the input range.

    Attributes
    ----------
    joint : str
        The dyad's middle joint (where the angle is measured).
    group : int
        The dyad's index in the decomposition's solving order.
    angle : float
        Smallest folded transmission angle (rad, [0, π/2]).
    input : float
        The first input where it occurs (rad or length).
    """

    joint: str
    group: int
    angle: float
    input: float


def _rrr_dyads(linkage: Linkage, decomposition: Decomposition) -> list[tuple[int, AssurGroup]]:
    return [(g, group) for g, group in enumerate(decomposition.groups) if group.kind == "RRR"]


def _joint(linkage: Linkage, assembly: Assembly, pair: int) -> np.ndarray:
    p: RevolutePair = linkage.pairs[pair]  # an RRR dyad's pairs are revolute
    return assembly.point(p.links[0], p.at[0])


def transmission_angles(
    linkage: Linkage, assembly: Assembly, *, decomposition: Decomposition | None = None
) -> list[tuple[str, np.ndarray]]:
    """Per RRR dyad (solving order): its middle joint's name and the folded transmission angle
    at every position of ``assembly`` (rad, (M,); 0 where it does not assemble)."""
    dec = decompose(linkage) if decomposition is None else decomposition
    ok = (assembly.status & Status.NOT_ASSEMBLABLE) == 0
    out = []
    for _, group in _rrr_dyads(linkage, dec):
        e1, mid, e2 = group.pairs
        zi = _joint(linkage, assembly, mid)
        u, v = _joint(linkage, assembly, e1) - zi, _joint(linkage, assembly, e2) - zi
        rel = u * np.conj(v)
        size = np.abs(rel)
        unit = np.where(size > 0, rel / np.where(size > 0, size, 1.0), 1.0)
        out.append((linkage.pairs[mid].joint, np.where(ok, transmission_fold(unit), 0.0)))
    return out


def transmission_minima(
    linkage: Linkage,
    start: Assembly,
    first: float,
    last: float,
    *,
    samples: int = 3600,
    decomposition: Decomposition | None = None,
) -> list[TransmissionMinimum]:
    """Each RRR dyad's smallest transmission angle as the first input runs over
    [``first``, ``last``] in the configuration of ``start`` (other inputs at its values).

    The smallest of ``samples`` + 1 evenly spaced positions (0.1° for a turn), its input
    refined to the vertex of the parabola through it and its two neighbours, where the angle
    is evaluated again on the exact positions; the smaller of the two stands. On a 0.1° grid
    the vertex is within ~h²·|μ‴/μ″| of the minimum, so the value is exact to ~1e-10 rad. The
    caller makes sure the configuration assembles over the range (as
    :func:`~kinematics.assur.limit_positions` does).
    """
    dec = decompose(linkage) if decomposition is None else decomposition
    dyads = _rrr_dyads(linkage, dec)
    if not dyads or not linkage.inputs:
        return []
    # over a full turn the positions just outside the range are those at its other end
    periodic = linkage.inputs[0].kind == "angle" and abs(last - first - 2 * np.pi) < 1e-12
    grid = np.linspace(first, last, samples + 1)
    h = grid[1] - grid[0]
    inputs = np.repeat(start.inputs[:1], grid.size, axis=0)
    inputs[:, 0] = grid
    sampled = transmission_angles(linkage, assemble(linkage, inputs, start, decomposition=dec), decomposition=dec)
    best = np.array([int(np.argmin(mu)) for _, mu in sampled])
    x = grid[best].copy()
    for k, (_, mu) in enumerate(sampled):
        i = best[k]
        if periodic:  # the grid's last position is its first
            left, right = mu[i - 1 if i > 0 else samples - 1], mu[i + 1 if i < samples else 1]
        elif 0 < i < samples:
            left, right = mu[i - 1], mu[i + 1]
        else:
            continue  # a minimum at an end of the range stays there
        curve = left - 2 * mu[i] + right
        if curve > 0:
            x[k] += 0.5 * h * (left - right) / curve
    rows = np.repeat(start.inputs[:1], x.size, axis=0)
    rows[:, 0] = x
    at = assemble(linkage, rows, start, decomposition=dec)
    at_ok = (at.status & Status.NOT_ASSEMBLABLE) == 0
    exact = transmission_angles(linkage, at, decomposition=dec)
    found = []
    for k, ((g, _), (joint, mu)) in enumerate(zip(dyads, sampled)):
        value = float(exact[k][1][k])
        if at_ok[k] and value < mu[best[k]]:
            found.append(TransmissionMinimum(joint, g, value, float(x[k])))
        else:
            found.append(TransmissionMinimum(joint, g, float(mu[best[k]]), float(grid[best[k]])))
    return found
