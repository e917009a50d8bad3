"""Four-bar kernel: reference cases, closed forms, loop closure, finite differences, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from kinematics import (
    AssemblyError,
    GrashofType,
    Status,
    crank_range,
    fourbar_motion,
    grashof_type,
    rocker_limits,
    time_derivatives,
    transmission_angle,
)

lengths = st.floats(0.2, 5.0)
angles = st.floats(-math.pi, math.pi)
branches = st.sampled_from([1, -1])


# --- reference cases ---------------------------------------------------------------------------


def test_p204001_both_configurations(reference_cases):
    case = reference_cases["P204001_fourbar"]
    x = case["inputs"]
    got = set()
    for branch in (1, -1):
        m = fourbar_motion(x["l1"], x["l2"], x["l3"], x["l4"], math.radians(x["theta1"]), branch, order=0)
        assert m.status == Status.OK
        got.add((float(np.degrees(m.theta)), float(np.degrees(m.gamma))))
    want = {tuple(row["solver"]) for row in case["rows"]}
    for theta, gamma in want:
        assert any(abs(theta - t) < 1e-8 and abs(gamma - g) < 1e-8 for t, g in got), (theta, gamma, got)
    # printed values, to half a unit of their last digit
    for row in case["rows"]:
        assert any(
            all(abs(v - d) <= h for v, d, h in zip(pair, row["document"], row["doc_half_unit_last_digit"]))
            for pair in got
        )


@pytest.mark.parametrize("name", ["fourbar_velocity_r1_150_w1_4.2735", "fourbar_velocity_r1_150_w1_7.6923"])
def test_fourbar_velocity_cases_at_exact_position(reference_cases, name):
    case = reference_cases[name]
    x, exact = case["inputs"], case["solver_at_exact_position"]
    matches = []
    for branch in (1, -1):
        m = fourbar_motion(x["r1"], x["r2"], x["r3"], x["r4"], math.radians(x["theta1_deg"]), branch)
        if abs(float(m.theta) - exact["theta2_rad"]) < 1e-9:
            matches.append(m)
    assert len(matches) == 1
    m = matches[0]
    assert float(m.gamma) == pytest.approx(exact["theta3_rad"], abs=1e-10)
    w1 = x["omega1"]
    vel = [time_derivatives(m.dtheta, w1)[0], time_derivatives(m.dgamma, w1)[0]]
    acc = [time_derivatives(m.dtheta, w1)[1], time_derivatives(m.dgamma, w1)[1]]
    np.testing.assert_allclose(np.array(vel, float), exact["omega"], rtol=1e-10)
    np.testing.assert_allclose(np.array(acc, float), exact["alpha_with_alpha1_0"], rtol=1e-10)


# --- closed forms ------------------------------------------------------------------------------


def test_parallelogram_translates_coupler():
    # a = c, b = d, open branch: the coupler never turns, θ ≡ 0 and θ' = θ'' = θ''' = 0,
    # the rocker turns with the crank (γ = φ).
    # For 0 < φ < π, B = A + 3 lies left of the line A→B0: branch +1.
    phi = np.linspace(0.5, 2.6, 9)  # away from the change points at 0 and π
    m = fourbar_motion(1.0, 3.0, 1.0, 3.0, phi, branch=1)
    np.testing.assert_allclose(m.theta, 0.0, atol=1e-14)
    np.testing.assert_allclose(m.gamma, phi, atol=1e-14)
    for k in range(3):
        np.testing.assert_allclose(m.dtheta[k], 0.0, atol=1e-12)
    np.testing.assert_allclose(m.dgamma[0], 1.0, atol=1e-12)


@pytest.mark.parametrize("branch, B_expected", [(1, 4.0 + 3.0j), (-1, 1.12 - 0.84j)])
def test_right_angle_position(branch, B_expected):
    # a=3, d=4 and φ = 90°: A = 3i, |A B0| = 5; with b = 4, c = 3 the angle at B is right.
    # cos β = 0.8, sin β = ±0.6 and e^{iθ} = (0.8 − 0.6i)(0.8 ± 0.6i): B = A + 4·e^{iθ}.
    m = fourbar_motion(3.0, 4.0, 3.0, 4.0, math.pi / 2, branch=branch, order=0)
    assert abs(complex(m.B) - B_expected) < 1e-14
    assert abs(m.sin_theta_gamma) == pytest.approx(1.0, abs=1e-14)  # right angle at B


@pytest.mark.parametrize(
    "links, kind",
    [
        ((1, 3, 2.5, 3), GrashofType.CRANK_ROCKER),
        ((3, 3, 2.5, 1), GrashofType.DOUBLE_CRANK),
        ((3, 1, 2.5, 3), GrashofType.DOUBLE_ROCKER),
        ((3, 2.5, 1, 3), GrashofType.ROCKER_CRANK),
        ((2, 3, 3.5, 5), GrashofType.TRIPLE_ROCKER),
        ((1, 2, 2, 1), GrashofType.CHANGE_POINT),
        ((1, 3, 2, 2), GrashofType.CHANGE_POINT),
    ],
)
def test_grashof_type(links, kind):
    assert GrashofType(int(grashof_type(*links))) is kind


def test_grashof_is_vectorised():
    out = grashof_type(np.ones((3, 1)), [3.0, 3.0], [2.5, 2.0], [3.0, 2.0])
    assert out.shape == (3, 2)
    assert (out[:, 0] == GrashofType.CRANK_ROCKER).all() and (out[:, 1] == GrashofType.CHANGE_POINT).all()


@settings(max_examples=60, deadline=None)
@given(lengths, lengths, lengths, lengths, branches)
def test_crank_range_is_where_the_loop_closes(a, b, c, d, branch):
    phi = np.linspace(-math.pi, math.pi, 2001)
    closes = fourbar_motion(a, b, c, d, phi, branch, order=0).status & Status.NOT_ASSEMBLABLE == 0
    inside = np.zeros_like(closes)
    ranges = crank_range(a, b, c, d)
    for lo, hi in ranges:
        wrapped = np.mod(phi - lo, 2 * math.pi)
        inside |= wrapped <= (hi - lo) + 1e-12
    # away from the interval ends the two must agree exactly
    near_end = np.zeros_like(closes)
    for lo, hi in ranges:
        for end in (lo, hi):
            near_end |= np.abs(np.angle(np.exp(1j * (phi - end)))) < 1e-6
    # A on B0 (a = d at φ = 0) is a single undetermined position, flagged by the kernel
    near_end |= np.abs(d - a * np.exp(1j * phi)) < 1e-9
    assert np.array_equal(closes[~near_end], inside[~near_end])


def test_rocker_limits_against_dense_scan():
    a, b, c, d = 1.0, 3.0, 2.5, 3.0
    for branch in (1, -1):
        lim = rocker_limits(a, b, c, d, branch)
        phi = np.linspace(0, 2 * math.pi, 200_001)
        m = fourbar_motion(a, b, c, d, phi, branch, order=1)
        g = np.unwrap(m.gamma)
        assert lim.swing == pytest.approx(g.max() - g.min(), abs=1e-9)
        at = fourbar_motion(a, b, c, d, [lim.phi_extended, lim.phi_folded], branch, order=1)
        np.testing.assert_allclose(at.dgamma[0], 0.0, atol=1e-12)
        np.testing.assert_allclose(np.sort(at.gamma), np.sort([lim.gamma_extended, lim.gamma_folded]), atol=1e-12)
        # time ratio from the dense scan: crank angles between the extremes of γ
        i_max, i_min = int(np.argmax(g)), int(np.argmin(g))
        fwd = abs(phi[i_max] - phi[i_min])
        assert lim.time_ratio == pytest.approx(max(fwd, 2 * math.pi - fwd) / min(fwd, 2 * math.pi - fwd), rel=1e-4)


def test_rocker_limits_refuses_non_crank_rocker():
    with pytest.raises(AssemblyError, match="crank-rocker"):
        rocker_limits(3, 3, 2.5, 1)


def test_transmission_angle_range():
    m = fourbar_motion(1.0, 3.0, 2.5, 3.0, np.linspace(0, 2 * math.pi, 721), 1, order=0)
    mu = transmission_angle(m)
    # extremes of μ happen with crank along the ground line: cos μ = (b² + c² − (d ∓ a)²)/(2bc)
    mu_min = math.acos((9 + 6.25 - 4) / (2 * 3 * 2.5))
    mu_max = math.acos((9 + 6.25 - 16) / (2 * 3 * 2.5))
    assert mu.min() == pytest.approx(mu_min, abs=1e-12)
    assert mu.max() == pytest.approx(mu_max, abs=1e-12)


# --- properties --------------------------------------------------------------------------------


@settings(max_examples=150, deadline=None)
@given(lengths, lengths, lengths, lengths, angles, branches)
def test_loop_closes_and_nothing_is_nan(a, b, c, d, phi, branch):
    m = fourbar_motion(a, b, c, d, phi, branch)
    for arr in (m.e_theta, *m.dtheta, *m.dgamma):
        assert np.all(np.isfinite(arr))
    if m.status & Status.NOT_ASSEMBLABLE:
        return
    A, B = complex(m.A), complex(m.B)
    scale = a + b + c + d
    assert abs(abs(B - A) - b) < 1e-13 * scale
    assert abs(abs(B - d) - c) < 1e-12 * scale
    # branch: B left (+1) or right (−1) of the directed line A → B0
    side = ((d - A) * np.conj(B - A)).imag  # cross(B − A, B0 − A) < 0 means B left of A→B0
    if abs(side) > 1e-9 * scale**2:
        assert np.sign(-side) == branch


@settings(max_examples=150, deadline=None)
@given(lengths, lengths, lengths, lengths, angles, branches)
def test_derivatives_match_central_differences(a, b, c, d, phi, branch):
    h = 1e-5
    m = fourbar_motion(a, b, c, d, [phi - h, phi, phi + h], branch)
    assume(np.all(m.status == 0))
    # a safe step: away from toggles the derivatives are smooth on the scale h
    assume(np.min(np.abs(m.sin_theta_gamma)) > 0.05)
    # ... and where the links do not whip round (A next to B0 makes θ′ huge): truncation
    # error ~ h²·q⁗ stays far below the tolerance
    assume(np.max(np.abs(m.dtheta[0])) + np.max(np.abs(m.dgamma[0])) < 10)
    dth = np.angle(m.e_theta[2] / m.e_theta[0]) / (2 * h)
    dga = np.angle(m.e_gamma[2] / m.e_gamma[0]) / (2 * h)
    scale = 1 + abs(m.dtheta[0][1]) + abs(m.dgamma[0][1])
    assert abs(dth - m.dtheta[0][1]) < 1e-6 * scale**2
    assert abs(dga - m.dgamma[0][1]) < 1e-6 * scale**2
    for k in (1, 2):
        s = 1 + np.abs(m.dtheta[k][1]) + np.abs(m.dgamma[k][1]) + scale**3
        assert abs((m.dtheta[k - 1][2] - m.dtheta[k - 1][0]) / (2 * h) - m.dtheta[k][1]) < 1e-5 * s
        assert abs((m.dgamma[k - 1][2] - m.dgamma[k - 1][0]) / (2 * h) - m.dgamma[k][1]) < 1e-5 * s


@settings(max_examples=80, deadline=None)
@given(lengths, lengths, lengths, lengths, angles, branches, st.floats(-2, 2), st.floats(-2, 2))
def test_coupler_point_derivatives(a, b, c, d, phi, branch, u, v):
    h = 1e-5
    m = fourbar_motion(a, b, c, d, [phi - h, phi, phi + h], branch)
    assume(np.all(m.status == 0) and np.min(np.abs(m.sin_theta_gamma)) > 0.05)
    z = m.coupler_point(u, v, order=3)
    scale = (1 + abs(u) + abs(v)) * (1 + np.max(np.abs(m.dtheta[0]))) ** 3
    for k in range(3):
        fd = (z[k][2] - z[k][0]) / (2 * h)
        assert abs(fd - z[k + 1][1]) < 1e-5 * scale * (1 + abs(z[k + 1][1]))
    # the pole has zero velocity: z' = 0 at p = w_P e^{-iθ} with w_P = i A'/θ'
    t1 = m.dtheta[0][1]
    assume(abs(t1) > 1e-3)
    A1 = 1j * a * np.exp(1j * phi)
    p = (1j * A1 / t1) / m.e_theta[1]
    assert abs(m.coupler_point(p.real, p.imag, order=1)[1][1]) < 1e-9 * (1 + abs(p))


def test_time_derivatives_chain_rule():
    a, b, c, d, branch = 1.0, 3.0, 2.5, 3.0, 1
    omega, alpha, t0, h = 2.0, 0.7, 0.3, 1e-4
    phi_of_t = lambda t: 0.2 + omega * t + 0.5 * alpha * t * t  # noqa: E731
    ts = t0 + h * np.arange(-2, 3)
    g = np.unwrap(fourbar_motion(a, b, c, d, phi_of_t(ts), branch, order=0).gamma)
    m = fourbar_motion(a, b, c, d, phi_of_t(t0), branch)
    w_now = omega + alpha * t0
    gd, gdd, gddd = time_derivatives(m.dgamma, w_now, alpha)
    fd1 = (g[3] - g[1]) / (2 * h)
    fd2 = (g[3] - 2 * g[2] + g[1]) / h**2
    fd3 = (g[4] - 2 * g[3] + 2 * g[1] - g[0]) / (2 * h**3)
    assert gd == pytest.approx(fd1, rel=1e-7)
    assert gdd == pytest.approx(fd2, rel=1e-5)
    assert gddd == pytest.approx(fd3, rel=1e-3)


# --- contract and errors -----------------------------------------------------------------------


def test_broadcast_shapes_and_dtypes():
    n, k = 4, 7
    m = fourbar_motion(np.ones((n, 1)), np.full((n, 1), 3.0), 2.5, 3.0, np.linspace(0, 6, k), 1)
    assert m.e_theta.shape == (n, k) and m.e_theta.dtype == np.complex128
    assert all(x.shape == (n, k) and x.dtype == np.float64 for x in (*m.dtheta, *m.dgamma))
    assert m.status.shape == (n, k) and m.status.dtype == np.uint8
    assert m.B.shape == (n, k) and m.theta.shape == (n, k)


def test_chunking_matches_single_block(monkeypatch):
    import kinematics.fourbar as fb

    rng = np.random.default_rng(1)
    a = np.ones((50, 1))
    b, c, d = (rng.uniform(2, 4, (50, 1)) for _ in range(3))
    phi = np.linspace(0, 6, 360)
    whole = fourbar_motion(a, b, c, d, phi, 1)
    monkeypatch.setattr(fb, "_CHUNK", 700)
    parts = fourbar_motion(a, b, c, d, phi, 1)
    assert np.array_equal(whole.e_theta, parts.e_theta)
    assert all(np.array_equal(x, y) for x, y in zip(whole.dtheta + whole.dgamma, parts.dtheta + parts.dgamma))
    assert np.array_equal(whole.status, parts.status)


def test_not_assemblable_is_flagged_not_nan():
    m = fourbar_motion(1.0, 1.0, 1.0, 5.0, np.linspace(0, 6, 10))
    assert np.all(m.status & Status.NOT_ASSEMBLABLE)
    assert np.all(np.isfinite(m.e_theta)) and all(np.all(np.isfinite(x)) for x in m.dtheta)


def test_crank_pin_on_rocker_pivot_is_flagged():
    # a = d at φ = 0 puts A on B0: the direction of A→B0 is undefined.
    m = fourbar_motion(2.0, 1.5, 1.5, 2.0, [0.0, 0.5])
    assert m.status[0] & Status.NOT_ASSEMBLABLE and m.status[1] == Status.OK
    assert np.all(np.isfinite(m.e_theta)) and all(np.all(np.isfinite(x)) for x in m.dtheta + m.dgamma)


def test_toggle_is_flagged_with_finite_derivatives():
    # a=1, b=2, c=3, d=2 at φ = 0: |A B0| = 1 and b + 1 = c, coupler and rocker aligned.
    m = fourbar_motion(1.0, 2.0, 3.0, 2.0, 0.0)
    assert m.status == Status.TOGGLE
    assert all(np.isfinite(x) for x in m.dtheta + m.dgamma)


def test_raise_mode_names_the_condition():
    with pytest.raises(AssemblyError, match=r"cannot assemble: \|A-B0\| = 4 is outside"):
        fourbar_motion(1.0, 1.0, 1.0, 5.0, 0.0, on_degenerate="raise")
    with pytest.raises(AssemblyError, match="toggle"):
        fourbar_motion(1.0, 2.0, 3.0, 2.0, 0.0, on_degenerate="raise")
    # positions alone are fine at a toggle
    fourbar_motion(1.0, 2.0, 3.0, 2.0, 0.0, order=0, on_degenerate="raise")


def test_bad_keywords():
    with pytest.raises(ValueError, match="on_degenerate must be one of 'flag', 'raise'"):
        fourbar_motion(1, 2, 2, 2, 0.0, on_degenerate="ignore")
    with pytest.raises(ValueError, match="order must be"):
        fourbar_motion(1, 2, 2, 2, 0.0, order=4)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_crank_range_rejects_bad_lengths(bad):
    with pytest.raises(AssemblyError, match="length a must be"):
        crank_range(bad, 2, 2, 2)
