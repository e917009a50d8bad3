"""Velocities and accelerations of every link, joint and point: J·q̇ = E and J·q̈ = C.

Coordinates q: the pose (x_i, y_i, θ_i) of every moving link i (Cartesian coordinates,
Nikravesh). Constraints Φ(q, t) = 0, two per lower pair and one per input:

* revolute pair (links i, j at local points p_i, p_j): r_i + e_i·p_i − r_j − e_j·p_j = 0;
* prismatic pair (guide g: line through q along u; block b: point o, direction w):
  θ_b − θ_g − arg(u·w̄) = 0 and Im(Ū·d) = 0 with U = e_g·u, d = r_b + e_b·o − r_g − e_g·q;
* input: θ_link − θ_relative_to − φ(t) = 0, or s(q) − s_in(t) = 0 with s = Re(Ū·d).

Differentiating once gives J·q̇ = E (E = the input rates on the input rows, 0 elsewhere);
twice gives J·q̈ = C, C = −(J̇·q̇) plus the input accelerations: for a revolute pair
C = θ̇_i²·e_i·p_i − θ̇_j²·e_j·p_j; for the guide line and a slide input C = −Im Z and
s̈_in − Re Z with Z = conj(Ü₀)·d + 2·conj(U̇)·ḋ + Ū·d̈₀, U̇ = iθ̇_g·U, Ü₀ = −θ̇_g²·U,
d̈₀ = −θ̇_b²·e_b·o + θ̇_g²·e_g·q. The angle columns are scaled by the linkage size L (and
the angle rows likewise), so that the singular values of J compare lengths with lengths; a
position where σ_min/σ_max < 1e-10 is singular (a toggle or dead centre, or a triad at a
singularity): its velocities are finite placeholders (0) and its status carries TOGGLE.

References
----------
P. E. Nikravesh, *Computer-Aided Analysis of Mechanical Systems*, Prentice Hall 1988,
ch. 3–4 (absolute coordinates, the velocity and acceleration equations).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinematics.assur.model import Linkage, PrismaticPair, RevolutePair
from kinematics.assur.positions import Assembly
from kinematics.status import Status

__all__ = ["LinkageMotion", "linkage_motion"]

#: σ_min/σ_max of the scaled Jacobian below which a position is singular.
SINGULAR_RATIO = 1e-10


@dataclass(frozen=True, slots=True)
class LinkageMotion:
    """Positions, velocities and accelerations of every link (struct of arrays over M positions).

    Attributes
    ----------
    assembly : Assembly
        Positions (link poses r, e; inputs; status).
    v, a : complex128 (M, n)
        Velocity and acceleration of each link frame's origin (length/s, length/s²).
    omega, alpha : float64 (M, n)
        Angular velocity and acceleration of each link (rad/s, rad/s²), counter-clockwise +.
    s, ds, dds : float64 (M, P)
        Displacement, velocity, acceleration of every prismatic pair (in ``linkage.pairs``
        order of the prismatic ones), s measured from the guide's ``through`` point.
    status : uint8 (M,)
        The assembly's flags, plus TOGGLE where J is singular (velocities there are 0).
    condition : float64 (M,)
        σ_min/σ_max of the scaled Jacobian (0 where the linkage does not assemble).
    """

    assembly: Assembly
    v: np.ndarray
    a: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    s: np.ndarray
    ds: np.ndarray
    dds: np.ndarray
    status: np.ndarray
    condition: np.ndarray

    def point(self, link: int, p: complex) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration of local point ``p`` of ``link``, each (M,)."""
        w = self.assembly.e[:, link] * p
        vel = self.v[:, link] + 1j * self.omega[:, link] * w
        acc = self.a[:, link] + (1j * self.alpha[:, link] - self.omega[:, link] ** 2) * w
        return self.assembly.r[:, link] + w, vel, acc


class _System:
    """Rows of J (M, N, N), right-hand sides E and C, for the moving links' coordinates."""

    def __init__(self, linkage: Linkage, M: int):
        self.L = linkage.length_scale
        self.n = len(linkage.links) - 1
        N = 3 * self.n
        self.J = np.zeros((M, N, N))
        self.rhs = np.zeros((M, N))
        self.row = 0

    def cols(self, link: int):
        base = 3 * (link - 1)
        return base, base + 1, base + 2

    def add(self, part: str, terms: list[tuple[int, np.ndarray, np.ndarray]], rhs) -> None:
        """One row: the real (``part="re"``) or imaginary part of Σ c_r·δr + c_θ·δθ."""
        take = np.real if part == "re" else np.imag
        for link, c_r, c_theta in terms:
            if link == 0:
                continue
            x, y, t = self.cols(link)
            self.J[:, self.row, x] += take(c_r)
            self.J[:, self.row, y] += take(c_r * 1j)
            self.J[:, self.row, t] += take(c_theta) / self.L  # angle column scaled by L
        self.rhs[:, self.row] = rhs
        self.row += 1


def _pair_terms(pair: PrismaticPair, asm: Assembly):
    """For a prismatic pair: U, d, and the pieces of its rows (see module notes)."""
    g, b = pair.guide, pair.block
    eg, eb = asm.e[:, g], asm.e[:, b]
    U = eg * pair.direction
    q, o = eg * pair.through, eb * pair.block_point
    d = asm.r[:, b] + o - asm.r[:, g] - q
    return g, b, U, d, q, o


def _build(linkage: Linkage, asm: Assembly, omega, v, rates, accels, second: bool) -> _System:
    M = asm.r.shape[0]
    sysm = _System(linkage, M)
    L = sysm.L
    zero = np.zeros(M)
    for pair in linkage.pairs:
        if isinstance(pair, RevolutePair):
            (i, j), (pi, pj) = pair.links, pair.at
            wi, wj = asm.e[:, i] * pi, asm.e[:, j] * pj
            terms = [(i, np.ones(M, complex), 1j * wi), (j, -np.ones(M, complex), -1j * wj)]
            c = omega[:, i] ** 2 * wi - omega[:, j] ** 2 * wj if second else np.zeros(M, complex)
            sysm.add("re", terms, c.real)
            sysm.add("im", terms, c.imag)
            continue
        g, b, U, d, q, o = _pair_terms(pair, asm)
        ones = np.ones(M, complex)
        sysm.add("re", [(b, 0 * ones, L * ones), (g, 0 * ones, -L * ones)], zero)  # θ_b − θ_g (×L)
        cU = np.conj(U)
        terms = [(b, cU, cU * 1j * o), (g, -cU, np.conj(1j * U) * d - 1j * cU * q)]
        sysm.add("im", terms, -_quadratic(pair, asm, omega, v).imag if second else zero)
    for k, inp in enumerate(linkage.inputs):
        pair = linkage.pairs[inp.pair]
        rate = accels[:, k] if second else rates[:, k]
        if inp.kind == "angle":
            ones = np.ones(M, complex)
            sysm.add("re", [(inp.link, 0 * ones, L * ones), (inp.relative_to, 0 * ones, -L * ones)], L * rate)
            continue
        g, b, U, d, q, o = _pair_terms(pair, asm)
        cU = np.conj(U)
        terms = [(b, cU, cU * 1j * o), (g, -cU, np.conj(1j * U) * d - 1j * cU * q)]
        rhs = rate - _quadratic(pair, asm, omega, v).real if second else rate
        sysm.add("re", terms, rhs)
    return sysm


def _quadratic(pair: PrismaticPair, asm: Assembly, omega, v) -> np.ndarray:
    """Z = conj(Ü₀)·d + 2·conj(U̇)·ḋ + Ū·d̈₀ (the velocity-squared part of the line equation)."""
    g, b, U, d, q, o = _pair_terms(pair, asm)
    wg, wb = omega[:, g], omega[:, b]
    dU = 1j * wg * U
    dd = v[:, b] + 1j * wb * o - v[:, g] - 1j * wg * q
    ddU0 = -(wg**2) * U
    ddd0 = -(wb**2) * o + wg**2 * q
    return np.conj(ddU0) * d + 2 * np.conj(dU) * dd + np.conj(U) * ddd0


def linkage_motion(linkage: Linkage, assembly: Assembly, rates=None, accelerations=None) -> LinkageMotion:
    """Velocities and accelerations at every position of ``assembly``.

    Parameters
    ----------
    rates, accelerations : array_like, shape (k,) or (M, k)
        Time derivatives of the inputs (rad/s or length/s; rad/s² or length/s²). Default:
        1 for the first input and 0 for the others, so that velocities are derivatives with
        respect to the first input (per rad or per length) and accelerations the second ones.
    """
    M, n = assembly.r.shape
    k = len(linkage.inputs)
    if rates is None:
        rates = np.eye(1, k)[0] if k else np.zeros(0)
    if accelerations is None:
        accelerations = np.zeros(k)
    rates = np.broadcast_to(np.asarray(rates, float), (M, k))
    accels = np.broadcast_to(np.asarray(accelerations, float), (M, k))
    zero_c = np.zeros((M, n), complex)
    zero_r = np.zeros((M, n))
    L = linkage.length_scale

    first = _build(linkage, assembly, zero_r, zero_c, rates, accels, second=False)
    J = first.J
    assembled = (assembly.status & Status.NOT_ASSEMBLABLE) == 0
    condition = np.zeros(M)
    if J.shape[1]:
        sv = np.linalg.svd(J[assembled], compute_uv=False)
        condition[assembled] = sv[:, -1] / np.where(sv[:, 0] > 0, sv[:, 0], 1.0)
    singular = assembled & (condition < SINGULAR_RATIO) if J.shape[1] else np.zeros(M, bool)
    good = assembled & ~singular
    eye = np.eye(J.shape[1])
    Jsafe = np.where(good[:, None, None], J, eye)

    def unpack(x):
        x = np.where(good[:, None], x, 0.0)
        lin = np.zeros((M, n), complex)
        ang = np.zeros((M, n))
        lin[:, 1:] = x[:, 0::3] + 1j * x[:, 1::3]
        ang[:, 1:] = x[:, 2::3] / L
        return lin, ang

    v, omega = unpack(np.linalg.solve(Jsafe, first.rhs[..., None])[..., 0]) if J.shape[1] else (zero_c, zero_r)
    second = _build(linkage, assembly, omega, v, rates, accels, second=True)
    acc, alpha = unpack(np.linalg.solve(Jsafe, second.rhs[..., None])[..., 0]) if J.shape[1] else (zero_c, zero_r)

    prism = [p for p in linkage.pairs if isinstance(p, PrismaticPair)]
    s = np.zeros((M, len(prism)))
    ds, dds = np.zeros_like(s), np.zeros_like(s)
    for c, pair in enumerate(prism):
        g, b, U, d, q, o = _pair_terms(pair, assembly)
        wg, wb = omega[:, g], omega[:, b]
        dU = 1j * wg * U
        dd = v[:, b] + 1j * wb * o - v[:, g] - 1j * wg * q
        ddU = (1j * alpha[:, g] - wg**2) * U
        ddd = acc[:, b] + (1j * alpha[:, b] - wb**2) * o - acc[:, g] - (1j * alpha[:, g] - wg**2) * q
        s[:, c] = (np.conj(U) * d).real
        ds[:, c] = (np.conj(dU) * d + np.conj(U) * dd).real
        dds[:, c] = (np.conj(ddU) * d + 2 * np.conj(dU) * dd + np.conj(U) * ddd).real
    status = assembly.status | np.where(singular, np.uint8(Status.TOGGLE), np.uint8(0))
    return LinkageMotion(
        assembly, v, acc, omega, alpha, s, ds * good[:, None], dds * good[:, None], status.astype(np.uint8), condition
    )
