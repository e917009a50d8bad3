"""Class III Assur groups (triads): every real assembly configuration.

A triad is a ternary body T (pose X = r_T, e = e^{iθ}) carrying three legs; leg i is a binary
body joined to a known body by its external pair and to T by its internal pair. Each leg
leaves one scalar equation on T's pose, of the common form

.. math:: g_i(X, θ) = κ_i |X|^2 + \\operatorname{Re}(\\bar a_i(θ) X) + d_i(θ) = 0,

with a_i = a₀ + a₁e and d_i = d₀ + Re(d₁e) linear in (cos θ, sin θ):

* RR leg (A fixed, leg length l, T's joint b): κ = 1, a = 2(e·b − A), d = |e·b − A|² − l²;
* PR leg (the leg slides on a known guide, its line base + tU; T's joint b on it): κ = 0,
  a = iU, d = Im(Ū(e·b − base));
* RP leg (the leg hangs from A and T slides on it, or it on T): κ = 0, X lies on the line
  A + e_L(m₀ + s v) with e_L = e·ρ̄, so a = i·ρ̄·v·e, d = −Im(conj(ρ̄ v e)·A) − Im(v̄ m₀).

Elimination: subtract one quadratic equation from the others (κ = 1 ones) to get two
equations linear in X, solve them by Cramer's rule X = N(θ)/Δ(θ), and put X into the
remaining equation. With the half-angle substitution θ = θ₀ + 2·atan t (e·(1 + t²) =
e^{iθ₀}(1 + it)²) this is a polynomial in t of degree 10 (κ = 1; it contains the factor
(1 + t²)² of the circular points, leaving the classic sextic — up to 6 real assemblies) or 6
(all legs linear). All its roots come from the eigenvalues of its companion matrix, so no
real root can be missed (the method is exact up to rounding; nearly double roots, which
rounding may push off the real axis, are kept when their imaginary part is small and both
neighbours are polished). θ₀ is picked per position so that no root sits near t = ∞
(θ = θ₀ + π). Every candidate is then refined by Newton's method on the three g_i (to
rounding, better than 1e-12 relative) and kept only if it satisfies them; the caller checks
loop closure of the whole linkage.

References
----------
C. M. Gosselin, J. Sefrioui, M. J. Richard, "Solutions polynomiales au problème de la
cinématique directe des manipulateurs parallèles plans à trois degrés de liberté",
Mech. Mach. Theory 27 (1992) 107–119 (the sextic, at most 6 real solutions).
G. R. Pennock, D. J. Kassner, "Kinematic analysis of a planar eight-bar linkage: application
to a platform-type robot", J. Mech. Des. 114 (1992) 87–95.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinematics.assur.pairs import Joint, Pin, Sleeve, Slide, link_from_two_points

__all__ = ["LegEquation", "TriadSolutions", "leg_equation", "leg_pose", "solve_triad"]

#: Candidate half-angle offsets θ₀ [rad]; the one with the best-conditioned leading coefficient wins.
_THETA0 = (0.3, 2.4, 4.5)
#: Roots with |Im t| below this (relative to 1 + |t|) are polished as possible real roots.
_IMAG_TOL = 0.05
_NEWTON_STEPS = 60
#: Accept a polished candidate if every leg equation holds to this (relative to the linkage size).
_ACCEPT = 1e-9
#: How many neighbours (in θ order) are compared when removing copies of a solution.
_WINDOW = 8
#: A pose farther than this (relative to the linkage size) is a solution at infinity.
_FAR = 1e4
#: Two solutions closer than this (relative) are one.
_SAME = 1e-8


@dataclass(frozen=True, slots=True)
class LegEquation:
    """g = κ|X|² + Re(conj(a₀ + a₁e)·X) + d₀ + Re(d₁e); coefficient arrays of one shape."""

    kappa: int
    a0: np.ndarray
    a1: np.ndarray
    d0: np.ndarray
    d1: np.ndarray

    def a(self, e):
        return self.a0 + self.a1 * e

    def d(self, e):
        return self.d0 + (self.d1 * e).real

    def value(self, X, e):
        return self.kappa * (X * np.conj(X)).real + (np.conj(self.a(e)) * X).real + self.d(e)

    def gradient(self, X, e):
        """(∂g/∂x, ∂g/∂y, ∂g/∂θ)."""
        a = self.a(e)
        gx = a.real + 2 * self.kappa * X.real
        gy = a.imag + 2 * self.kappa * X.imag
        gt = (np.conj(1j * self.a1 * e) * X).real + (1j * self.d1 * e).real
        return gx, gy, gt

    def rows(self, idx: np.ndarray) -> LegEquation:
        """The equations of the positions ``idx``."""
        return LegEquation(self.kappa, self.a0[idx], self.a1[idx], self.d0[idx], self.d1[idx])


def leg_equation(external: Pin | Slide, internal: Joint | Sleeve, shape: tuple[int, ...]) -> LegEquation:
    """The leg's scalar equation on T's pose (module notes); ``internal`` goes from the leg to T."""
    z = np.zeros(shape, complex)
    if isinstance(external, Pin) and isinstance(internal, Joint):
        A, b = external.at + z, internal.p2 + z
        length = np.abs(internal.p1 - external.local) + z.real
        d0 = (b * np.conj(b)).real + (A * np.conj(A)).real - length**2
        return LegEquation(1, -2 * A, 2 * b, d0, -2 * np.conj(A) * b)
    if isinstance(external, Slide) and isinstance(internal, Joint):
        base, U = external.line(internal.p1)
        base, U, b = base + z, U + z, internal.p2 + z
        return LegEquation(0, 1j * U, z, -(np.conj(U) * base).imag, -1j * np.conj(U) * b)
    if isinstance(external, Pin) and isinstance(internal, Sleeve):
        A = external.at + z
        m0 = internal.offset(external.local, 0.0) + z
        g = np.conj(internal.rho) * internal.v + z
        return LegEquation(0, z, 1j * g, -(np.conj(internal.v) * m0).imag, -1j * g * np.conj(A))
    raise TypeError("a triad leg needs an external pin or slide and an internal joint or sleeve")


def leg_pose(external: Pin | Slide, internal: Joint | Sleeve, X, e, rows, M: int):
    """Pose (r, e) of a leg once T's pose (X, e) is known at the positions ``rows`` (of M)."""

    def pick(v):
        return np.broadcast_to(np.asarray(v, complex), (M,))[rows]

    if isinstance(internal, Joint):
        B = X + e * pick(internal.p2)
        if isinstance(external, Pin):
            return link_from_two_points(pick(external.at), pick(external.local), B, pick(internal.p1))
        eL = pick(external.e)
        return B - eL * pick(internal.p1), eL
    eL = e * np.conj(pick(internal.rho))
    return pick(external.at) - eL * pick(external.local), eL


@dataclass(frozen=True, slots=True)
class TriadSolutions:
    """All real poses of T, flat over positions: solution k belongs to input position
    ``position[k]``; ``X`` (origin) and ``e`` (unit phasor) are T's pose. Sorted by position,
    then by θ = arg e. ``residual`` is the largest leg-equation residual as a length."""

    position: np.ndarray
    X: np.ndarray
    e: np.ndarray
    residual: np.ndarray


# -- batched polynomial arithmetic on coefficient rows (ascending powers of t) ---------------


def _pmul(p, q):
    out = np.zeros(np.broadcast_shapes(p.shape[:-1], q.shape[:-1]) + (p.shape[-1] + q.shape[-1] - 1,), complex)
    for i in range(p.shape[-1]):
        out[..., i : i + q.shape[-1]] += p[..., i : i + 1] * q
    return out


def _padd(*ps):
    n = max(p.shape[-1] for p in ps)
    out = np.zeros(np.broadcast_shapes(*(p.shape[:-1] for p in ps)) + (n,), complex)
    for p in ps:
        out[..., : p.shape[-1]] += p
    return out


def _re_conj_mul(a, n):
    """Coefficients of Re(conj(a(t))·n(t)) for real t."""
    return 0.5 * _padd(_pmul(np.conj(a), n), _pmul(a, np.conj(n)))


def _im_conj_mul(a, n):
    """Coefficients of Im(conj(a(t))·n(t)) for real t."""
    return -0.5j * _padd(_pmul(np.conj(a), n), -_pmul(a, np.conj(n)))


_W = np.array([1.0, 0.0, 1.0])  # 1 + t²
_E = np.array([1.0, 2.0j, -1.0])  # (1 + it)²


def _times_w(const, lin, e0):
    """(1 + t²)·(const + lin·e) with e·(1 + t²) = e0·(1 + it)²."""
    return np.asarray(const, complex)[..., None] * _W + (lin * e0)[..., None] * _E


def _eliminate(legs: list[LegEquation], order: tuple[int, int, int], theta0: float) -> np.ndarray:
    """Real coefficients of F(t) (module notes); ``order`` = (kept equation, linear 1, linear 2)."""
    e0 = np.exp(1j * theta0)
    q, j1, j2 = order
    A = [_times_w(L.a0, L.a1, e0) for L in legs]
    D = [_times_w(L.d0, L.d1, e0).real + 0j for L in legs]
    kq = legs[q].kappa
    A1, A2 = (A[j] - legs[j].kappa * kq * A[q] for j in (j1, j2))
    D1, D2 = (D[j] - legs[j].kappa * kq * D[q] for j in (j1, j2))
    delta = _im_conj_mul(A1, A2)
    N = 1j * _padd(_pmul(D1, A2), -_pmul(D2, A1))
    if kq:
        F = _padd(
            _pmul(_W + 0j, _pmul(N, np.conj(N))), _pmul(delta, _re_conj_mul(A[q], N)), _pmul(_pmul(delta, delta), D[q])
        )
    else:
        F = _padd(_re_conj_mul(A[q], N), _pmul(delta, D[q]))
    return F.real


def _starts(legs, order, row, theta):
    """Newton starts (row, θ, X) for candidate orientations.

    X comes from the two linear equations at θ (Cramer's rule). Where they are (nearly)
    parallel — Δ(θ) ≈ 0, which the elimination turns into a spurious double root that can sit
    on a true one — X lies on their common line; the kept equation then gives up to two points
    of that line, and both are tried.
    """
    e = np.exp(1j * theta)
    q, j1, j2 = order
    kq = legs[q].kappa
    a1, a2 = (legs[j].a(e) - legs[j].kappa * kq * legs[q].a(e) for j in (j1, j2))
    d1, d2 = (legs[j].d(e) - legs[j].kappa * kq * legs[q].d(e) for j in (j1, j2))
    delta = (np.conj(a1) * a2).imag
    rel = np.abs(delta) / np.maximum(np.abs(a1) * np.abs(a2), 1e-300)
    ok = rel > 1e-12
    X = 1j * (d1 * a2 - d2 * a1) / np.where(ok, delta, 1.0)
    rows, thetas, starts = [row[ok]], [theta[ok]], [X[ok]]
    # Cramer is ill-conditioned where the lines are nearly parallel, or where one equation has
    # (nearly) vanished (two legs give the same circle at this θ): try the remaining line too
    size_a = np.maximum.reduce([np.abs(a1), np.abs(a2), np.abs(legs[q].a(e))])
    weak = np.minimum(np.abs(a1), np.abs(a2)) < 1e-6 * size_a
    bad = np.flatnonzero((rel < 1e-3) | weak)
    if bad.size:
        # the line Re(conj(a)·X) = −d of the better-posed equation: X = X0 + λ·i·â
        a = np.where(np.abs(a1[bad]) >= np.abs(a2[bad]), a1[bad], a2[bad])
        d = np.where(np.abs(a1[bad]) >= np.abs(a2[bad]), d1[bad], d2[bad])
        size = np.where(np.abs(a) > 0, np.abs(a), 1.0)
        X0, u = -d * a / size**2, 1j * a / size
        Lq = legs[q].rows(bad)
        aq, dq = Lq.a(e[bad]), Lq.d(e[bad])
        # κ|X0 + λu|² + Re(conj(aq)(X0 + λu)) + dq = κλ² + Bλ + C
        B = 2 * kq * (np.conj(u) * X0).real + (np.conj(aq) * u).real
        C = kq * np.abs(X0) ** 2 + (np.conj(aq) * X0).real + dq
        if kq:  # |disc| keeps two distinct starts where rounding made a double root complex
            disc = np.abs(B * B - 4 * C)
            lams = [(-B + np.sqrt(disc)) / 2, (-B - np.sqrt(disc)) / 2]
        else:
            lams = [np.where(np.abs(B) > 0, -C / np.where(np.abs(B) > 0, B, 1.0), 0.0)]
        for lam in lams:
            rows.append(row[bad])
            thetas.append(theta[bad])
            starts.append(X0 + lam * u)
    return np.concatenate(rows), np.concatenate(thetas), np.concatenate(starts)


def _solve_batched(J, r):
    try:
        return np.linalg.solve(J, r[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return np.einsum("kij,kj->ki", np.linalg.pinv(J), r)


def _polish(legs: list[LegEquation], X, theta):
    """Newton's method on (g₁, g₂, g₃) = 0 in (x, y, θ); returns X, θ and the residual as a length.

    Each candidate stops when its step is at rounding level; the others go on (near-double
    roots converge only linearly), at most ``_NEWTON_STEPS`` times.
    """
    X, theta = X.astype(complex), theta.astype(float)
    active = np.arange(X.size)
    for _ in range(_NEWTON_STEPS):
        if active.size == 0:
            break
        sub = [L.rows(active) for L in legs]
        Xa, ta = X[active], theta[active]
        e = np.exp(1j * ta)
        g = np.stack([L.value(Xa, e) for L in sub], axis=-1)
        J = np.stack([np.stack(L.gradient(Xa, e), axis=-1) for L in sub], axis=-2)
        with np.errstate(all="ignore"):
            step = _solve_batched(J, -g)
        step = np.where(np.isfinite(step), step, 0.0)
        X[active] = Xa + step[:, 0] + 1j * step[:, 1]
        theta[active] = ta + step[:, 2]
        done = (np.abs(step[:, :2]).max(axis=-1) <= 1e-15 * (1 + np.abs(X[active]))) & (np.abs(step[:, 2]) <= 1e-15)
        active = active[~done]
    e = np.exp(1j * theta)
    resid = np.zeros(X.shape)
    for L in legs:
        gx, gy, _ = L.gradient(X, e)
        grad = np.hypot(gx, gy)
        resid = np.maximum(resid, np.abs(L.value(X, e)) / np.where(grad > 0, grad, 1.0))
    return X, np.angle(e), resid


def solve_triad(legs: list[LegEquation], scale: float) -> TriadSolutions:
    """Every real pose of T at every position (legs' coefficients of shape (M,)).

    ``scale`` is a length of the linkage (acceptance and de-duplication are relative to it).
    """
    M = legs[0].a0.shape[0]
    kappas = [L.kappa for L in legs]
    q = kappas.index(1) if 1 in kappas else 2
    order = (q, *[j for j in range(3) if j != q])
    Fs = np.stack([_eliminate(legs, order, t0) for t0 in _THETA0])  # (3, M, n)
    size = np.abs(Fs).max(axis=-1)
    quality = np.abs(Fs[..., -1]) / np.where(size > 0, size, 1.0)
    pick = np.argmax(quality, axis=0)
    rows = np.arange(M)
    F = Fs[pick, rows] / np.where(size[pick, rows] > 0, size[pick, rows], 1.0)[:, None]
    theta0 = np.asarray(_THETA0)[pick]
    alive = size[pick, rows] > 0

    cand_row: list[np.ndarray] = []
    cand_theta: list[np.ndarray] = []

    def add(rows_, t):
        cand_row.append(rows_)
        cand_theta.append(theta0[rows_] + 2 * np.arctan(t))

    full = alive & (np.abs(F[:, -1]) > 1e-13)
    n = F.shape[-1] - 1
    if np.any(full) and n > 0:
        idx = np.flatnonzero(full)
        comp = np.zeros((idx.size, n, n))
        comp[:, np.arange(1, n), np.arange(n - 1)] = 1.0
        comp[:, :, -1] = -F[idx, :n] / F[idx, n : n + 1]
        roots = np.linalg.eigvals(comp)
        _add_roots(add, np.repeat(idx, n), roots.ravel())
    for i in np.flatnonzero(alive & ~full):  # degree drops: a root at t = ∞ (θ = θ₀ + π)
        coeffs = np.trim_zeros(np.where(np.abs(F[i]) > 1e-13, F[i], 0.0), "b")
        if coeffs.size > 1:
            r = np.roots(coeffs[::-1])
            _add_roots(add, np.full(r.size, i), r)
        cand_row.append(np.array([i]))
        cand_theta.append(np.array([theta0[i] + np.pi]))
    if not cand_row:
        return TriadSolutions(np.zeros(0, int), np.zeros(0, complex), np.zeros(0, complex), np.zeros(0))
    row, theta, X0 = _starts(
        [L.rows(np.concatenate(cand_row)) for L in legs], order, np.concatenate(cand_row), np.concatenate(cand_theta)
    )
    sub = [L.rows(row) for L in legs]
    X, theta, resid = _polish(sub, X0, theta)
    # a root at which X runs off to infinity (parallel lines) is no assembly
    good = np.isfinite(X) & np.isfinite(theta) & (resid <= _ACCEPT * scale) & (np.abs(X) <= _FAR * scale)
    row, X, theta, resid = row[good], X[good], theta[good], resid[good]
    keep = np.lexsort((theta, row))
    row, X, theta, resid = row[keep], X[keep], theta[keep], resid[keep]
    # de-duplicate within each position: sorted by θ, copies sit within a few places of each
    # other (several poses may share one θ), or at the two ends of a row when θ is near ±π;
    # of two copies the better polished one stays
    drop = np.zeros(row.size, bool)
    first = np.searchsorted(row, row)
    last = np.searchsorted(row, row, side="right") - 1
    pairs = [(np.arange(lag, row.size), np.arange(0, row.size - lag)) for lag in range(1, _WINDOW + 1)]
    ends = np.flatnonzero((np.arange(row.size) == last) & (last > first))
    pairs.append((ends, first[ends]))
    for k, j in pairs:
        same = (row[k] == row[j]) & _close(theta[k], theta[j], X[k], X[j], scale)
        worse = np.where(resid[k] >= resid[j], k, j)
        drop[worse[same]] = True
    distinct = ~drop
    return TriadSolutions(row[distinct], X[distinct], np.exp(1j * theta[distinct]), resid[distinct])


def _close(t1, t2, X1, X2, scale):
    return (np.abs(np.angle(np.exp(1j * (t1 - t2)))) < _SAME) & (np.abs(X1 - X2) < _SAME * scale)


def _add_roots(add, rows, roots):
    """Queue real roots (and both neighbours of a nearly real complex pair)."""
    near = np.abs(roots.imag) <= _IMAG_TOL * (1 + np.abs(roots))
    rows, roots = rows[near], roots[near]
    add(rows, roots.real)
    split = np.abs(roots.imag) > 1e-7 * (1 + np.abs(roots))
    if np.any(split):
        add(rows[split], roots.real[split] + np.abs(roots.imag[split]))
        add(rows[split], roots.real[split] - np.abs(roots.imag[split]))
