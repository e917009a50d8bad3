"""Quick-return shaper kernel: reference table, loop closure, finite differences, limits, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinematics import AssemblyError, Status, time_derivatives
from kinematics.shaper import check_shaper, shaper_limits, shaper_motion

REFERENCE = dict(l1=60.0, l3=300.0, l4=150.0, h=200.0, e=30.0)
angles = st.floats(-math.pi, math.pi)
branches = st.sampled_from([1, -1])


@st.composite
def shapers(draw):
    """(l1, l3, l4, h, e) meeting every assembly condition by a margin (no toggle in the turn)."""
    h = draw(st.floats(1.0, 5.0))
    l1 = h * draw(st.floats(0.1, 0.9))
    l3 = (l1 + h) * draw(st.floats(1.05, 2.0))
    e = draw(st.floats(-h, h))
    reach = max(l3 + e - h, h - e - l3 * math.sqrt(1 - (l1 / h) ** 2), 0.0)
    return l1, l3, reach + draw(st.floats(0.1, 3.0)), h, e


# --- reference values --------------------------------------------------------------------------


def test_reference_table_every_row(reference_cases):
    case = reference_cases["shaper_crank_guiderod_slider_reference"]
    x, rows = case["inputs"], case["rows"]
    assert {k: x[k] for k in REFERENCE} == REFERENCE
    m = shaper_motion(**REFERENCE, phi1=np.radians([r["phi1_deg"] for r in rows]), on_degenerate="raise")
    w = x["omega1_rad_s"]
    (v2, a2), (omega3, eps3), (omega4, eps4), (v5, a5) = (
        time_derivatives(d, w) for d in (m.ds2, m.dphi3, m.dphi4, m.ds5)
    )
    got = {
        "s2_mm": m.s2,
        "phi3_deg": np.degrees(m.phi3),
        "phi4_deg": np.degrees(m.phi4),
        "s5_mm": m.s5,
        "v2_mm_s": v2,
        "omega3_rad_s": omega3,
        "omega4_rad_s": omega4,
        "v5_mm_s": v5,
        "a2_mm_s2": a2,
        "eps3_rad_s2": eps3,
        "eps4_rad_s2": eps4,
        "a5_mm_s2": a5,
    }
    assert set(got) | {"phi1_deg"} == set(rows[0])
    for key, values in got.items():
        want = [r[key] for r in rows]
        # relative to the column's magnitude, so that the exact zeros at 90° and 270° compare too
        assert list(values) == pytest.approx(want, rel=1e-9, abs=1e-9 * max(map(abs, want))), key


def test_reference_limits_closed_form():
    # Symmetric extremes: the rod tangent to the crank circle, cos φ3 = ±l1/h, link 4 mirrored,
    # so the stroke is 2·l3·l1/h and the time ratio (π + 2 asin(l1/h))/(π − 2 asin(l1/h)).
    lim = shaper_limits(**REFERENCE)
    turn = math.asin(60 / 200)
    assert lim.stroke == pytest.approx(2 * 300 * 60 / 200, rel=1e-14)
    assert lim.time_ratio == pytest.approx((math.pi + 2 * turn) / (math.pi - 2 * turn), rel=1e-14)
    assert lim.phi_max == pytest.approx(2 * math.pi - turn, rel=1e-14)
    assert lim.phi_min == pytest.approx(math.pi + turn, rel=1e-14)
    assert lim.reversals == 2


def test_collinear_rod_and_link_make_the_slider_turn_back_twice():
    # sin φ3 = h/(l3 + l4) lies inside the rod's swing: rod and link 4 stretch out in line
    # twice a turn (the maximum), with a small return between them at the rod's extreme.
    l1, l3, l4, h, e = 190.0, 400.0, 210.0, 200.0, 0.0
    lim = shaper_limits(l1, l3, l4, h, e)
    assert lim.reversals == 4
    assert lim.s_max == pytest.approx((l3 + l4) * math.sqrt(1 - (h / (l3 + l4)) ** 2), rel=1e-14)
    phi = np.linspace(0.0, 2 * math.pi, 400_001)[:-1]
    m = shaper_motion(l1, l3, l4, h, e, phi, order=1)
    assert m.ok.all()
    assert lim.s_max >= m.s5.max() and lim.s_max - m.s5.max() < 1e-6
    assert lim.s_min <= m.s5.min() and m.s5.min() - lim.s_min < 1e-6
    up, down = np.count_nonzero(m.ds5[0] > 0), np.count_nonzero(m.ds5[0] < 0)
    assert lim.time_ratio == pytest.approx(max(up, down) / min(up, down), rel=1e-4)


# --- contract ----------------------------------------------------------------------------------


def test_broadcast_shapes_dtypes_and_flags_without_nan():
    l4 = np.array([[150.0], [40.0]])  # the second cannot reach the slider line
    phi = np.linspace(-math.pi, math.pi, 9)
    m = shaper_motion(60.0, 300.0, l4, 200.0, 30.0, phi)
    for arr in (m.s2, m.phi3, m.phi4, m.s5, *m.ds2, *m.dphi3, *m.dphi4, *m.ds5):
        assert arr.shape == (2, 9) and arr.dtype == np.float64 and np.all(np.isfinite(arr))
    assert m.status.dtype == np.uint8 and m.ok[0].all()
    assert (m.status[1] == Status.NOT_ASSEMBLABLE).all()
    for point in (m.B, m.C, m.D, m.E):
        assert point.shape == (2, 9)
    assert shaper_motion(**REFERENCE, phi1=0.0, order=0).ds5 == ()


def test_b_on_the_rod_pivot_is_flagged_not_nan():
    m = shaper_motion(2.0, 10.0, 9.0, 2.0, 1.0, [-math.pi / 2, 0.0])
    assert list(m.status) == [Status.NOT_ASSEMBLABLE, Status.OK]
    assert all(np.all(np.isfinite(x)) for x in (m.phi3, m.s5, *m.dphi3, *m.ds5))


def test_toggle_of_link_4_is_flagged():
    # l4 = l3 + e − h exactly: link 4 hangs vertically when the rod is upright (φ1 = 90°).
    m = shaper_motion(60.0, 300.0, 130.0, 200.0, 30.0, [math.pi / 2, 0.0])
    assert list(m.status) == [Status.TOGGLE, Status.OK]
    with pytest.raises(AssemblyError, match=r"link 4 is perpendicular to the slider line \(cos phi4 = 0\)"):
        shaper_motion(60.0, 300.0, 130.0, 200.0, 30.0, math.pi / 2, on_degenerate="raise")


# --- properties --------------------------------------------------------------------------------


@settings(max_examples=80, deadline=None)
@given(shapers(), angles, branches)
def test_loop_closure(dims, phi1, branch):
    l1, l3, l4, h, e = dims
    check_shaper(*dims, branch)
    m = shaper_motion(*dims, phi1, branch, order=0)
    assert m.status == Status.OK
    B, C, D, E = (complex(p) for p in (m.B, m.C, m.D, m.E))
    tol = 1e-12 * (l3 + l4 + h)
    assert abs(B - C) == pytest.approx(float(m.s2), abs=tol)
    assert abs((B - C) * np.conj(D - C)).imag < tol * l3  # B lies on the rod C→D
    assert abs(D - C) == pytest.approx(l3, abs=tol) and abs(E - D) == pytest.approx(l4, abs=tol)
    assert abs(E - D - l4 * np.exp(1j * float(m.phi4))) < tol
    assert E.imag == -e and 0 < float(m.phi3) < math.pi and branch * math.cos(float(m.phi4)) > 0


@settings(max_examples=80, deadline=None)
@given(shapers(), angles, branches)
def test_finite_differences_of_the_crank_angle_derivatives(dims, phi1, branch):
    step = 1e-5
    m = shaper_motion(*dims, np.array([phi1 - step, phi1, phi1 + step]), branch)
    assert m.ok.all()
    # rows s2, φ3, φ4, s5; columns φ1 − step, φ1, φ1 + step
    pos = np.stack([m.s2, m.phi3, np.unwrap(m.phi4), m.s5])
    first = np.stack([m.ds2[0], m.dphi3[0], m.dphi4[0], m.ds5[0]])
    second = np.stack([m.ds2[1], m.dphi3[1], m.dphi4[1], m.ds5[1]])
    scale = np.array([dims[0], 1.0, 1.0, dims[0]])
    # the second derivative from the exact first one: no step² cancellation
    for q, exact in ((pos, first[:, 1]), (first, second[:, 1])):
        error = np.abs((q[:, 2] - q[:, 0]) / (2 * step) - exact)
        assert np.all(error <= 1e-6 * (np.abs(exact) + scale)), (error, exact)


@settings(max_examples=40, deadline=None)
@given(shapers(), angles, st.floats(0.5, 20.0), st.sampled_from([1.0, -1.0]), st.floats(-50.0, 50.0))
def test_time_derivatives_either_direction_with_crank_acceleration(dims, phi1, speed, sense, crank_alpha):
    # Every coordinate q(φ(t)), φ = φ1 + ωt + αt²/2, against central differences in time.
    w, dt = sense * speed, 1e-6
    t = np.array([-dt, 0.0, dt])
    m = shaper_motion(*dims, phi1 + w * t + 0.5 * crank_alpha * t * t)
    rate = speed + abs(crank_alpha) ** 0.5  # of the crank, in 1/s
    coords = ((m.s2, m.ds2, dims[0]), (m.phi3, m.dphi3, 1.0), (np.unwrap(m.phi4), m.dphi4, 1.0), (m.s5, m.ds5, dims[0]))
    for q, d, size in coords:
        v, a = time_derivatives(d, w + crank_alpha * t, crank_alpha)  # the speed at each instant
        for k, (of, exact) in enumerate(((q, v[1]), (v, a[1])), start=1):
            assert abs((of[2] - of[0]) / (2 * dt) - exact) <= 1e-5 * (abs(exact) + size * rate**k)


@settings(max_examples=40, deadline=None)
@given(shapers(), angles, branches)
def test_clockwise_flips_velocities_only(dims, phi1, branch):
    m = shaper_motion(*dims, phi1, branch)
    for d in (m.ds2, m.dphi3, m.dphi4, m.ds5):
        ccw, cw = time_derivatives(d, 2.5), time_derivatives(d, -2.5)
        assert cw[0] == -ccw[0] and cw[1] == ccw[1]


@settings(max_examples=30, deadline=None)
@given(shapers(), branches)
def test_limits_against_a_dense_scan(dims, branch):
    lim = shaper_limits(*dims, branch)
    at = shaper_motion(*dims, [lim.phi_max, lim.phi_min], branch, order=1)
    np.testing.assert_allclose(at.ds5[0], 0.0, atol=1e-9 * dims[1])
    np.testing.assert_allclose(at.s5, [lim.s_max, lim.s_min], rtol=1e-12, atol=1e-12 * dims[1])
    phi = np.linspace(0.0, 2 * math.pi, 20_001)
    s = shaper_motion(*dims, phi, branch, order=0).s5
    tol = 1e-12 * (dims[1] + dims[2])
    assert lim.s_max >= s.max() - tol and lim.s_min <= s.min() + tol
    assert lim.stroke == pytest.approx(s.max() - s.min(), rel=1e-5)
    assert lim.time_ratio >= 1.0 and lim.reversals in (2, 4)


# --- errors ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "dims, message",
    [
        (
            dict(l1=200.0),
            r"condition l1 < h violated \(l1 = 200, h = 200\): the guide rod would pass through its pivot C",
        ),
        (dict(l1=250.0, l3=600.0), r"condition l1 < h violated .* turn fully"),
        (dict(l3=260.0), r"condition l1 \+ h < l3 violated \(260 >= 260\): block 2 would run off"),
        (dict(l4=130.0), r"condition l3 \+ e - h < l4 violated \(130 >= 130\)"),
        (dict(l1=190.0, l3=400.0, l4=150.0, e=-100.0), r"condition h - e - l3\*sqrt\(1 - \(l1/h\)\^2\) < l4 violated"),
        (dict(l1=0.0), "length l1 must be > 0"),
        (dict(l3=-300.0), "length l3 must be > 0"),
        (dict(l4=float("nan")), "length l4 must be finite"),
        (dict(h=0.0), "length h must be > 0"),
        (dict(e=float("inf")), "e must be finite"),
    ],
)
def test_every_assembly_condition_is_named(dims, message):
    args = REFERENCE | dims
    with pytest.raises(AssemblyError, match=message):
        check_shaper(**args)
    with pytest.raises(AssemblyError, match=message):
        shaper_limits(**args)


def test_branch_and_options_are_checked():
    with pytest.raises(AssemblyError, match="branch must be"):
        shaper_motion(**REFERENCE, phi1=0.0, branch=0)
    with pytest.raises(ValueError, match="on_degenerate must be one of"):
        shaper_motion(**REFERENCE, phi1=0.0, on_degenerate="ignore")
    with pytest.raises(ValueError, match="order must be 0, 1 or 2"):
        shaper_motion(**REFERENCE, phi1=0.0, order=5)


@pytest.mark.parametrize(
    "dims, phi1_deg, message",
    [
        (dict(l3=250.0), 90.0, r"s2 = \|CB\| = 260 > l3 = 250, block 2 is off the rod"),
        (
            dict(l4=120.0),
            90.0,
            r"at crank angle 90 deg .*\|h - e - l3 sin\(phi3\)\| = 130 > l4 = 120, link 4 cannot reach the slider line",
        ),
        (dict(l1=200.0), -90.0, r"B lies on the rod pivot C \(l1 = h\)"),
    ],
)
def test_positions_that_cannot_assemble_raise_with_the_reason(dims, phi1_deg, message):
    phi = np.radians([0.0, phi1_deg])
    with pytest.raises(AssemblyError, match=message):
        shaper_motion(**(REFERENCE | dims), phi1=phi, on_degenerate="raise")
