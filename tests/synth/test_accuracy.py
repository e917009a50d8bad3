"""Accuracy of the curvature engine against an independent 40-digit computation (mpmath).

Cases: 200 random Grashof crank-rockers (crank a = 1; b, c, d uniform in [1.2, 6]; random
branch) at one random crank angle each; 12 rays per instant (36 when run as a script).

Residuals are dimensionless and relative to the crank: a distance divided by
max(a, |p|), where |p| is the point's distance from the crank pin (float64 cannot place a
point 1e5 cranks away closer than ~1e-11 of a crank, so the crank is the unit only for the
points within a crank length or so). The distance of a point from an exact locus is the
first-order distance |f|/|∇f| of the defining function at 40 digits: for the inflection circle
f = Im(z̄′z″) (∝ κ), for the cubic of stationary curvature g = Im(z̄′z‴)|z′|² −
3 Im(z̄′z″)Re(z̄′z″) (∝ dκ/dφ), for Ball's point the Newton correction of (f, g) = 0.
Dividing κ by its own gradient is the sensible normalisation: raw κ·a and (dκ/dφ)·a are
printed too, but they blow up near the pole, where a point 1e-15 off already changes dκ/dφ at
order one, while the point is still within 1e-15 of the exact locus.

* pole: |p − p_exact| with z′(p_exact) = 0;
* inflection circle: three random points on each returned circle, distance to κ = 0;
* line scanning: the returned circle point against the exact circle point on the same ray
  through the exact pole, its distance to the cubic (dκ/dφ = 0), and the returned centre
  point against the exact centre of curvature of that exact circle point, relative to
  max(a, radius);
* Ball's point: distance to the exact Ball point (κ = dκ/dφ = 0), and the order of contact
  with the tangent line measured as the log-log slope of the deviation over Δφ = ±1e-3·2^-k,
  k = 0..3 (a generic point gives 2, an inflection point 3, Ball's point 4);
* double Ball points (20 crank-rockers, all their points): distance to the exact Ball point
  at both crank angles, and the crank-angle error |δφ| of the Newton correction that the
  exact Ball points at φ₁ and φ₂ would still ask for.

Run ``python tests/synth/test_accuracy.py`` to print the measured maxima.
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest
from mp_fourbar import (
    DPS,
    Instant,
    centre_of_curvature,
    curvature,
    distance_to_ball_point,
    distance_to_cubic,
    distance_to_inflection_circle,
    exact_ball_point,
    tangent_deviation,
)

from kinematics.fourbar import GrashofType, fourbar_motion, grashof_type
from synth.curvature.ball import ball_point, ball_point_offset_rate
from synth.curvature.double_ball import double_ball_points, theta4
from synth.curvature.inflection import inflection_circle
from synth.curvature.line_scan import line_scan
from synth.curvature.pole import pole

LIMIT = 1e-9
N_CASES = 200


def crank_rockers(n: int, seed: int) -> np.ndarray:
    """Rows (a, b, c, d, branch, phi) of random Grashof crank-rockers with a = 1."""
    rng = np.random.default_rng(seed)
    rows = []
    while len(rows) < n:
        b, c, d = rng.uniform(1.2, 6.0, 3)
        if grashof_type(1.0, b, c, d) == GrashofType.CRANK_ROCKER:
            rows.append((1.0, b, c, d, rng.choice([1.0, -1.0]), rng.uniform(0.0, 2 * np.pi)))
    return np.array(rows)


def _exact_circle_point(inst: Instant, pole_uv, alpha, r_guess):
    """Root near r_guess of dκ/dφ = 0 on the ray pole + r·e^{iα} (coupler frame), 40 digits."""
    with mp.workdps(DPS):
        u = mp.expj(alpha - mp.arg(inst.E[0]))  # fixed-frame direction seen in the coupler frame

        def g(r):
            z = inst.path(pole_uv + r * u)
            c2, c3 = mp.conj(z[1]) * z[2], mp.conj(z[1]) * z[3]
            return c3.imag * abs(z[1]) ** 2 - 3 * c2.imag * c2.real

        r = mp.findroot(g, mp.mpf(r_guess), tol=mp.mpf(10) ** (-2 * DPS // 3))
        return pole_uv + r * u


def measure(n: int = N_CASES, rays: int = 12, seed: int = 20240601) -> dict[str, np.ndarray]:
    """All residuals (see the module docstring) as arrays keyed by what they measure."""
    rng = np.random.default_rng(seed + 1)
    rows = crank_rockers(n, seed)
    a, b, c, d, br, phi = (rows[:, k, None] for k in range(6))
    motion = fourbar_motion(a, b, c, d, phi, br)
    pl = pole(motion)
    circle = inflection_circle(pl)
    ball = ball_point(pl)
    alpha = (np.arange(rays) + rng.uniform(0, 1)) * np.pi / rays
    scan = line_scan(pl, alpha)
    out: dict[str, list[float]] = {
        k: []
        for k in (
            "pole",
            "inflection",
            "inflection_kappa_a",
            "circle_point",
            "circle_point_cubic",
            "circle_point_dkappa_a",
            "center_point",
            "ball",
            "ball_kappa_a",
            "ball_dkappa_a",
            "ball_contact_order",
            "flagged_fraction",
        )
    }
    flagged = 0
    for k in range(n):
        inst = Instant(*rows[k])
        ak = rows[k, 0]
        norm = lambda p: max(ak, abs(complex(p)))  # noqa: E731
        with mp.workdps(DPS):
            exact_pole = -inst.A[1] / inst.E[1]  # z′ = A′ + (e^{iθ})′·p = 0
        p_pole = complex(pl.to_coupler(pl.point)[k, 0])
        out["pole"].append(abs(p_pole - complex(exact_pole)) / norm(exact_pole))
        if circle.status[k, 0] == 0:
            for beta in rng.uniform(0, 2 * np.pi, 3):
                p = complex(pl.to_coupler(circle.center[k, 0] + 0.5 * circle.diameter[k, 0] * np.exp(1j * beta))[k, 0])
                out["inflection"].append(float(distance_to_inflection_circle(inst, p)) / norm(p))
                out["inflection_kappa_a"].append(abs(float(curvature(inst.path(p))[0])) * ak)
        else:
            flagged += 1
        for j in range(rays):
            if scan.status[k, j]:
                flagged += 1
                continue
            p = complex(scan.circle_point_uv[k, j])
            r_guess = abs(scan.circle_point[k, j] - pl.point[k, 0]) * np.sign(
                ((scan.circle_point[k, j] - pl.point[k, 0]) * np.exp(-1j * alpha[j])).real
            )
            exact = _exact_circle_point(inst, exact_pole, alpha[j], r_guess)
            out["circle_point"].append(abs(p - complex(exact)) / norm(exact))
            out["circle_point_cubic"].append(float(distance_to_cubic(inst, p)) / norm(p))
            out["circle_point_dkappa_a"].append(abs(float(curvature(inst.path(p))[1])) * ak)
            z = inst.path(exact)
            centre = complex(centre_of_curvature(z))
            radius = abs(centre - complex(z[0]))
            out["center_point"].append(abs(centre - scan.center_point[k, j]) / max(ak, radius))
        if ball.status[k, 0]:
            flagged += 1
            continue
        pb = complex(ball.uv[k, 0])
        kappa, dkappa = curvature(inst.path(pb))
        out["ball"].append(float(distance_to_ball_point(inst, pb)) / norm(pb))
        out["ball_kappa_a"].append(abs(float(kappa)) * ak)
        out["ball_dkappa_a"].append(abs(float(dkappa)) * ak)
        out["ball_contact_order"].append(contact_order(inst, pb))
    out["flagged_fraction"] = [flagged / (n * (rays + 2))]
    return {k: np.asarray(v, float) for k, v in out.items()}


def contact_order(inst: Instant, p) -> float:
    """Log-log slope of the deviation from the tangent line, averaged over Δφ > 0 and < 0."""
    hs = 1e-3 * 0.5 ** np.arange(4)
    slopes = []
    for sign in (1, -1):
        dev = [float(mp.log(tangent_deviation(inst, p, sign * h))) for h in hs]
        slopes.append(np.polyfit(np.log(hs), dev, 1)[0])
    return float(np.mean(slopes))


def measure_double_ball(n: int = 20, seed: int = 7) -> dict[str, np.ndarray]:
    """Ball residuals at both crank angles of every double Ball point of n crank-rockers."""
    rows = crank_rockers(n, seed)
    found = double_ball_points(rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], rows[:, 4])
    out: dict[str, list[float]] = {"ball_at_both": [], "kappa_a": [], "dkappa_a": [], "angle_error": [], "count": []}
    out["count"] = list(np.bincount(found.linkage_index, minlength=n))
    for k in range(len(found)):
        a, b, c, d, br = rows[found.linkage_index[k], :5]
        p = complex(found.uv[k])
        exact, jac = [], []
        for ph in (found.phi1[k], found.phi2[k]):
            inst = Instant(a, b, c, d, br, ph)
            out["ball_at_both"].append(float(distance_to_ball_point(inst, p)) / max(a, abs(p)))
            kappa, dkappa = curvature(inst.path(p))
            out["kappa_a"].append(abs(float(kappa)) * a)
            out["dkappa_a"].append(abs(float(dkappa)) * a)
            exact.append(complex(exact_ball_point(inst, p)))
            m = fourbar_motion(a, b, c, d, ph, br)
            w, dw = ball_point_offset_rate(*m.dtheta, theta4(m))
            jac.append(complex(np.conj(m.e_theta) * m.A * (1j * (1 - m.dtheta[0]) * w + dw)))
        # Newton correction [p′(φ₁), −p′(φ₂)]·δ = p_exact(φ₂) − p_exact(φ₁)
        res, j1, j2 = exact[1] - exact[0], jac[0], -jac[1]
        det = (np.conj(j1) * j2).imag
        out["angle_error"].append(max(abs((np.conj(res) * j2).imag / det), abs((np.conj(j1) * res).imag / det)))
    return {k: np.asarray(v, float) for k, v in out.items()}


@pytest.fixture(scope="module")
def residuals() -> dict[str, np.ndarray]:
    return measure()


@pytest.fixture(scope="module")
def double_ball_residuals() -> dict[str, np.ndarray]:
    return measure_double_ball()


@pytest.mark.parametrize("name", ["pole", "inflection", "circle_point", "circle_point_cubic", "center_point", "ball"])
def test_residual_below_limit(residuals, name):
    values = residuals[name]
    assert values.size >= N_CASES  # ≥ 200 crank-rockers × crank angles were checked
    assert values.max() <= LIMIT, f"{name}: max residual {values.max():.3g}"


def test_few_results_are_flagged(residuals):
    assert residuals["flagged_fraction"][0] < 0.05


def test_ball_point_has_fourth_order_contact(residuals):
    order = residuals["ball_contact_order"]
    assert order.size >= 0.95 * N_CASES
    assert np.all(np.abs(order - 4.0) < 0.05), order[np.argmax(np.abs(order - 4.0))]


def test_contact_order_tells_ball_from_inflection_and_generic_points():
    row = crank_rockers(1, 3)[0]
    motion = fourbar_motion(*row[:4], row[5], row[4])
    pl = pole(motion)
    circle = inflection_circle(pl)
    inst = Instant(*row)
    on_circle = complex(pl.to_coupler(circle.center + 0.5 * circle.diameter * pl.normal * 1j))
    assert abs(contact_order(inst, on_circle) - 3.0) < 0.1
    assert abs(contact_order(inst, on_circle + 0.3) - 2.0) < 0.1


def test_double_ball_points_are_ball_points_at_both_angles(double_ball_residuals):
    r = double_ball_residuals
    assert r["ball_at_both"].size >= 2 * 20
    assert r["ball_at_both"].max() <= LIMIT


def test_double_ball_angles_are_refined_to_1e_12(double_ball_residuals):
    assert double_ball_residuals["angle_error"].max() <= 1e-12


def _report() -> None:
    res = measure(rays=36)
    dbl = measure_double_ball()
    print(f"{'residual':28s} {'n':>6s} {'max':>10s} {'median':>10s}")
    for group in (res, {f"double_ball_{k}": v for k, v in dbl.items() if k != "count"}):
        for name, v in group.items():
            print(f"{name:28s} {v.size:6d} {v.max():10.3g} {np.median(v):10.3g}")
    print("double Ball points per crank-rocker:", dbl["count"].astype(int).tolist())


if __name__ == "__main__":
    _report()
