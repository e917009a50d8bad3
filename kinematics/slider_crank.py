"""Offset slider-crank: assembly, closed-form derivatives w.r.t. the crank angle, limit positions.

Conventions (``docs/cases/classic_mechanisms.md`` §2): crank pivot A = 0, crank AB = l1 at
φ1 (counter-clockwise from +x), connecting rod BC = l2 at φ2, slider C on a straight guide.
In the guide frame (x′ along the guide direction u(α)) the guide line is y′ = −e — e > 0 puts
it below A, i.e. to the right of the guide direction — and C = (s3, −e). The guide inclination
α (``guide_angle``) gives the general case P204101 of ``classic_mechanisms.json``:
C = s3·u(α) + e·u(α − 90°) = (s3 − i·e)·e^{iα}, s3 measured from the foot of the perpendicular
from A to the guide. Branch +1 (:class:`SliderBranch`) has cos(φ2 − α) > 0, −1 the mirror
assembly. Points are complex numbers (x + iy).

The kernel broadcasts its inputs (linkages as ``(N, 1)`` against crank angles ``(M,)``) and
never returns NaN/inf: positions the rod cannot reach and derivatives where the rod stands
perpendicular to the guide carry a :class:`~kinematics.status.Status` flag and finite values.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinematics.fourbar import check_lengths
from kinematics.loop import TOGGLE_EPS
from kinematics.status import AssemblyError, Status, assembly_status, check_on_degenerate, first_flagged

__all__ = [
    "SliderBranch",
    "SliderCrankMotion",
    "SliderLimits",
    "check_finite",
    "check_slider_branch",
    "slider_crank_limits",
    "slider_crank_motion",
    "slider_crank_range",
    "slider_limits_from",
    "slider_time_ratio",
]

F64 = NDArray[np.float64]
C128 = NDArray[np.complex128]
TWO_PI = 2.0 * np.pi


class SliderBranch(enum.IntEnum):
    """Assembly branch of a rod that drives a slider on a straight guide.

    ``FORWARD`` (+1): the rod points along the guide direction (cos > 0 of its angle to the
    guide), the slider lies ahead of the rod's other joint; ``BACKWARD`` (−1): the mirror
    assembly. The slider-crank's rod BC and the shaper's link DE use the same convention.
    """

    FORWARD = 1
    BACKWARD = -1


def check_finite(**values: ArrayLike) -> None:
    """Raise :class:`AssemblyError` unless every named value is finite (offsets, angles)."""
    for name, value in values.items():
        if not np.all(np.isfinite(np.asarray(value, dtype=float))):
            raise AssemblyError(f"{name} must be finite, got {value!r}")


def check_slider_branch(branch: ArrayLike) -> None:
    """Raise :class:`AssemblyError` unless every branch is +1 or −1 (:class:`SliderBranch`)."""
    b = np.asarray(branch, dtype=float)
    if not np.all((b == 1.0) | (b == -1.0)):
        raise AssemblyError(f"branch must be +1 or -1 (cos > 0 or cos < 0 of the rod), got {branch!r}")


@dataclass(frozen=True, slots=True)
class SliderCrankMotion:
    """Positions and crank-angle derivatives of an offset slider-crank, struct of arrays.

    Every array has the broadcast shape of the inputs. Derivatives are with respect to the
    crank angle φ1 (rad/rad and length/rad); :func:`kinematics.timing.time_derivatives` turns
    them into time derivatives for any crank speed and acceleration.

    Attributes
    ----------
    l1, l2 : float64, crank AB and rod BC lengths (any unit)
    e : float64, guide offset, same unit (y′ = −e in the guide frame)
    guide_angle : float64, guide inclination α (rad)
    phi1 : float64, crank angle (rad)
    branch : float64 of ±1, :class:`SliderBranch`
    phi2 : float64, rod angle arg(C − B) in (−π, π] (rad)
    s3 : float64, slider position along the guide from the foot of the perpendicular from A
    dphi2 : tuple (φ2′, φ2″)[:order], rad/rad^k
    ds3 : tuple (s3′, s3″)[:order], length/rad^k
    status : uint8, :class:`Status` flags (NOT_ASSEMBLABLE, TOGGLE)
    """

    l1: F64
    l2: F64
    e: F64
    guide_angle: F64
    phi1: F64
    branch: F64
    phi2: F64
    s3: F64
    dphi2: tuple[F64, ...]
    ds3: tuple[F64, ...]
    status: NDArray[np.uint8]

    @property
    def shape(self) -> tuple[int, ...]:
        return self.s3.shape

    @property
    def ok(self) -> NDArray[np.bool_]:
        return self.status == Status.OK

    @property
    def B(self) -> C128:
        """Crank pin B = l1·e^{iφ1}."""
        return self.l1 * np.exp(1j * self.phi1)

    @property
    def C(self) -> C128:
        """Slider joint C = (s3 − i·e)·e^{iα}."""
        return (self.s3 - 1j * self.e) * np.exp(1j * self.guide_angle)


def slider_crank_motion(
    l1: ArrayLike,
    l2: ArrayLike,
    e: ArrayLike,
    phi1: ArrayLike,
    branch: ArrayLike = SliderBranch.FORWARD,
    *,
    guide_angle: ArrayLike = 0.0,
    order: int = 2,
    on_degenerate: str = "flag",
) -> SliderCrankMotion:
    """Solve the slider-crank loop and its first ``order`` crank-angle derivatives in closed form.

    Parameters
    ----------
    l1, l2 : array_like
        Crank AB and connecting rod BC (> 0, any unit), broadcast against ``phi1``.
    e : array_like
        Offset of the guide line from A, same unit; positive to the right of the guide
        direction (below A for ``guide_angle`` = 0).
    phi1 : array_like
        Crank angle(s), radians, counter-clockwise from +x.
    branch : array_like of {+1, −1}
        :class:`SliderBranch`: sign of cos(φ2 − α).
    guide_angle : array_like
        Inclination α of the guide direction, radians (0: guide parallel to +x).
    order : {0, 1, 2}
        Highest derivative order computed.
    on_degenerate : {"flag", "raise"}
        ``"raise"`` raises :class:`AssemblyError` where the rod cannot reach the guide or a
        derivative is requested with the rod perpendicular to it; ``"flag"`` records it in
        ``status`` (positions there are finite placeholders, derivatives 0).

    Notes
    -----
    In the guide frame, with φ = φ1 − α and θ = φ2 − α, the loop
    :math:`l_1 e^{i\\varphi} + l_2 e^{i\\theta} = s_3 - i e` gives

    .. math::

        \\sin\\theta = -(e + l_1\\sin\\varphi)/l_2, \\quad
        \\cos\\theta = \\pm\\sqrt{(l_2 - q)(l_2 + q)}/l_2,\\ q = e + l_1\\sin\\varphi, \\\\
        s_3 = l_1\\cos\\varphi + l_2\\cos\\theta, \\quad
        \\theta' = -\\frac{l_1\\cos\\varphi}{l_2\\cos\\theta}, \\quad
        s_3' = -\\frac{l_1\\sin(\\varphi - \\theta)}{\\cos\\theta}, \\\\
        \\theta'' = \\frac{l_1\\sin\\varphi + l_2\\theta'^2\\sin\\theta}{l_2\\cos\\theta}, \\quad
        s_3'' = -\\frac{l_1\\cos(\\varphi - \\theta) + l_2\\theta'^2}{\\cos\\theta}.

    The product form of cos θ keeps its precision near the toggle (cos θ → 0).

    References
    ----------
    ``docs/cases/classic_mechanisms.md`` §2 (the same expressions with ω1 = 1, ε1 = 0),
    checked there against 40-digit finite differences; P204101 in ``classic_mechanisms.json``
    for the inclined guide.
    """
    mode = check_on_degenerate(on_degenerate)
    if order not in (0, 1, 2):
        raise ValueError(f"order must be 0, 1 or 2, not {order!r}")
    check_lengths(l1=l1, l2=l2)
    check_finite(e=e, phi1=phi1, guide_angle=guide_angle)
    check_slider_branch(branch)
    l1, l2, e, phi1, branch, alpha = np.broadcast_arrays(
        *(np.asarray(x, dtype=float) for x in (l1, l2, e, phi1, branch, guide_angle))
    )
    c1, s1 = np.cos(phi1 - alpha), np.sin(phi1 - alpha)
    q = e + l1 * s1  # = −l2·sin θ, the loop's y-equation
    root = (l2 - q) * (l2 + q)  # l2²·cos²θ; negative where the rod cannot reach the guide
    bad = root < 0
    sin2 = -np.clip(q / l2, -1.0, 1.0)
    cos2 = branch * np.sqrt(np.maximum(root, 0.0)) / l2
    toggle = ~bad & (np.abs(cos2) < TOGGLE_EPS)
    status = assembly_status(bad, toggle)

    ca, sa = np.cos(alpha), np.sin(alpha)
    phi2 = np.arctan2(sin2 * ca + cos2 * sa, cos2 * ca - sin2 * sa)
    s3 = l1 * c1 + l2 * cos2
    dphi2: list[F64] = []
    ds3: list[F64] = []
    if order >= 1:
        # Every derivative divides by cos θ: flagged positions get a finite 0 instead.
        inv_cos = np.divide(1.0, cos2, out=np.zeros_like(cos2), where=status == Status.OK)
        sin_12 = s1 * cos2 - c1 * sin2  # sin(φ − θ)
        t1 = -l1 * c1 * inv_cos / l2
        dphi2.append(t1)
        ds3.append(-l1 * sin_12 * inv_cos)
    if order >= 2:
        cos_12 = c1 * cos2 + s1 * sin2  # cos(φ − θ)
        dphi2.append((l1 * s1 + l2 * t1 * t1 * sin2) * inv_cos / l2)
        ds3.append(-(l1 * cos_12 + l2 * t1 * t1) * inv_cos)

    motion = SliderCrankMotion(l1, l2, e, alpha, phi1, branch, phi2, s3, tuple(dphi2), tuple(ds3), status)
    if mode == "raise":
        _raise_first_violation(motion, order)
    return motion


def _raise_first_violation(motion: SliderCrankMotion, order: int) -> None:
    """Raise :class:`AssemblyError` naming the first position that cannot be evaluated."""
    found = first_flagged(motion.status, Status.NOT_ASSEMBLABLE | (Status.TOGGLE if order else Status.OK))
    if found is None:
        return
    i, count = found
    l1, l2, e, alpha, phi1 = (float(x[i]) for x in (motion.l1, motion.l2, motion.e, motion.guide_angle, motion.phi1))
    q = e + l1 * np.sin(phi1 - alpha)
    where = f"slider-crank l1={l1:g} l2={l2:g} e={e:g} at crank angle {np.degrees(phi1):g} deg"
    if motion.status[i] & Status.NOT_ASSEMBLABLE:
        reach = _format_ranges(slider_crank_range(l1, l2, e, guide_angle=alpha))
        raise AssemblyError(
            f"{where} cannot assemble: |e + l1 sin(phi1)| = {abs(q):.6g} > l2 = {l2:g}, the rod cannot "
            f"reach the guide (a full turn needs l1 + |e| <= l2; reachable crank angles [deg]: {reach}; "
            f"{count} position(s) affected)"
        )
    raise AssemblyError(
        f"{where}: the rod is perpendicular to the guide (cos phi2 = 0, l1 + |e| = l2), so velocities are undefined"
    )


def _format_ranges(ranges: list[tuple[float, float]]) -> str:
    return ", ".join(f"[{np.degrees(lo):.6g}, {np.degrees(hi):.6g}]" for lo, hi in ranges) or "none"


def slider_crank_range(l1: float, l2: float, e: float, *, guide_angle: float = 0.0) -> list[tuple[float, float]]:
    """Crank-angle intervals (radians, start < end, start in [−π, π)) where the rod reaches the guide.

    The loop closes where |e + l1·sin(φ1 − α)| ≤ l2. A crank that turns fully (l1 + |e| ≤ l2)
    returns ``[(−π, π)]``; a rod that can never reach the guide returns ``[]``, and so does one
    that reaches it at a single crank angle only (just touching it: no interval); otherwise one
    interval (the guide line cuts the crank circle on one side only) or two mirror intervals.
    """
    check_lengths(l1=l1, l2=l2)
    check_finite(e=e, guide_angle=guide_angle)
    lo, hi = (-l2 - e) / l1, (l2 - e) / l1  # sin(φ1 − α) must lie in [lo, hi]
    if lo <= -1.0 and hi >= 1.0:
        return [(-np.pi, np.pi)]
    if lo > 1.0 or hi < -1.0:
        return []
    if lo <= -1.0:  # sin ≤ hi: one arc through −90°
        local = [(np.pi - np.arcsin(hi), TWO_PI + np.arcsin(hi))]
    elif hi >= 1.0:  # sin ≥ lo: one arc through +90°
        local = [(np.arcsin(lo), np.pi - np.arcsin(lo))]
    else:
        local = [(np.arcsin(lo), np.arcsin(hi)), (np.pi - np.arcsin(hi), np.pi - np.arcsin(lo))]
    out = []
    for start, end in local:
        if not end > start:  # the rod only touches the guide: one crank angle, no interval
            continue
        shifted = float(np.mod(start + guide_angle + np.pi, TWO_PI) - np.pi)
        out.append((shifted, shifted + float(end - start)))
    return sorted(out)


@dataclass(frozen=True, slots=True)
class SliderLimits:
    """Extreme (limit) positions of a slider over a full crank turn, where its velocity vanishes.

    Attributes
    ----------
    phi_max, phi_min : float
        Crank angles (rad, in [0, 2π)) at the largest and the smallest slider position.
    s_max, s_min : float
        Those slider positions (length unit of the input).
    stroke : float
        s_max − s_min.
    time_ratio : float
        ≥ 1: crank angle turned while the slider moves one way over the crank angle turned
        while it moves back (the quick-return ratio); independent of the crank direction.
    reversals : int
        How often the slider changes direction per turn: 2 for a classic quick-return; more
        when it stops and turns back inside a stroke.
    """

    phi_max: float
    s_max: float
    phi_min: float
    s_min: float
    stroke: float
    time_ratio: float
    reversals: int


def slider_time_ratio(phi_stationary: ArrayLike, s_stationary: ArrayLike) -> tuple[float, int]:
    """Time ratio (≥ 1) and number of reversals from every stationary position of a slider.

    ``phi_stationary`` must hold *all* crank angles of a turn where the slider velocity
    vanishes (radians) and ``s_stationary`` the slider positions there. Between two
    consecutive stationary angles the slider moves one way, from one value to the next, so
    the crank angle spent moving towards larger s and towards smaller s adds up exactly.
    """
    phi = np.mod(np.asarray(phi_stationary, dtype=float), TWO_PI)
    s = np.asarray(s_stationary, dtype=float)
    order = np.argsort(phi)
    phi, s = phi[order], s[order]
    span = np.diff(np.append(phi, phi[0] + TWO_PI))
    step = np.roll(s, -1) - s
    up, down = float(span[step > 0].sum()), float(span[step < 0].sum())
    if up <= 0.0 or down <= 0.0:
        raise ValueError("the stationary positions do not describe a slider moving back and forth")
    moves = np.sign(step[step != 0])
    reversals = int(np.count_nonzero(moves != np.roll(moves, 1)))
    return max(up, down) / min(up, down), reversals


def slider_limits_from(phi_stationary: ArrayLike, s_stationary: ArrayLike) -> SliderLimits:
    """:class:`SliderLimits` from every stationary position of a slider over a turn (radians).

    Raises :class:`AssemblyError` when the stroke vanishes in floating point (a crank some
    1e-16 times shorter than the other links): there are no limit positions to tell apart.
    """
    phi = np.mod(np.asarray(phi_stationary, dtype=float), TWO_PI)
    s = np.asarray(s_stationary, dtype=float)
    hi, lo = int(np.argmax(s)), int(np.argmin(s))
    if not s[hi] > s[lo]:
        raise AssemblyError(
            f"the slider's stroke is below floating-point resolution (it stops at s = {s[hi]:g} "
            "only): the link ratios are too extreme for limit positions"
        )
    ratio, reversals = slider_time_ratio(phi, s)
    return SliderLimits(
        float(phi[hi]), float(s[hi]), float(phi[lo]), float(s[lo]), float(s[hi] - s[lo]), ratio, reversals
    )


def slider_crank_limits(
    l1: float, l2: float, e: float, branch: int = SliderBranch.FORWARD, *, guide_angle: float = 0.0
) -> SliderLimits:
    """Dead-centre positions, stroke and time ratio of an offset slider-crank with a full-turn crank.

    The slider stops where crank and rod are collinear (s3′ ∝ sin(φ − θ) = 0): stretched, C at
    distance l1 + l2 from A, and folded, at l2 − l1, each on the guide line y′ = −e:

    .. math::

        s_{ext} = \\pm\\sqrt{(l_1 + l_2)^2 - e^2}, \\quad s_{fold} = \\pm\\sqrt{(l_2 - l_1)^2 - e^2},

    the sign being the branch; the crank points at C (stretched) or away from it (folded).
    For branch +1 the stretched position is ``s_max``.

    Raises :class:`AssemblyError` unless the crank turns fully (l1 + |e| ≤ l2).
    """
    check_lengths(l1=l1, l2=l2)
    check_finite(e=e, guide_angle=guide_angle)
    check_slider_branch(branch)
    if l1 + abs(e) > l2:
        reach = _format_ranges(slider_crank_range(l1, l2, e, guide_angle=guide_angle))
        raise AssemblyError(
            f"slider-crank limit positions need a full-turn crank: l1 + |e| = {l1 + abs(e):g} > l2 = {l2:g} "
            f"(reachable crank angles [deg]: {reach})"
        )
    # Product forms: (l ± e) factors keep precision when the rod barely reaches.
    s_ext = branch * np.sqrt(max((l1 + l2 - e) * (l1 + l2 + e), 0.0))
    s_fold = branch * np.sqrt(max((l2 - l1 - e) * (l2 - l1 + e), 0.0))
    phi_ext = np.arctan2(-e, s_ext) + guide_angle
    phi_fold = np.arctan2(-e, s_fold) + np.pi + guide_angle
    return slider_limits_from([phi_ext, phi_fold], [s_ext, s_fold])
