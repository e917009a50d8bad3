"""Extended-precision reference for the curvature benchmarks, and locus residuals.

:func:`loop_jet` solves the four-bar in numpy ``longdouble`` (x86: 64-bit mantissa, ~1e-19)
by a route of its own: B as the intersection of the circles about A and B0, then the Taylor
coefficients of θ(φ₀ + s) order by order from the loop b·e^{iθ} − c·e^{iγ} = R(φ) with the
exponential-series recurrence (e^{iθ})ₙ = (1/n)·Σₖ k·iθₖ·(e^{iθ})ₙ₋ₖ — not the closed-form
derivative system of the product.

The residual functions take the path derivatives z^{(k)} of a coupler point and the phasor
derivatives (e^{iθ})^{(k)} (= ∂z^{(k)}/∂p), as numpy arrays. The tests' 40-digit reference
(``tests/synth/mp_fourbar.py``) is a separate one, with gradients of its own. Distances are first-order distances of a point from
an exact locus, |f|/|∇f|, with ∇ taken as 2·∂f/∂p̄ (a complex number).
"""

from __future__ import annotations

from dataclasses import dataclass
from math import factorial

import numpy as np

LD = np.longdouble
CLD = np.clongdouble


@dataclass(frozen=True)
class LoopJet:
    """A^{(k)} and (e^{iθ})^{(k)}, k = 0..order, as complex longdouble arrays."""

    A: list
    E: list

    def path(self, p) -> list:
        """z^{(k)} of coupler-frame points p (broadcast)."""
        p = np.asarray(p, CLD)
        return [A + E * p for A, E in zip(self.A, self.E)]

    @property
    def theta1(self):
        return (self.E[1] / self.E[0]).imag

    @property
    def pole_uv(self):
        """Coupler-frame pole: z′ = A′ + (e^{iθ})′·p = 0."""
        return -self.A[1] / self.E[1]


def loop_jet(a, b, c, d, branch, phi, order: int = 3) -> LoopJet:
    """Solve the loop and its Taylor coefficients in longdouble (see the module notes).

    Where the loop cannot close or is at a toggle the values are meaningless (NaN or inf):
    callers only compare against results the product did not flag.
    """
    with np.errstate(all="ignore"):
        return _loop_jet(a, b, c, d, branch, phi, order)


def _loop_jet(a, b, c, d, branch, phi, order: int) -> LoopJet:
    a, b, c, d, branch, phi = (np.asarray(x, LD) for x in (a, b, c, d, branch, phi))
    e_phi = np.cos(phi) + 1j * np.sin(phi).astype(CLD)
    A = a * e_phi
    R = d - A  # A → B0
    r = np.abs(R)
    x = (r * r + b * b - c * c) / (2 * r)  # along A→B0
    h = np.sqrt(np.maximum((b - x) * (b + x), LD(0)))
    e0 = (R / r) * (x + 1j * branch * h) / b
    g0 = (b * e0 - R) / c
    thetas, gammas = [], []
    e, g = [e0], [g0]
    u1, u2 = 1j * b * e0, -1j * c * g0
    cross = lambda p, q: (np.conj(p) * q).imag  # noqa: E731
    det = cross(u1, u2)
    for n in range(1, order + 1):
        pn = sum(k * 1j * thetas[k - 1] * e[n - k] for k in range(1, n)) / n if n > 1 else 0
        qn = sum(k * 1j * gammas[k - 1] * g[n - k] for k in range(1, n)) / n if n > 1 else 0
        rn = -A * (1j**n) / factorial(n)
        t = rn - b * pn + c * qn
        thetas.append(cross(t, u2) / det)
        gammas.append(cross(u1, t) / det)
        e.append(1j * thetas[-1] * e0 + pn)
        g.append(1j * gammas[-1] * g0 + qn)
    return LoopJet([A * (1j**k) for k in range(order + 1)], [e[k] * factorial(k) for k in range(order + 1)])


def centre_of_curvature(z):
    """z + i·z′|z′|²/Im(z̄′z″)."""
    return z[0] + 1j * z[1] * abs(z[1]) ** 2 / (z[1].conjugate() * z[2]).imag


def inflection_function(E, z):
    """f = Im(z̄′z″) (zero on the inflection circle, ∝ κ) and its gradient ∇_p f."""
    f = (z[1].conjugate() * z[2]).imag
    return f, (E[1].conjugate() * z[2] - z[1] * E[2].conjugate()) / 1j


def cubic_function(E, z):
    """g = Im(z̄′z‴)|z′|² − 3 Im(z̄′z″)Re(z̄′z″) (zero on the circle-point cubic, ∝ dκ/dφ), ∇_p g."""
    c2, c3, s = z[1].conjugate() * z[2], z[1].conjugate() * z[3], abs(z[1]) ** 2
    dc2, dc2b = E[1].conjugate() * z[2], z[1] * E[2].conjugate()  # ∂c2/∂p̄, ∂c̄2/∂p̄
    dc3, dc3b = E[1].conjugate() * z[3], z[1] * E[3].conjugate()
    ds = z[1] * E[1].conjugate()
    d_im2, d_re2, d_im3 = (dc2 - dc2b) / 2j, (dc2 + dc2b) / 2, (dc3 - dc3b) / 2j
    g = c3.imag * s - 3 * c2.imag * c2.real
    return g, 2 * (d_im3 * s + c3.imag * ds - 3 * (d_im2 * c2.real + c2.imag * d_re2))


def distance_to_inflection_circle(E, z):
    f, grad = inflection_function(E, z)
    return abs(f) / abs(grad)


def distance_to_cubic(E, z):
    g, grad = cubic_function(E, z)
    return abs(g) / abs(grad)


def ball_correction(E, z):
    """Newton step δp (complex) from p towards the exact Ball point, where f = g = 0."""
    f, gf = inflection_function(E, z)
    g, gg = cubic_function(E, z)
    det = gf.real * gg.imag - gf.imag * gg.real  # ⟨∇f, δ⟩ = −f, ⟨∇g, δ⟩ = −g
    return (-f * gg.imag + g * gf.imag) / det + 1j * ((-g * gf.real + f * gg.real) / det)


def residuals(jet: LoopJet, a, results: dict, circle_angles=None) -> dict[str, np.ndarray]:
    """Residuals of the unflagged float64 results against this reference, by kind (float arrays).

    ``results`` maps kinds to ``synth`` results broadcast like ``jet``: ``"pole"`` (required),
    and any of ``"inflection_circle"`` (checked at the points at ``circle_angles`` on it),
    ``"ball_point"``, ``"line_scan"`` (circle and centre points) and ``"euler_savary"`` (with
    the coupler-frame points it was given under ``"points"``). Each residual is a distance over
    max(a, distance of the point from the crank pin); centres over max(a, radius):

    * pole: distance to the point with z′ = 0;
    * inflection circle: distance of points on it from the exact κ = 0 locus;
    * Ball's point: Newton correction to the exact κ = dκ/dφ = 0 point;
    * circle points: distance to the exact dκ/dφ = 0 locus;
    * centre points: against the centre point on the returned ray from this reference's pole
      derivatives (docs/curvature.md's r₀ in longdouble; the 40-digit tests check that formula
      against the centre of curvature itself). The conjugate of the *rounded* circle point is
      no yardstick: near the pole it moves ~(r₀/r_c)² times faster than the circle point;
    * Euler–Savary centres: against the centre of curvature of the given point.
    """
    pl = results["pole"]
    out = {}

    def rel(x, p, ok):
        return (np.abs(x)[ok] / np.maximum(a, np.abs(p))[ok]).astype(float)

    ok = pl.status == 0
    ref_pole = jet.pole_uv
    out["pole"] = rel(pl.to_coupler(pl.point) - ref_pole, ref_pole, ok)
    if "inflection_circle" in results:
        circle = results["inflection_circle"]
        on_circle = pl.to_coupler(circle.center + 0.5 * circle.diameter * np.exp(1j * circle_angles))
        ok = np.broadcast_to(circle.status == 0, on_circle.shape)
        out["inflection_circle"] = rel(distance_to_inflection_circle(jet.E, jet.path(on_circle)), on_circle, ok)
    if "ball_point" in results:
        ball = results["ball_point"]
        out["ball_point"] = rel(ball_correction(jet.E, jet.path(ball.uv)), ball.uv, ball.status == 0)
    if "line_scan" in results:
        scan = results["line_scan"]
        ok = scan.status == 0
        uv = scan.circle_point_uv
        out["circle_point"] = rel(distance_to_cubic(jet.E, jet.path(uv)), uv, ok)
        # the centre point on the same ray from this reference's pole derivatives
        z2 = jet.A[2] + jet.E[2] * ref_pole
        z3 = jet.A[3] + jet.E[3] * ref_pole
        t1, t2 = jet.theta1, (jet.E[2] / jet.E[0]).imag
        u = np.exp(1j * np.asarray(scan.alpha, LD))
        r2, i2 = (np.conj(u) * z2).real, (np.conj(u) * z2).imag
        r_0 = 3 * r2 * i2 / (t1 * (np.conj(u) * z3).real - 3 * t2 * r2)
        r_0_got = ((scan.center_point - pl.point) * np.conj(u)).real
        out["center_point"] = (np.abs(r_0_got - r_0)[ok] / np.maximum(a, scan.radius)[ok]).astype(float)
    if "euler_savary" in results:
        centres = results["euler_savary"]
        path = jet.path(results["points"])
        ref_c = centre_of_curvature(path)
        radius = np.abs(ref_c - path[0])
        ok = centres.status == 0
        out["euler_savary"] = (np.abs(centres.center - ref_c)[ok] / np.maximum(a, radius)[ok]).astype(float)
    return out
