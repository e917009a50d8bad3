"""Independent 40-digit reference for the curvature tests (mpmath; no code from the product).

The four-bar loop is solved as a triangle A, B, B0 at 40 significant digits and the coupler
angle's derivatives come from mpmath's numerical differentiation at that precision
(``mp.diffs``), not from the closed-form derivative system the product uses. A coupler point p
(coupler frame) traces z(φ) = A(φ) + e^{iθ(φ)}·p, so z^{(k)} = A^{(k)} + (e^{iθ})^{(k)}·p.

A point's distance from an exact locus is the first-order distance |f|/|∇f| of the locus's
defining function, with ∇ over the coupler-frame point taken by mpmath's numerical
differentiation (not the closed-form gradients of the benchmarks' reference,
:mod:`cli.bench.reference`):

* inflection circle: f = Im(z̄′z″) (zero where κ = 0);
* cubic of stationary curvature: g = Im(z̄′z‴)|z′|² − 3 Im(z̄′z″)Re(z̄′z″) (zero where dκ/dφ = 0);
* Ball's point: the Newton correction of (f, g) = 0.
"""

from __future__ import annotations

import mpmath as mp

DPS = 40
mp.mp.dps = DPS  # every later operation on these numbers (κ, centres, ...) keeps 40 digits


class Instant:
    """A four-bar at one crank angle: A^{(k)} and (e^{iθ})^{(k)}, k = 0..order, at 40 digits."""

    def __init__(self, a, b, c, d, branch, phi, order: int = 4):
        with mp.workdps(DPS):
            self.a, self.b, self.c, self.d = (mp.mpf(float(x)) for x in (a, b, c, d))
            self.branch = int(branch)
            self.phi = mp.mpf(float(phi))
            self.A = [self.a * mp.mpc(0, 1) ** k * mp.expj(self.phi) for k in range(order + 1)]
            self.E = list(mp.diffs(self.e_theta, self.phi, order))

    def e_theta(self, phi):
        """Coupler phasor e^{iθ} from the triangle A, B, B0 (branch +1: B left of A→B0)."""
        A = self.a * mp.expj(phi)
        R = self.d - A
        r = abs(R)
        cb = (self.b**2 + r**2 - self.c**2) / (2 * self.b * r)
        return (R / r) * mp.mpc(cb, self.branch * mp.sqrt(1 - cb**2))

    def position(self, phi, p):
        """Fixed-frame position of the coupler point p at crank angle phi."""
        with mp.workdps(DPS):
            return self.a * mp.expj(phi) + self.e_theta(phi) * p

    def path(self, p, order: int = 3):
        """(z, z′, …) of coupler point p (complex or mpc) at this instant."""
        with mp.workdps(DPS):
            p = mp.mpc(complex(p)) if not isinstance(p, mp.mpc) else p
            return [self.A[k] + self.E[k] * p for k in range(order + 1)]

    @property
    def dtheta(self):
        """θ′, θ″, θ‴, θ⁗ from the phasor derivatives (e^{iθ})^{(k)}/e^{iθ}."""
        with mp.workdps(DPS):
            r = [self.E[k] / self.E[0] for k in range(len(self.E))]
            t1 = r[1].imag
            t2 = (r[2] + t1**2).imag
            t3 = (r[3] + 3 * t1 * t2 + mp.mpc(0, 1) * t1**3).imag
            out = [t1, t2, t3]
            if len(r) > 4:
                out.append((r[4] + 6 * mp.mpc(0, 1) * t1**2 * t2).imag)
            return out


def curvature(z):
    """κ and dκ/dφ of a path from (z, z′, z″, z‴)."""
    c2 = mp.conj(z[1]) * z[2]
    c3 = mp.conj(z[1]) * z[3]
    s = abs(z[1]) ** 2
    return c2.imag / s**1.5, c3.imag / s**1.5 - 3 * c2.imag * c2.real / s**2.5


def centre_of_curvature(z):
    """The centre of curvature: a radius 1/κ along the left normal of the path."""
    return z[0] + 1j * (z[1] / abs(z[1])) / curvature(z)[0]


def _path(inst: Instant, p) -> list:
    """z, z′, z″, z‴ of an mpc point p at the working precision (``mp.diff`` raises it for its
    steps: :meth:`Instant.path` would round them away)."""
    return [inst.A[k] + inst.E[k] * p for k in range(4)]


def inflection_value(inst: Instant, p) -> mp.mpf:
    """f = Im(z̄′z″) of coupler point p (mpc)."""
    z = _path(inst, p)
    return (mp.conj(z[1]) * z[2]).imag


def cubic_value(inst: Instant, p) -> mp.mpf:
    """g = Im(z̄′z‴)|z′|² − 3 Im(z̄′z″)Re(z̄′z″) of coupler point p (mpc)."""
    z = _path(inst, p)
    c2, c3 = mp.conj(z[1]) * z[2], mp.conj(z[1]) * z[3]
    return c3.imag * abs(z[1]) ** 2 - 3 * c2.imag * c2.real


def gradient(value, inst: Instant, p) -> tuple[mp.mpf, mp.mpf]:
    """(∂/∂x, ∂/∂y) of ``value(inst, p)`` at p = x + iy (mpmath's numerical derivative)."""
    with mp.workdps(DPS):
        p = _mpc(p)
        dx = mp.diff(lambda x: value(inst, mp.mpc(x, p.imag)), p.real)
        dy = mp.diff(lambda y: value(inst, mp.mpc(p.real, y)), p.imag)
        return dx, dy


def _mpc(p) -> mp.mpc:
    return p if isinstance(p, mp.mpc) else mp.mpc(complex(p))


def _locus_distance(value, inst: Instant, p) -> mp.mpf:
    with mp.workdps(DPS):
        p = _mpc(p)
        return abs(value(inst, p)) / mp.hypot(*gradient(value, inst, p))


def distance_to_inflection_circle(inst: Instant, p) -> mp.mpf:
    """First-order distance |f|/|∇f| from coupler point p to the exact inflection circle."""
    return _locus_distance(inflection_value, inst, p)


def distance_to_cubic(inst: Instant, p) -> mp.mpf:
    """First-order distance |g|/|∇g| from p to the exact cubic of stationary curvature."""
    return _locus_distance(cubic_value, inst, p)


def ball_correction(inst: Instant, p) -> mp.mpc:
    """Newton step δp from p towards the exact Ball point, where f = g = 0."""
    with mp.workdps(DPS):
        p = _mpc(p)
        f, g = inflection_value(inst, p), cubic_value(inst, p)
        (fx, fy), (gx, gy) = gradient(inflection_value, inst, p), gradient(cubic_value, inst, p)
        det = fx * gy - fy * gx
        return mp.mpc((-f * gy + g * fy) / det, (-g * fx + f * gx) / det)


def distance_to_ball_point(inst: Instant, p) -> mp.mpf:
    """|Newton correction| from p to the exact Ball point (f = g = 0 solved to first order)."""
    with mp.workdps(DPS):
        return abs(ball_correction(inst, p))


def exact_ball_point(inst: Instant, p, steps: int = 4):
    """The exact Ball point near p (Newton on f = g = 0 at 40 digits)."""
    with mp.workdps(DPS):
        p = mp.mpc(complex(p))
        for _ in range(steps):
            p += ball_correction(inst, p)
        return p


def tangent_deviation(inst: Instant, p, h) -> mp.mpf:
    """Distance of z(φ + h) from the tangent line of the path of p at φ (40 digits)."""
    with mp.workdps(DPS):
        p = mp.mpc(complex(p))
        z = inst.path(p, order=1)
        t = z[1] / abs(z[1])
        return abs((mp.conj(t) * (inst.position(inst.phi + h, p) - z[0])).imag)
