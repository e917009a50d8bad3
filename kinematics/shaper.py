"""Crank / guide-rod / slider (quick-return shaper): assembly, derivatives, limit positions.

Conventions (``docs/cases/classic_mechanisms.md`` §1): crank pivot A = 0, x axis
perpendicular to the frame line AC, guide-rod pivot C = (0, −h). Crank AB = l1 at φ1
(counter-clockwise from +x); block 2 is pinned to the crank at B and slides on the guide rod
3, s2 = |CB|, φ3 = arg(B − C) in (0, π); rod CD = l3; link DE = l4 at φ4; slider 5 at
E = (s5, −e). Branch +1 (:class:`~kinematics.slider_crank.SliderBranch`) has cos φ4 > 0,
−1 the mirror assembly of link 4. Points are complex numbers (x + iy).

The kernel broadcasts its inputs (linkages as ``(N, 1)`` against crank angles ``(M,)``) and
never returns NaN/inf: positions that cannot assemble and derivatives where link 4 stands
perpendicular to the slider line carry a :class:`~kinematics.status.Status` flag.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinematics.fourbar import check_lengths
from kinematics.loop import TOGGLE_EPS
from kinematics.slider_crank import (
    SliderBranch,
    SliderLimits,
    check_finite,
    check_slider_branch,
    slider_limits_from,
)
from kinematics.status import AssemblyError, Status, assembly_status, check_on_degenerate, first_flagged

__all__ = [
    "ShaperMotion",
    "check_shaper",
    "shaper_limits",
    "shaper_motion",
]

F64 = NDArray[np.float64]
C128 = NDArray[np.complex128]


@dataclass(frozen=True, slots=True)
class ShaperMotion:
    """Positions and crank-angle derivatives of a crank / guide-rod / slider, struct of arrays.

    Every array has the broadcast shape of the inputs. Derivatives are with respect to the
    crank angle φ1 (rad/rad and length/rad); :func:`kinematics.timing.time_derivatives` turns
    them into time derivatives for any crank speed and acceleration.

    Attributes
    ----------
    l1, l3, l4, h : float64, crank AB, guide rod CD, link DE, height of A over C (any unit)
    e : float64, the slider line is y = −e, same unit
    phi1 : float64, crank angle (rad)
    branch : float64 of ±1, :class:`~kinematics.slider_crank.SliderBranch` of link 4
    s2 : float64, block 2 along the rod, |CB|
    phi3 : float64, guide rod angle arg(B − C) (rad)
    phi4 : float64, link 4 angle arg(E − D) in (−π, π] (rad)
    s5 : float64, slider 5 abscissa (E = (s5, −e))
    ds2, dphi3, dphi4, ds5 : tuples of the first and second φ1-derivatives [:order]
    status : uint8, :class:`Status` flags (NOT_ASSEMBLABLE, TOGGLE)
    """

    l1: F64
    l3: F64
    l4: F64
    h: F64
    e: F64
    phi1: F64
    branch: F64
    s2: F64
    phi3: F64
    phi4: F64
    s5: F64
    ds2: tuple[F64, ...]
    dphi3: tuple[F64, ...]
    dphi4: tuple[F64, ...]
    ds5: tuple[F64, ...]
    status: NDArray[np.uint8]

    @property
    def shape(self) -> tuple[int, ...]:
        return self.s5.shape

    @property
    def ok(self) -> NDArray[np.bool_]:
        return self.status == Status.OK

    @property
    def B(self) -> C128:
        """Crank pin B = l1·e^{iφ1} (also the centre of block 2)."""
        return self.l1 * np.exp(1j * self.phi1)

    @property
    def C(self) -> C128:
        """Guide-rod pivot C = −i·h."""
        return -1j * self.h + np.zeros(self.shape)

    @property
    def D(self) -> C128:
        """Rod end D = C + l3·e^{iφ3}."""
        return self.C + self.l3 * np.exp(1j * self.phi3)

    @property
    def E(self) -> C128:
        """Slider joint E = s5 − i·e."""
        return self.s5 - 1j * self.e


def check_shaper(l1: float, l3: float, l4: float, h: float, e: float, branch: int = SliderBranch.FORWARD) -> None:
    """Raise :class:`AssemblyError` naming the first violated assembly condition of a shaper.

    The conditions, for a crank that turns fully and a rod that oscillates:

    * l1, l3, l4, h > 0 and e finite;
    * l1 < h: the guide rod oscillates in (φ3min, π − φ3min), cos φ3min = l1/h (l1 = h would
      take B through C, where φ3 is undefined; l1 > h makes the rod turn fully);
    * l1 + h < l3: block 2 stays on the rod (s2 reaches h + l1 at φ1 = 90°);
    * l3 + e − h < l4: link 4 reaches the slider line with the rod upright (sin φ3 = 1);
    * h − e − l3·sin φ3min < l4, sin φ3min = √(h² − l1²)/h: link 4 reaches it with the rod at
      an extreme. |h − e − l3 sin φ3| = l4·|sin φ4| must stay below l4 over the whole swing,
      and it is monotonic in sin φ3, so these two ends are all that matter. The strict
      inequalities keep link 4 off the slider-line normal (cos φ4 = 0, a toggle).

    References
    ----------
    ``docs/cases/classic_mechanisms.md`` §1 gives the first three; the fourth is needed as
    soon as e is small or negative.
    """
    check_lengths(l1=l1, l3=l3, l4=l4, h=h)
    check_finite(e=e)
    check_slider_branch(branch)
    if not l1 < h:
        raise AssemblyError(
            f"shaper: condition l1 < h violated (l1 = {l1:g}, h = {h:g}): the guide rod would "
            + ("pass through its pivot C" if l1 == h else "turn fully instead of oscillating")
        )
    if not l1 + h < l3:
        raise AssemblyError(
            f"shaper: condition l1 + h < l3 violated ({l1 + h:g} >= {l3:g}): block 2 would run off the guide rod at D"
        )
    if not l3 + e - h < l4:
        raise AssemblyError(
            f"shaper: condition l3 + e - h < l4 violated ({l3 + e - h:g} >= {l4:g}): link 4 cannot "
            "reach the slider line with the guide rod upright"
        )
    low = h - e - l3 * _sin_phi3_min(l1, h)
    if not low < l4:
        raise AssemblyError(
            f"shaper: condition h - e - l3*sqrt(1 - (l1/h)^2) < l4 violated ({low:g} >= {l4:g}): link 4 "
            "cannot reach the slider line with the guide rod at its extreme position"
        )


def _sin_phi3_min(l1: float, h: float) -> float:
    """sin of the rod's extreme angle, where it is tangent to the crank circle."""
    return float(np.sqrt((h - l1) * (h + l1)) / h)


def shaper_motion(
    l1: ArrayLike,
    l3: ArrayLike,
    l4: ArrayLike,
    h: ArrayLike,
    e: ArrayLike,
    phi1: ArrayLike,
    branch: ArrayLike = SliderBranch.FORWARD,
    *,
    order: int = 2,
    on_degenerate: str = "flag",
) -> ShaperMotion:
    """Solve the shaper's two loops and their first ``order`` crank-angle derivatives in closed form.

    Parameters
    ----------
    l1, l3, l4, h : array_like
        Crank AB, guide rod CD, link DE and the height of A above C (> 0, any unit),
        broadcast against ``phi1``.
    e : array_like
        The slider line is y = −e (same unit).
    phi1 : array_like
        Crank angle(s), radians, counter-clockwise from +x.
    branch : array_like of {+1, −1}
        :class:`~kinematics.slider_crank.SliderBranch` of link 4: sign of cos φ4.
    order : {0, 1, 2}
        Highest derivative order computed.
    on_degenerate : {"flag", "raise"}
        ``"raise"`` raises :class:`AssemblyError` naming the condition where a position
        cannot assemble (B on C, block 2 beyond D, link 4 short of the slider line) or a
        derivative is requested with cos φ4 = 0; ``"flag"`` records it in ``status``.

    Notes
    -----
    Loop A-B-C: :math:`s_2 e^{i\\varphi_3} = l_1 e^{i\\varphi_1} + i h`; loop C-D-E:
    :math:`l_3\\cos\\varphi_3 + l_4\\cos\\varphi_4 = s_5`,
    :math:`l_3\\sin\\varphi_3 + l_4\\sin\\varphi_4 = h - e`. With u = φ1 − φ3 and primes for
    d/dφ1,

    .. math::

        s_2' = -l_1\\sin u, \\quad \\varphi_3' = l_1\\cos u / s_2, \\quad
        \\varphi_4' = -\\frac{l_3\\varphi_3'\\cos\\varphi_3}{l_4\\cos\\varphi_4}, \\quad
        s_5' = -l_3\\varphi_3'\\sin\\varphi_3 - l_4\\varphi_4'\\sin\\varphi_4, \\\\
        s_2'' = s_2\\varphi_3'^2 - l_1\\cos u, \\quad
        \\varphi_3'' = -\\frac{2 s_2'\\varphi_3' + l_1\\sin u}{s_2}, \\\\
        \\varphi_4'' = \\frac{l_3\\varphi_3'^2\\sin\\varphi_3 - l_3\\varphi_3''\\cos\\varphi_3
                     + l_4\\varphi_4'^2\\sin\\varphi_4}{l_4\\cos\\varphi_4}, \\quad
        s_5'' = -\\frac{l_4\\varphi_4'^2 + l_3\\varphi_3''\\sin(\\varphi_3 - \\varphi_4)
                      + l_3\\varphi_3'^2\\cos(\\varphi_3 - \\varphi_4)}{\\cos\\varphi_4}.

    :math:`2 s_2'\\varphi_3'` is the Coriolis term.

    References
    ----------
    ``docs/cases/classic_mechanisms.md`` §1 (with ω1 = 1, ε1 = 0; its a2 and a5 correct a
    widely circulated program that has ω1² for ω3² in a2 and the wrong sign of l4·ω4² in a5).
    """
    mode = check_on_degenerate(on_degenerate)
    if order not in (0, 1, 2):
        raise ValueError(f"order must be 0, 1 or 2, not {order!r}")
    check_lengths(l1=l1, l3=l3, l4=l4, h=h)
    check_finite(e=e, phi1=phi1)
    check_slider_branch(branch)
    l1, l3, l4, h, e, phi1, branch = np.broadcast_arrays(
        *(np.asarray(x, dtype=float) for x in (l1, l3, l4, h, e, phi1, branch))
    )
    c1, s1 = np.cos(phi1), np.sin(phi1)
    bx, by = l1 * c1, l1 * s1 + h  # C→B
    s2 = np.hypot(bx, by)
    on_pivot = s2 <= TOGGLE_EPS * (l1 + h)  # B on C: the rod's direction is undetermined
    safe_s2 = np.where(on_pivot, 1.0, s2)
    cos3, sin3 = np.where(on_pivot, 1.0, bx / safe_s2), np.where(on_pivot, 0.0, by / safe_s2)
    phi3 = np.arctan2(sin3, cos3)
    q4 = h - e - l3 * sin3  # = l4·sin φ4
    root4 = (l4 - q4) * (l4 + q4)  # l4²·cos²φ4, negative where link 4 falls short
    bad = on_pivot | (s2 > l3) | (root4 < 0)
    sin4 = np.clip(q4 / l4, -1.0, 1.0)
    cos4 = branch * np.sqrt(np.maximum(root4, 0.0)) / l4
    toggle = ~bad & (np.abs(cos4) < TOGGLE_EPS)
    status = assembly_status(bad, toggle)
    phi4 = np.arctan2(sin4, cos4)
    s5 = l3 * cos3 + l4 * cos4

    ds2: list[F64] = []
    dphi3: list[F64] = []
    dphi4: list[F64] = []
    ds5: list[F64] = []
    if order >= 1:
        ok = status == Status.OK
        # Flagged positions get finite zeros instead of a division by s2 = 0 or cos φ4 = 0.
        inv_s2 = np.divide(1.0, s2, out=np.zeros_like(s2), where=ok)
        inv_c4 = np.divide(1.0, cos4, out=np.zeros_like(cos4), where=ok)
        cos_u, sin_u = c1 * cos3 + s1 * sin3, s1 * cos3 - c1 * sin3  # of u = φ1 − φ3
        v2 = -l1 * sin_u * ok
        w3 = l1 * cos_u * inv_s2
        w4 = -l3 * w3 * cos3 * inv_c4 / l4
        ds2.append(v2)
        dphi3.append(w3)
        dphi4.append(w4)
        ds5.append(-l3 * w3 * sin3 - l4 * w4 * sin4)
    if order >= 2:
        cos_34, sin_34 = cos3 * cos4 + sin3 * sin4, sin3 * cos4 - cos3 * sin4
        e3 = -(2.0 * v2 * w3 + l1 * sin_u) * inv_s2
        ds2.append((s2 * w3 * w3 - l1 * cos_u) * ok)
        dphi3.append(e3)
        dphi4.append((l3 * w3 * w3 * sin3 - l3 * e3 * cos3 + l4 * w4 * w4 * sin4) * inv_c4 / l4)
        ds5.append(-(l4 * w4 * w4 + l3 * e3 * sin_34 + l3 * w3 * w3 * cos_34) * inv_c4)

    motion = ShaperMotion(
        l1,
        l3,
        l4,
        h,
        e,
        phi1,
        branch,
        s2,
        phi3,
        phi4,
        s5,
        tuple(ds2),
        tuple(dphi3),
        tuple(dphi4),
        tuple(ds5),
        status,
    )
    if mode == "raise":
        _raise_first_violation(motion, order)
    return motion


def _raise_first_violation(motion: ShaperMotion, order: int) -> None:
    """Raise :class:`AssemblyError` naming the condition broken at the first bad position."""
    found = first_flagged(motion.status, Status.NOT_ASSEMBLABLE | (Status.TOGGLE if order else Status.OK))
    if found is None:
        return
    i, count = found
    l1, l3, l4, h, e, phi1, s2, phi3 = (
        float(x[i]) for x in (motion.l1, motion.l3, motion.l4, motion.h, motion.e, motion.phi1, motion.s2, motion.phi3)
    )
    where = f"shaper l1={l1:g} l3={l3:g} l4={l4:g} h={h:g} e={e:g} at crank angle {np.degrees(phi1):g} deg"
    affected = f"({count} position(s) affected)"
    if not motion.status[i] & Status.NOT_ASSEMBLABLE:
        raise AssemblyError(f"{where}: link 4 is perpendicular to the slider line (cos phi4 = 0), velocities undefined")
    if s2 <= TOGGLE_EPS * (l1 + h):
        raise AssemblyError(
            f"{where} cannot assemble: B lies on the rod pivot C (l1 = h), the rod angle is undefined {affected}"
        )
    if s2 > l3:
        raise AssemblyError(
            f"{where} cannot assemble: s2 = |CB| = {s2:.6g} > l3 = {l3:g}, block 2 is off the rod {affected}"
        )
    q4 = h - e - l3 * np.sin(phi3)
    raise AssemblyError(
        f"{where} cannot assemble: |h - e - l3 sin(phi3)| = {abs(q4):.6g} > l4 = {l4:g}, link 4 cannot reach "
        f"the slider line {affected}"
    )


def shaper_limits(
    l1: float, l3: float, l4: float, h: float, e: float, branch: int = SliderBranch.FORWARD
) -> SliderLimits:
    """Limit positions, stroke and time ratio of slider 5, from every stationary position in closed form.

    s5′ = φ3′·ds5/dφ3 with ds5/dφ3 = −l3·sin(φ3 − φ4)/cos φ4, so slider 5 stops where

    * the guide rod is at an extreme, tangent to the crank circle (φ3′ = 0, CB ⊥ AB):
      sin φ1 = −l1/h, i.e. φ1 = −asin(l1/h) and π + asin(l1/h);
    * rod and link 4 are collinear (φ4 = φ3 or φ3 + π, σ = ±1): (l3 + σ·l4)·sin φ3 = h − e
      with σ·cos φ3 of the branch's sign, if that φ3 lies inside the rod's swing; each such φ3
      is met at the two crank angles where the line C + s2·e^{iφ3} cuts the crank circle,
      s2 = h·sin φ3 ± √(l1² − h²cos²φ3).

    Usually only the two tangent positions exist (the classic quick-return with time ratio
    (π + 2·asin(l1/h))/(π − 2·asin(l1/h))); a collinear pair makes the slider turn back
    inside a stroke, and the extremes and the time ratio account for it
    (:func:`~kinematics.slider_crank.slider_time_ratio`).

    Raises :class:`AssemblyError` (via :func:`check_shaper`) for data that cannot assemble.
    """
    check_shaper(l1, l3, l4, h, e, branch)
    turn = np.arcsin(l1 / h)
    candidates = [-turn, np.pi + turn]
    phi3_min = np.arccos(l1 / h)
    for sigma in (1.0, -1.0):
        reach = l3 + sigma * l4
        if reach == 0.0 or abs((h - e) / reach) > 1.0:
            continue
        root = np.arcsin((h - e) / reach)
        for phi3 in {float(root), float(np.pi - root)}:
            if not (phi3_min < phi3 < np.pi - phi3_min) or branch * sigma * np.cos(phi3) <= 0.0:
                continue
            chord = np.sqrt(max((l1 - h * np.cos(phi3)) * (l1 + h * np.cos(phi3)), 0.0))
            for s2 in (h * np.sin(phi3) + chord, h * np.sin(phi3) - chord):
                candidates.append(float(np.arctan2(s2 * np.sin(phi3) - h, s2 * np.cos(phi3))))
    phi = np.sort(np.mod(candidates, 2.0 * np.pi))
    # A collinear position at the rod's extreme coincides with a tangent one: count it once.
    gaps = np.diff(np.append(phi, phi[0] + 2.0 * np.pi))
    phi = phi[gaps > 1e-12]
    at = shaper_motion(l1, l3, l4, h, e, phi, branch, order=0, on_degenerate="raise")
    return slider_limits_from(phi, at.s5)
