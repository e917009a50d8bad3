"""The dyad fits' compiled parts: the RRR fit's closed-form direction ranking
(:class:`synth.mechanism.dyad.RrrTerms`'s ``estimate``: per row and rocker direction, two passes over
the path samples instead of a dozen ``(rows, directions, samples)`` temporaries), and the
swing S(u) with its derivative that the RRR and RPR swing solves iterate on
(:func:`rrr_swing`: the dyad loop, the rocker's extremes and ∂S/∂u; :func:`rpr_swing`: the
slot's angle, its extremes and ∂S/∂u — one pass per dyad instead of ~10–20 array passes; the
samples ordered by a pseudo-angle, the arctangent taken only where a value is read).

The ranking runs the same operations in the same order as the numpy expressions it replaced
(no fused multiply-adds, reductions by max and min, which round nothing), so its numbers are
the same bit for bit (``tests/synth/test_dyad.py`` compares them); the transcendental parts
(the direction's cosine and sine, the branch, the final arccos) stay in numpy around it. The
swings are not bit for bit their numpy evaluations: numpy's ``arctan2`` and complex products
may run on other instructions (SVML, fused multiply-adds on AVX-512), and two samples whose
angles tie to rounding may be ordered the other way; the tests hold the two to 1e-12 and
the derivatives to central differences.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from synth.mechanism.sample_ranges import parabola_rise
from synth.mechanism.sixbar_kernel import closing_point
from synth.parallel_rows import one_signature, over_rows

__all__ = ["direction_estimates", "pseudo_angle", "rpr_swing", "rrr_swing", "solve_rpr", "solve_rrr"]


@numba.njit(cache=True, nogil=True)
def _estimates(wx, wy, A, inv_a_rho, half, rho, c, s, branch, target, ratio, u_lo, u_hi, u_est, cos_max, feasible):
    R, J = c.shape
    S = wx.shape[1]
    for r in range(R):
        rho2 = rho[r] * rho[r]
        for j in range(J):
            cj, sj, bj = c[r, j], s[r, j], branch[r, j]
            hi = math.inf
            lo = -math.inf
            smax = -math.inf
            smin = math.inf
            for k in range(S):
                p = wx[r, k] * cj + wy[r, k] * sj
                q = wy[r, k] * cj - wx[r, k] * sj
                centre = -p * inv_a_rho[r, k]
                hi = min(hi, centre + half[r, k])
                lo = max(lo, centre - half[r, k])
                sk = q + bj * math.sqrt(max(rho2 - p * p, 0.0))
                smax = max(smax, sk)
                smin = min(smin, sk)
            lo = max(lo, 0.0)
            est = target[r] / max(smax - smin, 1e-12)
            u_try = ratio[r, j] * est
            u_lo[r, j], u_hi[r, j], u_est[r, j] = lo, hi, est
            feasible[r, j] = (lo <= hi) and (u_try <= hi)
            u_use = min(max(u_try, lo), max(hi, lo))
            worst = 0.0
            for k in range(S):
                p = wx[r, k] * cj + wy[r, k] * sj
                worst = max(worst, abs(A[r, k] * u_use + p / rho[r]))
            cos_max[r, j] = worst


def direction_estimates(wx, wy, A, inv_a_rho, half, rho, c, s, branch, target, ratio):
    """For samples ``wx, wy, A, inv_a_rho, half`` ``(R, S)`` (C-contiguous float64), radii
    ``rho`` and swings ``target`` ``(R,)``, direction cosines and sines ``c, s``, branches and
    scale ``ratio`` ``(R, J)``: (u_lo, u_hi, u_est, cos_max, feasible), each ``(R, J)`` —
    :meth:`synth.mechanism.dyad.RrrTerms.estimate`'s quantities before its arccos."""
    R, J = c.shape
    out = [np.empty((R, J)) for _ in range(4)] + [np.empty((R, J), np.bool_)]
    # ratio arrives writable or read-only (a broadcast): one compile for both
    one_signature(_estimates, (wx, wy, A, inv_a_rho, half, rho, c, s, branch, target, ratio, *out), read_only=(10,))
    # ~4 ns a sample and direction
    over_rows(
        R,
        lambda lo, hi: _estimates(
            *(x[lo:hi] for x in (wx, wy, A, inv_a_rho, half, rho, c, s, branch, target, ratio, *out))
        ),
        4 * R * J * wx.shape[1],
    )
    return tuple(out)


@numba.njit(cache=True, nogil=True)
def _vertex_value(y, k, sign):
    """:func:`kinematics.loop.sampled_extreme`'s value at its extreme sample ``k``: the vertex
    of the parabola through it and its cyclic neighbours where it bends the right way."""
    m = y.shape[0]
    y0 = y[k]
    den, rise = parabola_rise(y[(k - 1) % m], y0, y[(k + 1) % m])
    return y0 + (rise if sign * den < 0 else 0.0)


@numba.njit(cache=True, nogil=True)
def pseudo_angle(y, x):
    """A number in [−2, 2] that orders directions (x, y) as atan2(y, x) does (its cut and signed
    zeros included), at the cost of one division: 1 − x/(|x| + |y|), negated below the axis."""
    p = 1.0 - x / (abs(x) + abs(y))
    return -p if math.copysign(1.0, y) < 0 else p


@numba.njit(cache=True, nogil=True)
def _angle_swing(xa, ya, order, angle):
    """The swing of the angle arg(x + iy) over cyclic samples ``xa``, ``ya`` (``order``: their
    pseudo-angles; ``angle``: scratch): (argmax, argmin, max − min refined to the parabolas'
    vertices, whether it jumps by more than π between neighbours — it crossed its cut)."""
    M = xa.shape[0]
    khi = np.argmax(order)
    klo = np.argmin(order)
    for k in (khi - 1, khi, khi + 1, klo - 1, klo, klo + 1):
        k %= M
        angle[k] = math.atan2(ya[k], xa[k])
    swing = _vertex_value(angle, khi, 1) - _vertex_value(angle, klo, -1)
    # a step of more than π between neighbours needs the angle to change sides of the axis
    for k in range(M):
        j = (k + 1) % M
        if (
            math.copysign(1.0, ya[k]) != math.copysign(1.0, ya[j])
            and abs(math.atan2(ya[j], xa[j]) - math.atan2(ya[k], xa[k])) > math.pi
        ):
            return khi, klo, swing, True
    return khi, klo, swing, False


@numba.njit(cache=True, nogil=True)
def _rtsafe_step(u, lt, ht, St, dS, invalid, target, tol):
    """One step of the safeguarded Newton on [lt, ht] (Numerical Recipes' ``rtsafe``) from the
    swing St and dS/du at u: (S, converged, lt, ht, next u, go on). An invalid S (revolving,
    not assemblable) counts as too large; a Newton step that leaves the bracket is replaced by
    bisection."""
    f = St - target
    conv = (not invalid) and abs(f) <= tol
    if invalid or f > 0:
        ht = u
    else:
        lt = u
    ok_d = (not invalid) and dS > 0
    newton = u - (f / dS if ok_d else 0.0)
    step = newton if (ok_d and newton > lt and newton < ht) else 0.5 * (lt + ht)
    return St, conv, lt, ht, step, (not conv) and (ht - lt) > 1e-15 * ht


@numba.njit(cache=True, nogil=True)
def _rrr_one(wx, wy, r, ex, ey, br, rho, u, scratch):
    """(S, dS/du, invalid) of one RRR dyad (:func:`rrr_swing`'s row); ``scratch``: (4, M)."""
    M = wx.shape[1]
    eta, order, xa, ya = scratch[0], scratch[1], scratch[2], scratch[3]
    L = 1.0 / u
    lx, ly = L * ex, L * ey
    any_sing = False
    for k in range(M):
        # the loop closed at R = D − P (D = L·e, P relative to C₀), l1 = ρ, l2 = L
        _, _, c2, s2, status, _, _ = closing_point(lx - wx[r, k], ly - wy[r, k], rho, L, br)
        # η = arg(e^{iψ}·(−ē)), the rocker's turn from rest: ordered by its pseudo-angle,
        # its arctangent taken only where a value is read (extremes, the cut's crossings)
        xa[k], ya[k] = c2 * (-ex) - s2 * ey, c2 * ey + s2 * (-ex)
        order[k] = pseudo_angle(ya[k], xa[k])
        any_sing = any_sing or status != 0
    khi, klo, S, jump = _angle_swing(xa, ya, order, eta)
    scale = L * u**2
    # ∂ψ/∂u = −∂ψ/∂L / u², ∂ψ/∂L = −Re((e + e^{iψ}) e^{−iχ}) / (L sin(χ − ψ)), at the two
    # extremes (the loop closed there again: the same numbers as in the pass, not stored for
    # every sample); k2 is 1/height, L sin(χ − ψ) = −height, 0 at a flagged sample
    rate = 0.0
    for k, sign in ((khi, 1.0), (klo, -1.0)):
        c1, s1, c2, s2, _, _, k2 = closing_point(lx - wx[r, k], ly - wy[r, k], rho, L, br)
        re = (ex + c2) * c1 - (ey + s2) * (-s1)
        rate += sign * (re * (-L * k2) / scale)
    return S, rate, any_sing or jump


@numba.njit(cache=True, nogil=True)
def _rrr_swing(wx, wy, rows, ex, ey, br, rho, u, S, dS, invalid):
    scratch = np.empty((4, wx.shape[1]))
    for i in range(rows.shape[0]):
        S[i], dS[i], invalid[i] = _rrr_one(wx, wy, rows[i], ex[i], ey[i], br[i], rho[i], u[i], scratch)


@numba.njit(cache=True, nogil=True)
def _solve_rrr(
    wx, wy, rows, ex, ey, br, rho, lo, hi, u0, target, active, check_far, tol, max_iter, u_out, S_out, conv_out
):
    scratch = np.empty((4, wx.shape[1]))
    for i in range(rows.shape[0]):
        r, exi, eyi, bri, rhoi = rows[i], ex[i], ey[i], br[i], rho[i]
        lt, ht, t = lo[i], hi[i], target[i]
        u = min(max(u0[i], lt), ht) if u0[i] == u0[i] else u0[i]  # np.clip: NaN stays NaN
        go = active[i]
        if check_far and go:
            S_hi, _, inv_hi = _rrr_one(wx, wy, r, exi, eyi, bri, rhoi, ht, scratch)
            go = inv_hi or S_hi >= t - tol
        S, conv = 0.0, False
        if go:
            for _ in range(max_iter):
                St, dSt, inv = _rrr_one(wx, wy, r, exi, eyi, bri, rhoi, u, scratch)
                S, conv, lt, ht, u_next, go = _rtsafe_step(u, lt, ht, St, dSt, inv, t, tol)
                if not go:
                    break
                u = u_next
        u_out[i], S_out[i], conv_out[i] = u, S if conv else 0.0, conv


def rrr_swing(wx, wy, rows, ex, ey, branch, rho, u):
    """The RRR dyad's output swing S(u) on sampled paths and ∂S/∂u, u = 1/L, for the swing
    solve of :func:`synth.mechanism.dyad._solve_rrr`: dyad i moves the path ``(wx, wy)[rows[i]]``
    (relative to the arc's centre C₀, C-contiguous ``(R, M)`` float64) with its rocker pivot
    at D = L·(ex + i·ey)[i] from C₀, rod ``rho[i]``, loop ``branch[i]`` (±1). Returns (S,
    dS/du, invalid), each ``(len(rows),)``; invalid: the loop does not close or toggles at a
    sample, or the rocker's angle jumps by more than π between samples (it revolves). The
    loop is the six-bar kernel's scalar circle intersection
    (:func:`synth.mechanism.sixbar_kernel.closing_point`), the extremes as
    :func:`kinematics.loop.sampled_extreme` finds them."""
    n = rows.shape[0]
    S, dS, invalid = np.empty(n), np.empty(n), np.empty(n, np.bool_)
    over_rows(
        n,
        lambda lo, hi: _rrr_swing(wx, wy, *(x[lo:hi] for x in (rows, ex, ey, branch, rho, u, S, dS, invalid))),
        15 * n * wx.shape[1],
    )  # ~15 ns a sample
    return S, dS, invalid


@numba.njit(cache=True, nogil=True)
def _rpr_one(t_s, n_s, r, sg, t_end, u, scratch):
    """(S, dS/du, invalid) of one RPR dyad (:func:`rpr_swing`'s row); ``scratch``: (4, M)."""
    M = t_s.shape[1]
    psi, order, xa, ya = scratch[0], scratch[1], scratch[2], scratch[3]
    tD = t_end + sg / u
    for k in range(M):
        # ψ = arg(−σ·(P − D)) in the line's frame: the angle's cut runs along the line from
        # D away from the stretch
        xa[k], ya[k] = -sg * (t_s[r, k] - tD), -sg * n_s[r, k]
        order[k] = pseudo_angle(ya[k], xa[k])
    khi, klo, S, invalid = _angle_swing(xa, ya, order, psi)
    a_hi, b_hi = t_s[r, khi] - tD, n_s[r, khi]
    a_lo, b_lo = t_s[r, klo] - tD, n_s[r, klo]
    # ∂ψ/∂t_D = Im(−1/(P − D)) at the two extremes
    dS = (b_hi / (a_hi * a_hi + b_hi * b_hi) - b_lo / (a_lo * a_lo + b_lo * b_lo)) * (-sg / (u * u))
    return S, dS, invalid


@numba.njit(cache=True, nogil=True)
def _rpr_swing(t_s, n_s, rows, side, t_end, u, S, dS, invalid):
    scratch = np.empty((4, t_s.shape[1]))
    for i in range(rows.shape[0]):
        S[i], dS[i], invalid[i] = _rpr_one(t_s, n_s, rows[i], side[i], t_end[i], u[i], scratch)


@numba.njit(cache=True, nogil=True)
def _solve_rpr(
    t_s, n_s, rows, side, t_end, lo, hi, u0, target, active, check_far, tol, max_iter, u_out, S_out, conv_out
):
    scratch = np.empty((4, t_s.shape[1]))
    for i in range(rows.shape[0]):
        r, sg, te = rows[i], side[i], t_end[i]
        lt, ht, t = lo[i], hi[i], target[i]
        u = min(max(u0[i], lt), ht) if u0[i] == u0[i] else u0[i]  # np.clip: NaN stays NaN
        go = active[i]
        if check_far and go:
            S_hi, _, inv_hi = _rpr_one(t_s, n_s, r, sg, te, ht, scratch)
            go = inv_hi or S_hi >= t - tol
        S, conv = 0.0, False
        if go:
            for _ in range(max_iter):
                St, dSt, inv = _rpr_one(t_s, n_s, r, sg, te, u, scratch)
                S, conv, lt, ht, u_next, go = _rtsafe_step(u, lt, ht, St, dSt, inv, t, tol)
                if not go:
                    break
                u = u_next
        u_out[i], S_out[i], conv_out[i] = u, S if conv else 0.0, conv


def solve_rrr(
    wx, wy, rows, ex, ey, branch, rho, lo, hi, u0, target, active, check_far: bool, tol: float, max_iter: int
):
    """S(u) = target solved for every RRR dyad of :func:`rrr_swing`'s arguments by safeguarded
    Newton on [lo, hi] (:func:`_rtsafe_step`; with ``check_far`` a dyad that falls short of
    the swing at ``hi`` is not iterated); only ``active`` dyads. Returns (u, S, converged),
    each ``(len(rows),)``, S = 0 where not converged. The iteration of the numpy form in
    ``tests/synth/test_dyad.py``, one dyad at a time."""
    n = rows.shape[0]
    u, S, conv = np.empty(n), np.empty(n), np.empty(n, np.bool_)
    dyads = (rows, ex, ey, branch, rho, lo, hi, u0, target, active)
    # u0 and active arrive writable or read-only (broadcasts): one compile for both
    one_signature(_solve_rrr, (wx, wy, *dyads, check_far, tol, max_iter, u, S, conv), read_only=(9, 11))
    # ~56 ns a sample, the iterations included
    over_rows(
        n,
        lambda a, b: _solve_rrr(wx, wy, *(x[a:b] for x in dyads), check_far, tol, max_iter, u[a:b], S[a:b], conv[a:b]),
        56 * n * wx.shape[1],
    )
    return u, S, conv


def rpr_swing(t_s, n_s, rows, side, t_end, u):
    """The RPR dyad's output swing S(u) on sampled paths and ∂S/∂u, for the swing solve of
    :func:`synth.mechanism.dyad.fit_rpr`: dyad i moves the path ``(t_s, n_s)[rows[i]]`` (in its line's
    frame, C-contiguous ``(R, M)`` float64) with its slot pivot on the line at
    t_D = ``t_end[i]`` + ``side[i]``/u (side ±1: behind the stretch or beyond it). Returns (S,
    dS/du, invalid), each ``(len(rows),)``; invalid: the slot's angle jumps by more than π
    between samples (the path crosses the cut beyond D: the output would revolve). The
    extremes as :func:`kinematics.loop.sampled_extreme` finds them."""
    n = rows.shape[0]
    S, dS, invalid = np.empty(n), np.empty(n), np.empty(n, np.bool_)
    over_rows(
        n,
        lambda lo, hi: _rpr_swing(t_s, n_s, *(x[lo:hi] for x in (rows, side, t_end, u, S, dS, invalid))),
        5 * n * t_s.shape[1],
    )  # ~5 ns a sample
    return S, dS, invalid


def solve_rpr(t_s, n_s, rows, side, t_end, lo, hi, u0, target, active, check_far: bool, tol: float, max_iter: int):
    """:func:`solve_rrr` for the RPR dyads of :func:`rpr_swing`'s arguments."""
    n = rows.shape[0]
    u, S, conv = np.empty(n), np.empty(n), np.empty(n, np.bool_)
    dyads = (rows, side, t_end, lo, hi, u0, target, active)
    one_signature(_solve_rpr, (t_s, n_s, *dyads, check_far, tol, max_iter, u, S, conv), read_only=(7, 9))
    # ~17 ns a sample, the iterations included
    over_rows(
        n,
        lambda a, b: _solve_rpr(
            t_s, n_s, *(x[a:b] for x in dyads), check_far, tol, max_iter, u[a:b], S[a:b], conv[a:b]
        ),
        17 * n * t_s.shape[1],
    )
    return u, S, conv
