"""The six-bar's motion compiled: one pass over (six-bar, crank angle) for
:func:`synth.mechanism.sixbar.simulate`, positions and derivatives up to order 2.

The query, the figures, the refinement and the reports simulate six-bars by the million; the
numpy path spends most of its time in temporaries (a dozen full-size arrays per call) and in
per-call overhead at small sizes. This kernel runs the same closed forms, in the same
floating-point order, one position at a time: the four-bar's closing triangle and its rates
(:func:`kinematics.loop.circle_intersection_xy` and ``rates_xy``: Heron's height, the loop solved
in units of its span beyond ``HERON_SAFE``, the same thresholds and placeholders; the derivative
system of :func:`kinematics.fourbar.solve_block`), the coupler point and its derivatives
(:meth:`kinematics.fourbar.FourBarMotion.coupler_point`), the RPR or RRR dyad
(:func:`synth.mechanism.sixbar._rpr`, :func:`synth.mechanism.sixbar._rrr`), the folded transmission angles
(:func:`kinematics.loop.transmission_fold`) and the continuous output angle
(:func:`synth.mechanism.sixbar._unwrap`).

The numpy path stays the reference and the fallback (crank angles of other shapes);
``tests/synth/test_sixbar_kernel.py`` holds the two to the same statuses and to ~1e-11
(numpy's complex product may fuse a multiply and an add where this kernel does not). numba
compiles on first use (~1–3 s) and caches the machine code beside this file.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from kinematics.loop import COINCIDENT_EPS, HERON_SAFE, TOGGLE_EPS
from kinematics.status import Status
from synth.parallel_rows import one_signature, over_rows

__all__ = [
    "closing_point",
    "coupler_point",
    "coupler_rocker_cos",
    "fold_transmission",
    "output_angles",
    "output_phasor",
    "phasor_step",
    "pin_size",
    "sixbar_positions",
    "slot_phasor",
]

_NA = int(Status.NOT_ASSEMBLABLE)
_TOGGLE = int(Status.TOGGLE)


@numba.njit(cache=True, error_model="numpy")
def closing_point(rx, ry, l1, l2, branch):
    """Scalar :func:`kinematics.loop.circle_intersection_xy`: (cos1, sin1, cos2, sin2, status,
    k1, k2), e2 put back on the unit circle where the loop does not close, k1 and k2 the Cramer
    factors of the rates (0 where flagged) — the same operations."""
    r2 = rx * rx + ry * ry
    r = math.sqrt(r2)
    s12 = l1 + l2
    u = 1.0
    if max(s12, r) > HERON_SAFE or s12 < 1.0 / HERON_SAFE:  # in units of the span there
        u = max(s12, r)
        rx, ry, l1, l2 = rx / u, ry / u, l1 / u, l2 / u
        r2 = rx * rx + ry * ry
        r = math.sqrt(r2)
        s12 = l1 + l2
    d21 = l2 - l1
    heron = (r + d21) * (s12 - r) * (r - d21) * (r + s12)
    root = math.sqrt(max(heron, 0.0))
    coincident = r <= COINCIDENT_EPS * s12
    bad = heron < 0 or coincident
    if coincident:
        r = 1.0
    inv_2r = 0.5 / (l1 * r)
    cb = (r2 - d21 * s12) * inv_2r
    sb = root * (branch * inv_2r)
    if bad:
        cb = min(max(cb, -1.0), 1.0)
        if not math.isfinite(sb):  # 0·∞: a loop that cannot close, its links ~1e100 apart or more
            sb = 0.0
        if coincident:
            rx, ry = 1.0, 0.0
    inv_r = 1.0 / r
    c1 = (rx * cb - ry * sb) * inv_r
    s1 = (rx * sb + ry * cb) * inv_r
    height = r * sb
    inv_l2 = 1.0 / l2
    c2 = (l1 * c1 - rx) * inv_l2
    s2 = (l1 * s1 - ry) * inv_l2
    if bad:
        mag = math.hypot(c2, s2)
        if mag == 0.0:
            c2 = 1.0
        else:
            c2, s2 = c2 / mag, s2 / mag
        status = _NA
    elif abs(height) < TOGGLE_EPS * l2:
        status = _TOGGLE
    else:
        status = 0
    # Cramer factors of the rates (CircleIntersection.rates): 0 where flagged
    k2 = 0.0 if status else 1.0 / height
    return c1, s1, c2, s2, status, (l2 / l1) * k2 / u, k2 / u


@numba.njit(cache=True, error_model="numpy")
def _divide(ax, ay, bx, by):
    """(a / b) for complex a, b by Smith's scaling, as numpy divides (no overflow of |b|²)."""
    if abs(bx) >= abs(by):
        rat = by / bx
        scl = 1.0 / (bx + by * rat)
        return (ax + ay * rat) * scl, (ay - ax * rat) * scl
    rat = bx / by
    scl = 1.0 / (by + bx * rat)
    return (ax * rat + ay) * scl, (ay * rat - ax) * scl


@numba.njit(cache=True, error_model="numpy")
def fold_transmission(cos_mu):
    """:func:`kinematics.loop.transmission_fold` of the relative phasor's real part."""
    mu = math.acos(min(max(cos_mu, -1.0), 1.0))
    return min(mu, math.pi - mu)


@numba.njit(cache=True, error_model="numpy")
def coupler_rocker_cos(ax, ay, ct, st, b, c, d):
    """cos μ of the four-bar's transmission at B: Re(e^{iθ}·conj(e^{iγ})), e^{iγ} = (A + b·e^{iθ}
    − d)/c, from A = (ax, ay) and e^{iθ} = (ct, st) (fold it with :func:`fold_transmission`)."""
    inv_c = 1.0 / c
    gx = ((ax + b * ct) - d) * inv_c
    gy = (ay + b * st) * inv_c
    return ct * gx + st * gy


@numba.njit(cache=True, error_model="numpy")
def phasor_step(ex, ey, px, py):
    """The angle (rad, in (−π, π]) from the unit phasor (px, py) to (ex, ey): the output's step
    between two samples before its 2π branch is chosen."""
    return math.atan2(-(ex * py) + ey * px, ex * px + ey * py)


@numba.njit(cache=True, error_model="numpy")
def pin_size(a, b, c, d, dx, dy):
    """The six-bar's size for the pin test: its longest four-bar link or |D|."""
    return max(max(max(a, b), max(c, d)), math.hypot(dx, dy))


@numba.njit(cache=True, error_model="numpy")
def coupler_point(a, b, c, d, branch, u, v, cphi, sphi):
    """The four-bar at crank angle φ (cos φ, sin φ): circles about A (radius b) and B0 (radius
    c), R = B0 − A. Returns :func:`closing_point`'s seven values (e^{iθ}, e^{iγ}, status, rate
    factors), A = (ax, ay), w = e^{iθ}(u + iv) and the coupler point P = A + w."""
    ct, st, cg, sg, fb, fk1, fk2 = closing_point(d - a * cphi, -(a * sphi), b, c, branch)
    ax, ay = a * cphi, a * sphi
    wx, wy = ct * u - st * v, ct * v + st * u
    return ct, st, cg, sg, fb, fk1, fk2, ax, ay, wx, wy, ax + wx, ay + wy


@numba.njit(cache=True, error_model="numpy")
def slot_phasor(zx, zy, dx, dy, pin_eps, size):
    """The RPR slot's direction e^{iψ} = W/|W|, W = P − D, as numpy's complex ÷ real computes
    it ((W + 0i)·(1/|W|), zeros' signs included), its status (NOT_ASSEMBLABLE and a +x
    placeholder where P is within ``pin_eps`` of the size of D) and W."""
    rx, ry = zx - dx, zy - dy
    r = math.hypot(rx, ry)
    if r <= pin_eps * size:
        scale = 1.0 / size
        return (size + 0.0 * 0.0) * scale, (0.0 - size * 0.0) * scale, _NA, rx, ry
    scale = 1.0 / r
    return (rx + ry * 0.0) * scale, (ry - rx * 0.0) * scale, 0, rx, ry


@numba.njit(cache=True, error_model="numpy")
def output_phasor(params, rpr, i, phi, pin_eps):
    """Six-bar ``i``'s output direction e^{iψ} = (cos ψ, sin ψ) at one crank angle ``phi``
    (rad) and its :class:`~kinematics.status.Status` flags: :func:`_positions`' order-0 path
    for one position (the refinements' pointwise ψ, taken as atan2 of it)."""
    ai, bi, ci, di, bri, ui, vi = (
        params[i, 0],
        params[i, 1],
        params[i, 2],
        params[i, 3],
        params[i, 4],
        params[i, 5],
        params[i, 6],
    )
    dxi, dyi, li, rhoi, dbri = params[i, 7], params[i, 8], params[i, 9], params[i, 10], params[i, 11]
    out = coupler_point(ai, bi, ci, di, bri, ui, vi, math.cos(phi), math.sin(phi))
    fb, zx, zy = out[4], out[11], out[12]
    if rpr[i]:
        ex, ey, st_dyad, _, _ = slot_phasor(zx, zy, dxi, dyi, pin_eps, pin_size(ai, bi, ci, di, dxi, dyi))
    else:
        _, _, ex, ey, st_dyad, _, _ = closing_point(dxi - zx, dyi - zy, rhoi, li, dbri)
    return ex, ey, fb | st_dyad


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _positions(params, rpr, phi, pin_eps, order, full, points, angles, derivs, status_fourbar, status):
    """Fill ``points`` (e^{iθ}, P, Q, then P′, P″ up to ``order``), ``angles`` (ψ, μ four-bar,
    μ output), ``derivs`` ((θ′, γ′, ψ′, θ″, γ″, ψ″)[: 3·order]), each ``(k, N, M)``, and the two
    status arrays ``(N, M)``; with ``full`` False (order 0) only ψ and the statuses. A row of
    ``params``: a, b, c, d, branch, u, v, pivot x, pivot y, rocker, rod, dyad branch."""
    n, m = status.shape
    shared_phi = phi.shape[0] == 1
    # a crank grid shared by every six-bar: its cosines and sines once
    cos_phi, sin_phi = np.empty(m), np.empty(m)
    if shared_phi:
        for j in range(m):
            cos_phi[j], sin_phi[j] = math.cos(phi[0, j]), math.sin(phi[0, j])
    e_theta, z, moving_pivot = points[0], points[1], points[2]
    psi, mu_fourbar, mu_output = angles[0], angles[1], angles[2]
    half_pi = 0.5 * math.pi
    two_pi = 2.0 * math.pi
    for i in range(n):
        ai, bi, ci, di, bri, ui, vi = (
            params[i, 0],
            params[i, 1],
            params[i, 2],
            params[i, 3],
            params[i, 4],
            params[i, 5],
            params[i, 6],
        )
        dxi, dyi, li, rhoi, dbri = params[i, 7], params[i, 8], params[i, 9], params[i, 10], params[i, 11]
        size = pin_size(ai, bi, ci, di, dxi, dyi)
        base0 = 0.0
        acc = 0.0
        px, py, prev_p1 = 1.0, 0.0, 0.0  # e^{iψ} and ψ′ at the previous sample
        row = 0 if shared_phi else i
        for j in range(m):
            if shared_phi:
                cphi, sphi = cos_phi[j], sin_phi[j]
            else:
                cphi, sphi = math.cos(phi[row, j]), math.sin(phi[row, j])
            ct, st, cg, sg, fb, fk1, fk2, ax, ay, wx, wy, zx, zy = coupler_point(
                ai, bi, ci, di, bri, ui, vi, cphi, sphi
            )
            status_fourbar[i, j] = fb
            # up to ``order``, P′ and P″ (docs/curvature.md §1: P′ = iA + iθ′w, P″ = −A + (iθ″ − θ′²)w)
            if full:
                e_theta[i, j] = complex(ct, st)
                z[i, j] = complex(zx, zy)
                mu_fourbar[i, j] = fold_transmission(coupler_rocker_cos(ax, ay, ct, st, bi, ci, di))
            t1 = g1 = t2 = g2 = 0.0
            z1x = z1y = z2x = z2y = 0.0
            if order >= 1:
                # rates of the loop (CircleIntersection.rates_xy) with q = R′ = (a sin φ, −a cos φ)
                qx, qy = ai * sphi, -(ai * cphi)
                t1 = (qx * cg + qy * sg) * fk1
                g1 = (qx * ct + qy * st) * fk2
                z1x, z1y = -ay - t1 * wy, ax + t1 * wx
                points[3, i, j] = complex(z1x, z1y)
                if order >= 2:
                    bt2, cg2 = bi * (t1 * t1), ci * (g1 * g1)
                    qx, qy = ax + (bt2 * ct - cg2 * cg), ay + (bt2 * st - cg2 * sg)
                    t2 = (qx * cg + qy * sg) * fk1
                    g2 = (qx * ct + qy * st) * fk2
                    tt = t1 * t1
                    z2x, z2y = -ax + (-(tt * wx) - t2 * wy), -ay + (t2 * wx - tt * wy)
                    points[4, i, j] = complex(z2x, z2y)
            p1 = p2 = 0.0
            if rpr[i]:
                ex, ey, st_dyad, rx, ry = slot_phasor(zx, zy, dxi, dyi, pin_eps, size)
                if not st_dyad:
                    if order >= 1:  # ψ′ = Im(P′/W), ψ″ = Im(P″/W − (P′/W)²), W = P − D
                        f1x, f1y = _divide(z1x, z1y, rx, ry)
                        p1 = f1y
                        if order >= 2:
                            p2 = _divide(z2x, z2y, rx, ry)[1] - 2.0 * f1x * f1y
                if full:
                    moving_pivot[i, j] = complex(zx, zy)
                    mu_output[i, j] = half_pi
            else:
                # circles about P (radius ρ) and D (radius L), R = D − P
                cx, cy, ex, ey, st_dyad, dk1, dk2 = closing_point(dxi - zx, dyi - zy, rhoi, li, dbri)
                if full:
                    moving_pivot[i, j] = complex(dxi + li * ex, dyi + li * ey)
                    mu_output[i, j] = 0.0 if st_dyad & _NA else fold_transmission(cx * ex + cy * ey)
                # (χ′, ψ′) from q = −P′, then ψ″ from q = −P″ + ρχ′²e^{iχ} − Lψ′²e^{iψ}
                if order >= 1:
                    c1 = (-z1x * ex - z1y * ey) * dk1
                    p1 = (-z1x * cx - z1y * cy) * dk2
                    if order >= 2:
                        rc, lp = rhoi * c1 * c1, li * p1 * p1
                        qx, qy = -z2x + rc * cx - lp * ex, -z2y + rc * cy - lp * ey
                        p2 = (qx * cx + qy * cy) * dk2
            st_six = fb | st_dyad
            status[i, j] = st_six
            if st_six:  # derivatives at a flagged position are placeholders: 0
                p1 = p2 = 0.0
            if order >= 1:
                derivs[0, i, j], derivs[1, i, j], derivs[2, i, j] = t1, g1, p1
                if order >= 2:
                    derivs[3, i, j], derivs[4, i, j], derivs[5, i, j] = t2, g2, p2
            # ψ continuous: the first sample's angle plus the running sum of the steps, each
            # (with ψ′) the 2π-branch nearest the trapezoidal prediction (synth.mechanism.sixbar._unwrap)
            if j == 0:
                base0 = math.atan2(ey, ex)
                psi[i, j] = base0
            else:
                step = phasor_step(ex, ey, px, py)
                if order >= 1:
                    pred = 0.5 * (p1 + prev_p1) * (phi[row, j] - phi[row, j - 1])
                    step = pred + ((step - pred + math.pi) % two_pi - math.pi)
                acc += step
                psi[i, j] = acc + base0
            px, py, prev_p1 = ex, ey, p1


#: :func:`_positions`'s paged outputs (points, angles, derivs) and its read inputs (params, rpr, phi).
_POSITIONS_PAGES = (6, 7, 8)
_POSITIONS_INPUTS = (0, 1, 2)


def output_angles(params: np.ndarray, rpr: np.ndarray, phi: np.ndarray, pin_eps: float) -> np.ndarray:
    """The continuous output angle ψ alone (``(N, M)``, rad), as :func:`sixbar_positions` gives
    it, without the points and transmission angles (the refinements' many small calls)."""
    n, m = params.shape[0], phi.shape[1]
    angles = np.empty((3, n, m))  # only ψ is written (the other two pages are never touched)
    status_fourbar, status = np.empty((n, m), np.uint8), np.empty((n, m), np.uint16)
    none_c, none_f = np.empty((3, 0, 0), np.complex128), np.empty((0, 0, 0))
    # the pages of a block are strided (A) or, unsplit, contiguous (C): one compile for both
    one_signature(
        _positions,
        (params, rpr, phi, pin_eps, 0, False, none_c, angles, none_f, status_fourbar, status),
        any_layout=_POSITIONS_PAGES,
        read_only=_POSITIONS_INPUTS,
    )

    def block(lo: int, hi: int) -> None:
        _positions(
            params[lo:hi],
            rpr[lo:hi],
            _rows(phi, lo, hi),
            pin_eps,
            0,
            False,
            none_c,
            angles[:, lo:hi],
            none_f,
            status_fourbar[lo:hi],
            status[lo:hi],
        )

    over_rows(n, block, 85 * n * m)  # ~85 ns a point (its crank angle's sine and cosine included)
    return angles[0]


def _rows(phi: np.ndarray, lo: int, hi: int) -> np.ndarray:
    """The crank angles of rows lo..hi: all of a shared grid ``(1, M)``, else those rows."""
    return phi if phi.shape[0] == 1 else phi[lo:hi]


def sixbar_positions(params: np.ndarray, rpr: np.ndarray, phi: np.ndarray, pin_eps: float, order: int = 0):
    """Motion of ``N`` six-bars (``params``: ``(N, 12)`` rows as :func:`_positions` reads them,
    C-contiguous float64; ``rpr``: ``(N,)`` bool) at crank angles ``phi`` of shape ``(1, M)``
    (shared) or ``(N, M)``, with derivatives up to ``order`` (0, 1 or 2).

    Returns (points, angles, derivs, status_fourbar, status): ``points`` complex
    ``(3 + order, N, M)`` — the coupler phasor e^{iθ}, the coupler point P, Q (RPR: P), then
    P′, P″; ``angles`` ``(3, N, M)`` — the continuous output angle ψ and the two folded
    transmission angles (rad; RPR output: π/2, 0 where an RRR cannot assemble); ``derivs``
    ``(3·order, N, M)`` — θ′, γ′, ψ′, then θ″, γ″, ψ″ (ψ's are 0 wherever the six-bar is
    flagged); the four-bar's ``uint8`` and the six-bar's ``uint16``
    :class:`~kinematics.status.Status` flags, ``(N, M)``.
    """
    n, m = params.shape[0], phi.shape[1]
    points = np.empty((3 + order, n, m), np.complex128)
    angles = np.empty((3, n, m))
    derivs = np.empty((3 * order, n, m))
    status_fourbar = np.empty((n, m), np.uint8)
    status = np.empty((n, m), np.uint16)
    one_signature(
        _positions,
        (params, rpr, phi, pin_eps, order, True, points, angles, derivs, status_fourbar, status),
        any_layout=_POSITIONS_PAGES,
        read_only=_POSITIONS_INPUTS,
    )

    def block(lo: int, hi: int) -> None:
        _positions(
            params[lo:hi],
            rpr[lo:hi],
            _rows(phi, lo, hi),
            pin_eps,
            order,
            True,
            points[:, lo:hi],
            angles[:, lo:hi],
            derivs[:, lo:hi],
            status_fourbar[lo:hi],
            status[lo:hi],
        )

    over_rows(n, block, 75 * n * m)  # ~75 ns a position (order 2)
    return points, angles, derivs, status_fourbar, status
