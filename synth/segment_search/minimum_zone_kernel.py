"""The minimum-zone fit compiled: one row of path samples at a time (:mod:`synth.segment_search.minimum_zone`).

Lawson's iteratively reweighted least squares (C. L. Lawson, 1961) on the line or circle
linearised about the current geometry, with scalar accumulators and closed-form 2×2/3×3
solves; the band's peak over a window of samples raised to the parabola's vertex; and the
scalar twin of :func:`synth.segment_search.minimum_zone.path_deviation`. The numpy form made a dozen passes
over every row's samples per Lawson iteration and was a fifth of the atlas build
(docs/atlas.md, "Speed"). A row's fit does not depend on the other rows of a batch.
Units: crank lengths, radians.
"""

from __future__ import annotations

import cmath
import math

import numba
import numpy as np

from synth.kinds import SegmentKind

__all__ = ["deviation_at", "fit_row", "fit_rows", "lawson", "window_peak"]

_LINE = SegmentKind.LINE.code
#: Relative ridge on the normal equations: keeps near-singular fits (a stretch seen almost
#: edge-on) finite.
_RIDGE = 1e-13


@numba.njit(cache=True, nogil=True, error_model="numpy")
def deviation_at(z, kind, point, direction, radius):
    """:func:`path_deviation` of one sample (scalars): Im(conj(direction)·(z − point)) for a
    line, |z − point| − radius for a circle."""
    if kind == _LINE:
        w = z - point
        return direction.real * w.imag - direction.imag * w.real
    return abs(z - point) - radius


@numba.njit(cache=True, nogil=True, error_model="numpy")
def lawson(c0, c1, c2, r0, p, iterations, w, res):
    """Approximate Chebyshev (minimax) solution x of r0 ≈ x₀·c0 + x₁·c1 (+ x₂·c2 if ``p`` is
    3) over the samples; ``w``, ``res`` are work arrays of the samples' length. Returns the
    best x seen (x₂ = 0 when ``p`` is 2).

    Normal equations of the weighted least squares by Cramer's rule (far cheaper than a solver
    at this size); weights multiplied by the residuals each iteration (Lawson)."""
    k = r0.size
    for j in range(k):
        w[j] = 1.0 / k
    b0 = b1 = b2 = 0.0
    best_h = 0.0
    for j in range(k):
        best_h = max(best_h, abs(r0[j]))
    for _ in range(iterations):
        m00 = m01 = m02 = m11 = m12 = m22 = q0 = q1 = q2 = 0.0
        for j in range(k):
            wj = w[j]
            u0, u1 = wj * c0[j], wj * c1[j]
            m00 += u0 * c0[j]
            m01 += u0 * c1[j]
            m11 += u1 * c1[j]
            q0 += u0 * r0[j]
            q1 += u1 * r0[j]
            if p == 3:
                u2 = wj * c2[j]
                m02 += u0 * c2[j]
                m12 += u1 * c2[j]
                m22 += u2 * c2[j]
                q2 += u2 * r0[j]
        if p == 2:
            ridge = _RIDGE * (m00 + m11) + 1e-300
            m00 += ridge
            m11 += ridge
            det = m00 * m11 - m01 * m01
            x0 = (m11 * q0 - m01 * q1) / det
            x1 = (m00 * q1 - m01 * q0) / det
            x2 = 0.0
        else:
            ridge = _RIDGE * (m00 + m11 + m22) + 1e-300
            m00 += ridge
            m11 += ridge
            m22 += ridge
            # cofactors of the symmetric matrix [[m00 m01 m02] [m01 m11 m12] [m02 m12 m22]]
            A = m11 * m22 - m12 * m12
            B = m02 * m12 - m01 * m22
            C = m01 * m12 - m02 * m11
            D = m00 * m22 - m02 * m02
            E = m01 * m02 - m00 * m12
            F = m00 * m11 - m01 * m01
            det = m00 * A + m01 * B + m02 * C
            x0 = (A * q0 + B * q1 + C * q2) / det
            x1 = (B * q0 + D * q1 + E * q2) / det
            x2 = (C * q0 + E * q1 + F * q2) / det
        # a singular system (a column that vanishes on every sample) leaves the geometry as it is
        if not math.isfinite(x0):
            x0 = 0.0
        if not math.isfinite(x1):
            x1 = 0.0
        if not math.isfinite(x2):
            x2 = 0.0
        h = 0.0
        total = 0.0
        for j in range(k):
            r = abs(r0[j] - x0 * c0[j] - x1 * c1[j] - x2 * c2[j])
            res[j] = r
            h = max(h, r)
            w[j] *= r
            total += w[j]
        if h < best_h:
            b0, b1, b2, best_h = x0, x1, x2, h
        for j in range(k):
            w[j] = w[j] / total if total > 0 else 1.0 / k
    return b0, b1, b2


@numba.njit(cache=True, nogil=True, error_model="numpy")
def fit_row(zs, kind, point, direction, radius, iterations, work):
    """The minimum-zone line (``kind`` ``SegmentKind.LINE.code``) or circle through the
    samples ``zs`` (k,), started from the given one; ``work`` is a (6, k) float work array.
    Returns (point, direction, radius).

    Linearised about the current geometry: a line moves by δo along its normal and turns by
    δβ, r ≈ r0 − δo − δβ·s (s along the line, scaled to O(1) for conditioning); a circle's
    centre moves by δc and its radius by δρ, r ≈ r0 − Re(δc·conj(e)) − δρ with e the unit
    vector from the centre (first order in the change, which is of the order of the band over
    the stretch). On a short arc e hardly turns, so its components are nearly constant:
    centred and scaled to O(1), the columns stay independent enough for the closed-form solve
    (the constant absorbs their means)."""
    k = zs.size
    r0, c0, c1, c2, w, res = work[0], work[1], work[2], work[3], work[4], work[5]
    for j in range(k):
        r0[j] = deviation_at(zs[j], kind, point, direction, radius)
    if kind == _LINE:
        scale = 0.0
        for j in range(k):
            rel = zs[j] - point
            c1[j] = direction.real * rel.real + direction.imag * rel.imag
            scale = max(scale, abs(c1[j]))
        scale = max(scale, 1e-12)
        for j in range(k):
            c0[j] = 1.0
            c1[j] /= scale
            c2[j] = 0.0
        x0, x1, _ = lawson(c0, c1, c2, r0, 2, iterations, w, res)
        return point + 1j * direction * x0, direction * cmath.exp(1j * (x1 / scale)), radius
    mean0 = mean1 = 0.0
    for j in range(k):
        rel = zs[j] - point
        size = max(abs(rel), 1e-300)
        c0[j] = rel.real / size
        c1[j] = rel.imag / size
        mean0 += c0[j]
        mean1 += c1[j]
    mean0 /= k
    mean1 /= k
    scale0 = scale1 = 0.0
    for j in range(k):
        c0[j] -= mean0
        c1[j] -= mean1
        scale0 = max(scale0, abs(c0[j]))
        scale1 = max(scale1, abs(c1[j]))
    scale0, scale1 = max(scale0, 1e-12), max(scale1, 1e-12)
    for j in range(k):
        c0[j] /= scale0
        c1[j] /= scale1
        c2[j] = 1.0
    x0, x1, x2 = lawson(c0, c1, c2, r0, 3, iterations, w, res)
    dcx, dcy = x0 / scale0, x1 / scale1
    return point + dcx + 1j * dcy, direction, radius + x2 - dcx * mean0 - dcy * mean1


@numba.njit(cache=True, nogil=True, error_model="numpy")
def fit_rows(z, kind, point, direction, radius, iterations):
    n, k = z.shape
    work = np.empty((6, k))
    p_out, d_out, r_out = point.copy(), direction.copy(), radius.copy()
    for i in range(n):
        p_out[i], d_out[i], r_out[i] = fit_row(z[i], kind, point[i], direction[i], radius[i], iterations, work)
    return p_out, d_out, r_out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def window_peak(absdev, t_lo, t_hi):
    """Largest |deviation| ``absdev`` over the samples t_lo..t_hi (0 if none), with each
    interior local maximum raised to the vertex of the parabola through it and its neighbours
    (:func:`kinematics.loop.parabola_vertex`): a fitted band touches ε between samples too, and
    the band must hold on the whole interval, not only at samples."""
    h = 0.0
    for j in range(t_lo, t_hi + 1):
        h = max(h, absdev[j])
    for j in range(t_lo + 1, t_hi):
        top = absdev[j]
        if top >= absdev[j - 1] and top >= absdev[j + 1]:
            den = absdev[j - 1] - 2 * top + absdev[j + 1]
            if den < 0:
                diff = absdev[j - 1] - absdev[j + 1]
                top = top - diff * diff / (8 * den)
            h = max(h, top)
    return h
