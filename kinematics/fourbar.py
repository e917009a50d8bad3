"""Planar four-bar: assembly, Grashof type, closed-form derivatives w.r.t. the crank angle.

Conventions (README, *Conventions*): ground pivots A0 = 0 (crank) and B0 = d on the
+x axis; crank a (A0→A), coupler b (A→B), rocker c (B0→B); crank angle φ counter-clockwise
from +x; coupler angle θ = arg(B − A), rocker angle γ = arg(B − B0). Branch +1 puts B to the
left of the directed line A→B0. Points are complex numbers (x + iy).

All kernels broadcast their inputs (linkages as ``(N, 1)`` against crank angles ``(M,)``) and
never return NaN/inf: positions that cannot assemble or derivatives at a toggle carry a
:class:`~kinematics.status.Status` flag and finite placeholder values.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinematics.loop import COINCIDENT_EPS, circle_intersection_xy
from kinematics.status import (
    AssemblyError,
    Branch,
    Status,
    check_on_degenerate,
    first_flagged,
)

__all__ = [
    "FourBarMotion",
    "GrashofType",
    "RockerLimits",
    "check_lengths",
    "crank_range",
    "fourbar_motion",
    "grashof_type",
    "rocker_limits",
    "solve_block",
    "transmission_angle",
]

#: Elements per chunk: keeps every temporary inside the L2 cache (measured: 16384 is ~2.5x
#: faster than whole-array evaluation at 36 M positions).
_CHUNK = 16384

F64 = NDArray[np.float64]
C128 = NDArray[np.complex128]


class GrashofType(enum.IntEnum):
    """Grashof classification with the crank (link a) as the input link.

    s + l < p + q is Grashof; the shortest link decides the type. ``ROCKER_CRANK`` has the
    rocker shortest (the input cannot turn fully), ``TRIPLE_ROCKER`` is every non-Grashof
    linkage, ``CHANGE_POINT`` has s + l = p + q (it can fold flat).
    """

    CRANK_ROCKER = 1
    DOUBLE_CRANK = 2
    DOUBLE_ROCKER = 3
    ROCKER_CRANK = 4
    TRIPLE_ROCKER = 5
    CHANGE_POINT = 6

    @property
    def label(self) -> str:
        return self.name.lower().replace("_", "-")


def check_lengths(**lengths: ArrayLike) -> None:
    """Raise :class:`AssemblyError` unless every named length is finite and > 0."""
    for name, value in lengths.items():
        arr = np.asarray(value, dtype=float)
        if not np.all(np.isfinite(arr)):
            raise AssemblyError(f"length {name} must be finite, got {value!r}")
        if np.any(arr <= 0):
            raise AssemblyError(f"length {name} must be > 0, got {value!r}")


def grashof_type(a: ArrayLike, b: ArrayLike, c: ArrayLike, d: ArrayLike, *, rtol: float = 1e-12) -> NDArray[np.int8]:
    """Grashof type (values of :class:`GrashofType`) of broadcast link lengths.

    ``rtol`` is the relative tolerance on s + l = p + q that counts as a change point.
    """
    links = np.stack(np.broadcast_arrays(*(np.asarray(x, float) for x in (a, b, c, d))), axis=-1)
    srt = np.sort(links, axis=-1)
    s, p, q, l = srt[..., 0], srt[..., 1], srt[..., 2], srt[..., 3]
    excess = (s + l) - (p + q)
    scale = links.sum(axis=-1)
    change = np.abs(excess) <= rtol * scale
    grashof = excess < 0
    shortest = np.argmin(links, axis=-1)  # 0 crank, 1 coupler, 2 rocker, 3 ground
    by_shortest = np.array(
        [GrashofType.CRANK_ROCKER, GrashofType.DOUBLE_ROCKER, GrashofType.ROCKER_CRANK, GrashofType.DOUBLE_CRANK],
        dtype=np.int8,
    )
    out = np.where(grashof, by_shortest[shortest], np.int8(GrashofType.TRIPLE_ROCKER))
    return np.where(change, np.int8(GrashofType.CHANGE_POINT), out).astype(np.int8)


def crank_range(a: float, b: float, c: float, d: float) -> list[tuple[float, float]]:
    """Crank-angle intervals (radians, start < end, start in [−π, π)) where the loop closes.

    The loop closes where b − c ≤ |R(φ)| ≤ b + c with |R|² = a² + d² − 2ad·cos φ. A fully
    rotating crank returns ``[(−π, π)]``; a linkage that never closes returns ``[]``. Grashof
    rocker-cranks and double-rockers give two mirror intervals, one per assembly circuit.
    """
    check_lengths(a=a, b=b, c=c, d=d)
    # cos φ must lie in [lo, hi]
    hi = (a * a + d * d - (b - c) ** 2) / (2 * a * d)  # from |R| >= |b − c|
    lo = (a * a + d * d - (b + c) ** 2) / (2 * a * d)  # from |R| <= b + c
    lo, hi = max(lo, -1.0), min(hi, 1.0)
    if lo > hi:
        return []
    phi_hi = float(np.arccos(lo))  # largest |φ| allowed
    phi_lo = float(np.arccos(hi))  # smallest |φ| allowed
    if phi_lo == 0.0 and phi_hi == np.pi:
        return [(-np.pi, np.pi)]
    if phi_lo == 0.0:
        return [(-phi_hi, phi_hi)]
    if phi_hi == np.pi:
        return [(phi_lo, 2 * np.pi - phi_lo)] if phi_lo > 0 else [(-np.pi, np.pi)]
    return [(-phi_hi, -phi_lo), (phi_lo, phi_hi)]


@dataclass(frozen=True, slots=True)
class FourBarMotion:
    """Positions and crank-angle derivatives of a four-bar, struct of arrays.

    ``e_theta``, the derivatives and ``status`` have the broadcast shape of the inputs; the
    inputs ``a, b, c, d, phi, branch`` are kept as given (broadcastable to it). Derivatives
    are with respect to the crank angle φ (rad/rad); :func:`kinematics.timing.time_derivatives`
    turns them into time derivatives.

    Attributes
    ----------
    a, b, c, d : float64 arrays, link lengths (any unit)
    phi : float64 array, crank angle (rad)
    branch : float64 array of ±1, assembly branch (:class:`Branch`)
    e_theta : complex128, unit phasor e^{iθ} of the coupler (A→B)
    dtheta, dgamma : tuples (θ′, θ″, θ‴)[:order], (γ′, γ″, γ‴)[:order]
    status : uint8, :class:`Status` flags (NOT_ASSEMBLABLE, TOGGLE)
    """

    a: F64
    b: F64
    c: F64
    d: F64
    phi: F64
    branch: F64
    e_theta: C128
    dtheta: tuple[F64, ...]
    dgamma: tuple[F64, ...]
    status: NDArray[np.uint8]

    @property
    def shape(self) -> tuple[int, ...]:
        return self.e_theta.shape

    @property
    def A(self) -> C128:
        """Crank pin A = a·e^{iφ}."""
        return self.a * np.exp(1j * self.phi)

    @property
    def B(self) -> C128:
        """Coupler–rocker joint B = A + b·e^{iθ}."""
        return self.A + self.b * self.e_theta

    @property
    def e_gamma(self) -> C128:
        """Unit phasor e^{iγ} = (B − B0)/c of the rocker."""
        return (self.B - self.d) / self.c

    @property
    def theta(self) -> F64:
        """Coupler angle θ = arg(B − A) in (−π, π]."""
        return np.angle(self.e_theta)

    @property
    def gamma(self) -> F64:
        """Rocker angle γ = arg(B − B0) in (−π, π]."""
        return np.angle(self.e_gamma)

    @property
    def sin_theta_gamma(self) -> F64:
        """sin(θ − γ), signed; zero at a toggle of coupler and rocker."""
        return (self.e_theta * np.conj(self.e_gamma)).imag

    @property
    def ok(self) -> NDArray[np.bool_]:
        return self.status == Status.OK

    def coupler_point(self, u: ArrayLike, v: ArrayLike, order: int = 0) -> tuple[C128, ...]:
        """Path of the coupler point p = u + iv (coupler frame: origin A, x-axis A→B).

        Returns ``(z, z′, z″, z‴)[: order + 1]``, complex128, derivatives w.r.t. φ
        (docs/curvature.md §1: z = A + w, w = e^{iθ}p; z′ = A′ + iθ′w; z″ = A″ + (iθ″ − θ′²)w;
        z‴ = A‴ + (iθ‴ − 3θ′θ″ − iθ′³)w). ``u, v`` broadcast against the motion's shape.
        """
        if order > len(self.dtheta):
            raise ValueError(f"coupler_point order {order} needs a motion computed with order >= {order}")
        eA = self.A
        w = self.e_theta * (np.asarray(u, float) + 1j * np.asarray(v, float))
        out = [eA + w]
        if order >= 1:
            t1 = self.dtheta[0]
            out.append(1j * eA + 1j * t1 * w)
        if order >= 2:
            t2 = self.dtheta[1]
            out.append(-eA + (1j * t2 - t1 * t1) * w)
        if order >= 3:
            t3 = self.dtheta[2]
            out.append(-1j * eA + (1j * (t3 - t1**3) - 3 * t1 * t2) * w)
        return tuple(out)


def fourbar_motion(
    a: ArrayLike,
    b: ArrayLike,
    c: ArrayLike,
    d: ArrayLike,
    phi: ArrayLike,
    branch: ArrayLike = Branch.LEFT,
    *,
    order: int = 3,
    on_degenerate: str = "flag",
) -> FourBarMotion:
    """Solve the four-bar loop and its first ``order`` crank-angle derivatives in closed form.

    Parameters
    ----------
    a, b, c, d : array_like
        Crank, coupler, rocker, ground lengths (> 0, any unit), broadcast against ``phi``.
    phi : array_like
        Crank angle(s), radians, counter-clockwise from +x.
    branch : array_like of {+1, −1}
        Assembly branch (:class:`Branch`).
    order : {0, 1, 2, 3}
        Highest derivative order computed.
    on_degenerate : {"flag", "raise"}
        ``"raise"`` raises :class:`AssemblyError` where the loop cannot close or a derivative
        is requested at a toggle; ``"flag"`` records it in ``status``.

    Notes
    -----
    Position from the triangle A, B, B0 with R = d − a·e^{iφ} (the vector A→B0), the
    circle–circle intersection of :func:`kinematics.loop.circle_intersection` (radius b about
    A, c about B0): e^{iθ} = (R/|R|)·(cos β + i·branch·sin β), cos β = (b² + |R|² − c²)/(2b|R|),
    sin β in Heron's form (no cancellation near toggles); e^{iγ} = (b·e^{iθ} − R)/c.

    Derivatives solve i·b·x·e^{iθ} − i·c·y·e^{iγ} = Q_k (docs/curvature.md §1,
    :meth:`kinematics.loop.CircleIntersection.rates`):
    x = −Re(Q_k e^{−iγ})/(b sin(θ−γ)), y = −Re(Q_k e^{−iθ})/(c sin(θ−γ)), with
    Q_1 = R′, Q_2 = R″ + bθ′²e^{iθ} − cγ′²e^{iγ},
    Q_3 = R‴ + b(3θ′θ″ + iθ′³)e^{iθ} − c(3γ′γ″ + iγ′³)e^{iγ}.

    References
    ----------
    ``docs/curvature.md`` §1 (checked there against 40-digit arithmetic).
    """
    mode = check_on_degenerate(on_degenerate)
    if order not in (0, 1, 2, 3):
        raise ValueError(f"order must be 0, 1, 2 or 3, not {order!r}")
    arrays = [np.asarray(x, dtype=float) for x in (a, b, c, d, phi, branch)]
    shape = np.broadcast(*arrays).shape  # far cheaper than np.broadcast_shapes for small calls
    ndim = len(shape)
    arrays = [x if x.ndim == ndim else x.reshape((1,) * (ndim - x.ndim) + x.shape) for x in arrays]

    e_theta = np.empty(shape, np.complex128)
    status = np.empty(shape, np.uint8)
    derivs = [np.empty(shape) for _ in range(2 * order)]

    # Chunk along the leading axis so that temporaries stay in cache.
    if ndim == 0:
        solve_block(*arrays, order, e_theta[...], status[...], [g[...] for g in derivs])
    else:
        inner = max(1, math.prod(shape[1:]))
        step = max(1, _CHUNK // inner)
        for i in range(0, shape[0], step):
            sl = slice(i, i + step)
            parts = [x[sl] if x.shape[0] > 1 else x for x in arrays]
            solve_block(*parts, order, e_theta[sl], status[sl], [g[sl] for g in derivs])

    motion = FourBarMotion(*arrays, e_theta, tuple(derivs[0::2]), tuple(derivs[1::2]), status)
    if mode == "raise":
        _raise_first_violation(motion, order)
    return motion


def _raise_first_violation(motion: FourBarMotion, order: int) -> None:
    """Raise :class:`AssemblyError` naming the first position that cannot be evaluated."""
    found = first_flagged(motion.status, Status.NOT_ASSEMBLABLE | (Status.TOGGLE if order else Status.OK))
    if found is None:
        return
    i, count = found
    pick = lambda x: float(np.broadcast_to(x, motion.shape)[i])  # noqa: E731
    a, b, c, d, phi = (pick(x) for x in (motion.a, motion.b, motion.c, motion.d, motion.phi))
    where = f"four-bar a={a:g} b={b:g} c={c:g} d={d:g} at crank angle {np.degrees(phi):g} deg"
    if motion.status[i] & Status.NOT_ASSEMBLABLE:
        r = abs(d - a * np.exp(1j * phi))
        if r <= COINCIDENT_EPS * (b + c):  # within [|b-c|, b+c], yet the loop has no direction
            raise AssemblyError(
                f"{where} cannot be solved: |A-B0| = {r:.6g} is under {COINCIDENT_EPS:g} of b+c = {b + c:g}, "
                f"so the directions of coupler and rocker are undetermined ({count} position(s) affected)"
            )
        ranges = crank_range(a, b, c, d)
        reach = ", ".join(f"[{np.degrees(lo):.4g}, {np.degrees(hi):.4g}]" for lo, hi in ranges) or "none"
        raise AssemblyError(
            f"{where} cannot assemble: |A-B0| = {r:.6g} is outside [|b-c|, b+c] = "
            f"[{abs(b - c):g}, {b + c:g}] (reachable crank angles [deg]: {reach}; {count} position(s) affected)"
        )
    raise AssemblyError(f"{where}: coupler and rocker are aligned (toggle), so velocities are undefined")


def solve_block(a, b, c, d, phi, branch, order, e_theta, status, derivs) -> None:
    """Closed-form position and derivatives for one cache-sized block (see fourbar_motion),
    written into ``e_theta``, ``status`` and ``derivs`` ((θ′, γ′, θ″, γ″, θ‴, γ‴)[: 2·order]).

    Any float dtype: the inputs' precision is kept (``dwell bench kinematics`` runs it in
    longdouble as the reference for the float64 kernel)."""
    cphi, sphi = np.cos(phi), np.sin(phi)
    acp, asp = a * cphi, a * sphi
    # The loop A + b·e^{iθ} = B0 + c·e^{iγ}: circles about A (radius b) and B0 (radius c),
    # R = B0 − A = (d − a cos φ, −a sin φ).
    loop = circle_intersection_xy(d - acp, -asp, b, c, branch, rates=order > 0)
    ct, st = loop.cos1, loop.sin1
    e_theta.real, e_theta.imag = ct, st
    status[...] = loop.status
    if order == 0:
        return
    cg, sg = loop.cos2, loop.sin2

    def solve(qx, qy, k):
        return loop.rates_xy(qx, qy, out=(derivs[2 * k], derivs[2 * k + 1]))

    # Q1 = R' = -i a e^{iφ}
    t1, g1 = solve(asp, -acp, 0)
    if order == 1:
        return
    bt2, cg2 = b * (t1 * t1), c * (g1 * g1)
    t2, g2 = solve(acp + (bt2 * ct - cg2 * cg), asp + (bt2 * st - cg2 * sg), 1)
    if order == 2:
        return
    # b(3θ′θ″ + iθ′³)e^{iθ} − c(3γ′γ″ + iγ′³)e^{iγ}, added to R‴ = i a e^{iφ}
    pt, qt = (3.0 * b) * (t1 * t2), bt2 * t1
    pg, qg = (3.0 * c) * (g1 * g2), cg2 * g1
    solve(
        (pt * ct - qt * st) - (pg * cg - qg * sg) - asp,
        (pt * st + qt * ct) - (pg * sg + qg * cg) + acp,
        2,
    )


def transmission_angle(motion: FourBarMotion) -> F64:
    """Transmission angle μ ∈ [0, π] between coupler (A→B) and rocker (B0→B), radians.

    The design quality is min(μ, π − μ); 90° is ideal.
    """
    cos_mu = (motion.e_theta * np.conj(motion.e_gamma)).real
    return np.arccos(np.clip(cos_mu, -1.0, 1.0))


@dataclass(frozen=True, slots=True)
class RockerLimits:
    """Extreme positions of the rocker of a crank-rocker (crank and coupler collinear).

    Angles in radians. ``phi_extended`` / ``gamma_extended``: crank and coupler stretched
    out (|A0B| = a + b); ``*_folded``: folded (|A0B| = b − a). ``swing`` = |Δγ|;
    ``time_ratio`` ≥ 1 is the longer over the shorter crank interval between the two.
    """

    phi_extended: float
    gamma_extended: float
    phi_folded: float
    gamma_folded: float
    swing: float
    time_ratio: float


def rocker_limits(a: float, b: float, c: float, d: float, branch: int = Branch.LEFT) -> RockerLimits:
    """Rocker dead-centre positions, swing and time ratio of a crank-rocker.

    At a limit the rocker velocity vanishes, i.e. crank and coupler are collinear and B lies at
    distance L = b ± a from A0 on the rocker circle: cos α = (d² + L² − c²)/(2dL) gives
    B = L·e^{±iα}; the sign that the given branch reaches is kept.

    Raises :class:`AssemblyError` unless the linkage is a crank-rocker.
    """
    check_lengths(a=a, b=b, c=c, d=d)
    kind = GrashofType(int(grashof_type(a, b, c, d)))
    if kind is not GrashofType.CRANK_ROCKER:
        raise AssemblyError(f"rocker limit positions need a crank-rocker; this linkage is {kind.label}")
    out = []
    for L, flip in ((b + a, 0.0), (b - a, np.pi)):
        cos_alpha = np.clip((d * d + L * L - c * c) / (2 * d * L), -1.0, 1.0)
        alpha = np.arccos(cos_alpha) * np.array([1.0, -1.0])
        phis = alpha + flip  # crank along +B̂ (extended) or −B̂ (folded)
        motion = fourbar_motion(a, b, c, d, phis, branch, order=0)
        B_expected = L * np.exp(1j * alpha)
        k = int(np.argmin(np.abs(motion.B - B_expected)))
        out.append((float(np.mod(phis[k], 2 * np.pi)), float(motion.gamma[k])))
    (p_ext, g_ext), (p_fold, g_fold) = out
    fwd = float(np.mod(p_ext - p_fold, 2 * np.pi))
    ratio = max(fwd, 2 * np.pi - fwd) / min(fwd, 2 * np.pi - fwd)
    swing = abs(float(np.angle(np.exp(1j * (g_ext - g_fold)))))
    return RockerLimits(p_ext, g_ext, p_fold, g_fold, swing, ratio)
