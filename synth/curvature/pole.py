"""The pole (instant centre) of the coupler motion and its derivatives: the instantaneous
invariants every other curvature quantity is built from.

All quantities are derivatives with respect to the crank angle φ (docs/curvature.md §1–2); points
are complex numbers in the fixed frame (A0 = 0, B0 = d on the +x axis). Kernels broadcast
like :func:`kinematics.fourbar.fourbar_motion` and never return NaN/inf: degenerate instants
carry :class:`~kinematics.status.Status` flags in a ``uint16`` status array (``synth/`` uses
the ``AT_POLE`` bit, which does not fit the four-bar's ``uint8``) and finite placeholders (0).

Relative thresholds
-------------------
Every threshold is relative, so that a linkage and its scaled copy get the same flags:

* ``FAR``: a point farther than ``FAR · L`` from the crank pin, L = max(a, b, c, d), is "at
  infinity".
* ``POLE_FAR``: the pole is at infinity beyond ``POLE_FAR · L``, i.e. |θ′| < a/(POLE_FAR·L).
  The relative error of θ′ grows like ε_mach/|θ′|, so the pole's absolute error grows like
  ε_mach·a²/(L·θ′²); circle and centre points near the linkage are reached from the pole
  along rays and inherit it. Measured (``dwell bench stability``): with the bound at 1e6·L,
  centre points near the linkage reached from a pole 1e5 cranks away were off by 7e-7 of a
  crank; with 1e3·L the worst is ~3e-8 (change-point linkages near ``MAX_CONDITION``).
* ``MAX_CONDITION``: the loop's condition number L/(min(b, c)·|sin(θ − γ)|) above it is
  flagged ``ILL_CONDITIONED``. The invariants need θ‴, and the float64 loop loses digits near
  a toggle (|R| ≈ b ± c cancels) and when the coupler or rocker is tiny against the other
  links. Measured on ``dwell bench stability`` (link ratios 1e-3…1e3, change points, 1e-9 rad
  from toggles; 4 × 100 000 cases): with 100 the unflagged poles, inflection circles, Ball
  points and circle points stay within ~1e-9 of a crank; 300 lets 2e-7 through. The
  four-bar kernel's own ``TOGGLE_EPS`` only guards its division.
* ``COLLAPSE``: |Z2| ≤ COLLAPSE·a·(1 + |θ′|) is a collapsed inflection circle (θ′ = 1 and
  θ″ = 0 at once); below it the direction of the pole normal is lost to rounding.
* ``RAY_EPS``: a ray within this angle (rad) of the pole tangent or normal meets the cubic of
  stationary curvature at the pole (line scanning; Ball's point at a rocker dead-centre).

Rounding-error estimate of θ′, θ″, θ‴
-------------------------------------
``Pole.dtheta_error`` is a first-order estimate of the absolute float64 error of the coupler
angle's derivatives, from which :func:`synth.curvature.line_scan.line_scan` estimates the error of each
conjugate pair (see ``synth.curvature.line_scan.ACCURACY``). With κ the loop condition (above),
D = b·|sin(θ − γ)| and the magnitudes of the terms of the derivative systems of docs/curvature.md §1,

    T1 = a/D,   T2 = (a + b·θ′² + c·γ′²)/D,
    T3 = (a + b·(3|θ′θ″| + |θ′|³) + c·(3|γ′γ″| + |γ′|³))/D,
    S1 = (b|θ′| + c|γ′|)/D,   S2 = (b|θ″| + c|γ″| + b·θ′² + c·γ′²)/D,

the estimates are (S1, S2 carry the error of the lower orders into the higher ones)

    δθ′ = E·κ·(T1 + κ|θ′|),   δθ″ = E·κ²·(T2 + 2·S1·T1),   δθ‴ = E·κ²·(T3 + 3·S1·T2 + 3·S2·T1),

with E = ``DTHETA_ERROR_UNIT`` = 2ε (ε = 2.2e-16). The solved angle carries the error of a
position that is itself conditioned like κ, hence one power of κ more than the terms alone.
Measured (``dwell bench stability``, seeds 0–4 × 100 000 cases, unflagged instants, against the
extended-precision reference, with two versions of the four-bar kernel: projections on e^{iγ}
taken from the phasors, and in closed form): the true error over the estimate is at most 1.04, 0.66 and 0.92 for θ′, θ″, θ‴
(median 0.01–0.03: it is meant as a bound, not as a typical value); without the carried terms
S1, S2 it reaches 2 for θ″ and 14 for θ‴ near change points, with κ instead of κ² 16 and 26.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinematics.fourbar import FourBarMotion
from kinematics.status import Status, check_on_degenerate, raise_on_flags
from synth.types import ANY_FLAG, C128, F64, MAX_CONDITION, U16

__all__ = ["COLLAPSE", "DTHETA_ERROR_UNIT", "POLE_FAR", "Pole", "loop_condition", "pole"]

#: A pole farther than ``POLE_FAR`` × linkage size from the crank pin is at infinity (see module notes).
POLE_FAR = 1e3
#: Relative size of |Z2| below which the inflection circle has collapsed (see module notes).
COLLAPSE = 1e-7
#: Rounding unit of the error estimate ``Pole.dtheta_error`` (two units of float64 rounding;
#: see the module notes for the model and the measurement behind it).
DTHETA_ERROR_UNIT = 2.0 * float(np.finfo(float).eps)


@dataclass(frozen=True, slots=True)
class Pole:
    """Instant centre and the pole derivatives Z2, Z3 at each (linkage, crank angle).

    Arrays have the motion's broadcast shape. Lengths are in the linkage's unit; derivatives
    are per radian of crank angle.

    Attributes
    ----------
    point : complex128
        Pole I (instant centre of the coupler), fixed frame.
    crank_pin : complex128
        Crank pin A = a·e^{iφ} (origin of the coupler frame).
    e_theta : complex128
        Coupler phasor e^{iθ} (x-axis of the coupler frame).
    dtheta : (θ′, θ″, θ‴), float64
        Coupler angle derivatives w.r.t. φ (rad/rad).
    z2, z3 : complex128
        Second and third φ-derivatives of the coupler point that coincides with the pole
        ("pole acceleration and jerk"), length/rad² and length/rad³.
    size : float64
        Linkage size L = max(a, b, c, d), broadcastable to the motion's shape: the length
        scale of the relative thresholds.
    status : uint16
        :class:`Status` flags: those of the motion, plus ``POLE_AT_INFINITY``,
        ``INFLECTION_CIRCLE_COLLAPSED`` and ``ILL_CONDITIONED`` (``MAX_CONDITION``).
        Where the pole is at infinity or the motion is flagged, ``point``, ``z2`` and ``z3``
        are 0 placeholders.
    dtheta_error : (δθ′, δθ″, δθ‴), float64
        First-order estimates of the absolute rounding error of ``dtheta`` (see the module
        notes), ≥ 0; 0 placeholders where ``point`` is one.
    """

    point: C128
    crank_pin: C128
    e_theta: C128
    dtheta: tuple[F64, F64, F64]
    z2: C128
    z3: C128
    size: F64
    status: U16
    dtheta_error: tuple[F64, F64, F64]

    @property
    def shape(self) -> tuple[int, ...]:
        return self.point.shape

    @property
    def ok(self) -> NDArray[np.bool_]:
        return self.status == Status.OK

    @property
    def normal(self) -> C128:
        """Unit pole normal Z2/|Z2|: from the pole towards the inflection pole (1 where collapsed)."""
        mag = np.abs(self.z2)
        return np.divide(self.z2, mag, out=np.ones_like(self.z2), where=mag > 0)

    @property
    def tangent(self) -> C128:
        """Unit pole tangent: direction in which the pole moves along the fixed centrode as φ grows.

        From I′ = i·Z2/θ′ (differentiate I = A + i·A′/θ′), so tangent = i·sign(θ′)·normal.
        """
        return 1j * np.where(self.dtheta[0] < 0, -1.0, 1.0) * self.normal

    def to_coupler(self, z: ArrayLike) -> C128:
        """Fixed-frame points z → coupler frame p = e^{−iθ}(z − A) (origin A, x-axis A→B)."""
        return np.conj(self.e_theta) * (np.asarray(z, np.complex128) - self.crank_pin)

    def to_fixed(self, p: ArrayLike) -> C128:
        """Coupler-frame points p → fixed frame z = A + e^{iθ}p."""
        return self.crank_pin + self.e_theta * np.asarray(p, np.complex128)


def loop_condition(motion: FourBarMotion) -> F64:
    """Condition number L/(min(b, c)·|sin(θ − γ)|) of the loop at each position, motion's shape.

    L = max(a, b, c, d); ≥ 1, and the largest float at an exact toggle (never inf). It grows
    as the coupler and rocker align and as either of them gets small against the linkage:
    both make the coupler angle's derivatives lose digits.
    """
    size = np.maximum(np.maximum(motion.a, motion.b), np.maximum(motion.c, motion.d))
    return _condition(motion, size, np.abs(motion.sin_theta_gamma))


def _condition(motion: FourBarMotion, size, abs_sin) -> F64:
    """:func:`loop_condition` from L and |sin(θ − γ)| computed by the caller."""
    lever = np.minimum(motion.b, motion.c) * abs_sin
    with np.errstate(divide="ignore", over="ignore"):
        return np.minimum(size / lever, np.finfo(float).max)


def _dtheta_error(motion: FourBarMotion, kappa, abs_sin, bad) -> tuple[F64, F64, F64]:
    """First-order error estimates (δθ′, δθ″, δθ‴) of the module notes; 0 where ``bad``."""
    a, b, c = motion.a, motion.b, motion.c
    t1, t2 = np.abs(motion.dtheta[0]), np.abs(motion.dtheta[1])
    g1, g2 = np.abs(motion.dgamma[0]), np.abs(motion.dgamma[1])
    inv_d = np.divide(1.0, b * abs_sin, out=np.zeros(bad.shape), where=~bad)
    u1, v1 = b * t1, c * g1
    t_1 = a * inv_d  # T1
    s_1 = (u1 + v1) * inv_d  # S1
    vel = (u1 * t1 + v1 * g1) * inv_d  # (b·θ′² + c·γ′²)/D
    t_2 = vel + t_1  # T2
    t_3 = (u1 * (3.0 * t2 + t1 * t1) + v1 * (3.0 * g2 + g1 * g1)) * inv_d + t_1  # T3
    s_2 = (b * t2 + c * g2) * inv_d + vel  # S2
    kap = np.where(bad, 0.0, kappa)
    k = kap * DTHETA_ERROR_UNIT
    kk = k * kap
    e1 = k * t_1 + kk * t1
    e2 = kk * (t_2 + 2.0 * s_1 * t_1)
    e3 = kk * (t_3 + 3.0 * (s_1 * t_2 + s_2 * t_1))
    return e1, e2, e3


def pole(motion: FourBarMotion, *, on_degenerate: str = "flag") -> Pole:
    """Pole, pole derivatives and degeneracy flags of a four-bar's coupler motion.

    Parameters
    ----------
    motion : FourBarMotion
        From :func:`kinematics.fourbar.fourbar_motion` with ``order=3``.
    on_degenerate : {"flag", "raise"}
        ``"raise"`` raises :class:`~kinematics.status.AssemblyError` if any instant is flagged.

    Returns
    -------
    Pole
        Arrays of ``motion.shape``.

    Notes
    -----
    With E = a·e^{iφ} (so A′ = iE, A″ = −E, A‴ = −iE), the pole offset from the crank pin
    w_P = i·A′/θ′ and the pole derivatives of docs/curvature.md §2 simplify to

    .. math::

        w_P = -E/θ', \\quad I = A + w_P,\\quad
        Z_2 = -E\\,\\bigl(1 - θ' + iθ''/θ'\\bigr),\\quad
        Z_3 = -E\\,\\bigl(-3θ'' + i(1 + θ'''/θ' - θ'^2)\\bigr),

    which avoids forming the large w_P twice when θ′ is small.

    References
    ----------
    ``docs/curvature.md`` §2 (pole, Z2, Z3), checked against 40-digit arithmetic in
    ``tests/synth/test_accuracy.py``.
    """
    mode = check_on_degenerate(on_degenerate)
    if len(motion.dtheta) < 3:
        raise ValueError("pole needs a motion computed with order=3")
    t1, t2, t3 = (np.asarray(x, float) for x in motion.dtheta)
    a = np.asarray(motion.a, float)
    size = np.maximum(np.maximum(a, motion.b), np.maximum(motion.c, motion.d))
    E = motion.A
    status = motion.status.astype(np.uint16)
    abs_sin = np.abs(motion.sin_theta_gamma)
    kappa = _condition(motion, size, abs_sin)
    ill = (kappa > MAX_CONDITION) & (status == 0)
    status |= np.where(ill, np.uint16(Status.ILL_CONDITIONED), np.uint16(0))
    far = (np.abs(t1) * (POLE_FAR * size) <= a) & (status == 0)
    status |= np.where(far, np.uint16(Status.POLE_AT_INFINITY), np.uint16(0))
    bad = status != 0
    inv_t1 = np.divide(1.0, t1, out=np.zeros_like(t1 * E.real), where=~bad)
    z2 = -E * ((1.0 - t1) + 1j * (t2 * inv_t1))
    z3 = -E * (-3.0 * t2 + 1j * (1.0 + t3 * inv_t1 - t1 * t1))
    collapsed = (np.abs(z2) <= COLLAPSE * a * (1.0 + np.abs(t1))) & ~bad
    status |= np.where(collapsed, np.uint16(Status.INFLECTION_CIRCLE_COLLAPSED), np.uint16(0))
    point = np.where(bad, 0j, E * (1.0 - inv_t1))
    z2 = np.where(bad, 0j, z2)
    z3 = np.where(bad, 0j, z3)
    error = _dtheta_error(motion, kappa, abs_sin, bad)
    out = Pole(point, E, motion.e_theta, (t1, t2, t3), z2, z3, np.asarray(size, float), status, error)
    if mode == "raise":
        raise_on_flags(status, "pole of the coupler motion", ANY_FLAG)
    return out
