"""Independent 40-digit reference for the curvature tests (mpmath; no code from the product).

The four-bar loop is solved as a triangle A, B, B0 at 40 significant digits and the coupler
angle's derivatives come from mpmath's numerical differentiation at that precision
(``mp.diffs``), not from the closed-form derivative system the product uses. The locus
residuals are the generic ones of :mod:`cli.bench.reference`, fed with 40-digit numbers.
A coupler point p (coupler frame) traces z(φ) = A(φ) + e^{iθ(φ)}·p, so z^{(k)} = A^{(k)} + (e^{iθ})^{(k)}·p.
"""

from __future__ import annotations

import mpmath as mp

from cli.bench import reference

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


def distance_to_inflection_circle(inst: Instant, p) -> mp.mpf:
    """First-order distance |f|/|∇f| from coupler point p to the exact inflection circle."""
    with mp.workdps(DPS):
        return reference.distance_to_inflection_circle(inst.E, inst.path(p))


def distance_to_cubic(inst: Instant, p) -> mp.mpf:
    """First-order distance |g|/|∇g| from p to the exact cubic of stationary curvature."""
    with mp.workdps(DPS):
        return reference.distance_to_cubic(inst.E, inst.path(p))


def distance_to_ball_point(inst: Instant, p) -> mp.mpf:
    """|Newton correction| from p to the exact Ball point (f = g = 0 solved to first order)."""
    with mp.workdps(DPS):
        return abs(reference.ball_correction(inst.E, inst.path(p)))


def exact_ball_point(inst: Instant, p, steps: int = 4):
    """The exact Ball point near p (Newton on f = g = 0 at 40 digits)."""
    with mp.workdps(DPS):
        p = mp.mpc(complex(p))
        for _ in range(steps):
            p += reference.ball_correction(inst.E, inst.path(p))
        return p


def tangent_deviation(inst: Instant, p, h) -> mp.mpf:
    """Distance of z(φ + h) from the tangent line of the path of p at φ (40 digits)."""
    with mp.workdps(DPS):
        p = mp.mpc(complex(p))
        z = inst.path(p, order=1)
        t = z[1] / abs(z[1])
        return abs((mp.conj(t) * (inst.position(inst.phi + h, p) - z[0])).imag)
