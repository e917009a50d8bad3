"""Offset slider-crank kernel: reference tables, P204101, loop closure, finite differences, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from kinematics import AssemblyError, Status, time_derivatives
from kinematics.slider_crank import (
    slider_crank_limits,
    slider_crank_motion,
    slider_crank_range,
    slider_time_ratio,
)

branches = st.sampled_from([1, -1])
angles = st.floats(-math.pi, math.pi)


@st.composite
def full_turn(draw):
    """(l1, l2, e) with l1 + |e| < l2 by a margin: no toggle anywhere in the turn."""
    l1 = draw(st.floats(0.2, 5.0))
    e = draw(st.floats(-3.0, 3.0))
    return l1, l1 + abs(e) + draw(st.floats(0.1, 5.0)), e


def assert_close(got, want, rel=1e-9):
    """Relative to the column's magnitude, so that exact zeros of the reference compare too."""
    got, want = np.asarray(got, float), np.asarray(want, float)
    np.testing.assert_allclose(got, want, rtol=rel, atol=rel * max(1.0, float(np.max(np.abs(want)))))


# --- reference values --------------------------------------------------------------------------


def test_reference_table_every_row(reference_cases):
    case = reference_cases["offset_slider_crank_reference"]
    x, rows = case["inputs"], case["rows"]
    phi1 = np.radians([r["phi1_deg"] for r in rows])
    m = slider_crank_motion(x["l1"], x["l2"], x["e"], phi1, on_degenerate="raise")
    w = x["omega1_rad_s"]
    omega2, eps2 = time_derivatives(m.dphi2, w)
    v3, a3 = time_derivatives(m.ds3, w)
    got = {
        "phi2_deg": np.degrees(m.phi2),
        "s3_mm": m.s3,
        "omega2_rad_s": omega2,
        "v3_mm_s": v3,
        "eps2_rad_s2": eps2,
        "a3_mm_s2": a3,
    }
    for key, values in got.items():
        assert_close(values, [r[key] for r in rows])


def test_p204101_both_configurations(reference_cases):
    # Inclined guide (alpha = 30°), e to the right of the guide direction: the kernel's own frame.
    case = reference_cases["P204101_offset_slider_crank"]
    x = case["inputs"]
    got = []
    for branch in (1, -1):
        m = slider_crank_motion(
            x["l1"],
            x["l2"],
            x["e"],
            math.radians(x["theta1"]),
            branch,
            guide_angle=math.radians(x["alpha"]),
            order=0,
            on_degenerate="raise",
        )
        got.append((float(np.degrees(m.phi2)), float(m.s3)))
    for row, pair in zip(case["rows"], got):
        assert_close(pair, row["solver"])
        assert all(abs(v - d) <= h for v, d, h in zip(pair, row["document"], row["doc_half_unit_last_digit"]))


def test_p204101_by_rotating_the_horizontal_case(reference_cases):
    # The same answer from the md §2 frame (guide along +x), rotated by hand: φ1 − α in, φ2 + α out.
    x = reference_cases["P204101_offset_slider_crank"]["inputs"]
    alpha = math.radians(x["alpha"])
    for branch, row in zip((1, -1), reference_cases["P204101_offset_slider_crank"]["rows"]):
        m = slider_crank_motion(x["l1"], x["l2"], x["e"], math.radians(x["theta1"]) - alpha, branch, order=0)
        phi2 = math.degrees(float(np.angle(np.exp(1j * (float(m.phi2) + alpha)))))
        assert_close([phi2, float(m.s3)], row["solver"])


def test_centric_slider_crank_closed_form():
    # e = 0: stroke 2·l1, dead centres at 0 and 180°, time ratio 1.
    lim = slider_crank_limits(2.0, 7.0, 0.0)
    assert lim.stroke == pytest.approx(4.0, rel=1e-15)
    assert (lim.s_max, lim.s_min) == pytest.approx((9.0, 5.0), rel=1e-15)
    assert lim.phi_max == pytest.approx(0.0, abs=1e-15) and lim.phi_min == pytest.approx(math.pi, rel=1e-15)
    assert lim.time_ratio == pytest.approx(1.0, rel=1e-15) and lim.reversals == 2


# --- contract ----------------------------------------------------------------------------------


def test_broadcast_shapes_dtypes_and_flags_without_nan():
    l1 = np.array([[1.0], [2.0], [4.0]])  # the last cannot turn fully: l1 + e > l2
    phi = np.linspace(-math.pi, math.pi, 7)
    m = slider_crank_motion(l1, 3.0, 0.5, phi)
    for arr in (m.phi2, m.s3, *m.dphi2, *m.ds3):
        assert arr.shape == (3, 7) and arr.dtype == np.float64 and np.all(np.isfinite(arr))
    assert m.status.shape == (3, 7) and m.status.dtype == np.uint8
    assert m.ok[:2].all()
    assert (m.status[2] & Status.NOT_ASSEMBLABLE).any()
    assert m.B.shape == m.C.shape == (3, 7)
    assert slider_crank_motion(1.0, 3.0, 0.5, 0.3, order=0).ds3 == ()


def test_toggle_is_flagged_with_finite_values():
    # l1 + e = l2: at φ1 = 90° the rod stands perpendicular to the guide.
    m = slider_crank_motion(1.0, 2.0, 1.0, [math.pi / 2, 0.0])
    assert list(m.status) == [Status.TOGGLE, Status.OK]
    assert all(np.all(np.isfinite(d)) for d in (*m.dphi2, *m.ds3))


@settings(max_examples=60, deadline=None)
@given(st.floats(0.2, 5.0), st.floats(0.2, 5.0), st.floats(-6.0, 6.0), st.floats(-math.pi, math.pi))
@example(l1=0.3, l2=0.2, e=0.5, alpha=0.0)  # found by a random seed: the rod only touches the guide at −90°
def test_crank_range_is_where_the_loop_closes(l1, l2, e, alpha):
    phi = np.linspace(-math.pi, math.pi, 2001)
    closes = (slider_crank_motion(l1, l2, e, phi, guide_angle=alpha, order=0).status & Status.NOT_ASSEMBLABLE) == 0
    inside = np.zeros_like(closes)
    # where the rod just touches the guide the loop closes at one angle (an interval's end, or
    # a lone tangent point that is no interval): rounding decides there, so it is not compared
    near_end = np.abs(np.abs(e + l1 * np.sin(phi - alpha)) - l2) <= 1e-9 * (l1 + l2 + abs(e))
    for lo, hi in slider_crank_range(l1, l2, e, guide_angle=alpha):
        assert -math.pi <= lo < hi
        inside |= np.mod(phi - lo, 2 * math.pi) <= (hi - lo) + 1e-12
        for end in (lo, hi):
            near_end |= np.abs(np.angle(np.exp(1j * (phi - end)))) < 1e-6
    assert np.array_equal(closes[~near_end], inside[~near_end])


# --- properties --------------------------------------------------------------------------------


@settings(max_examples=80, deadline=None)
@given(full_turn(), angles, branches, angles)
def test_loop_closure(links, phi1, branch, alpha):
    l1, l2, e = links
    m = slider_crank_motion(l1, l2, e, phi1, branch, guide_angle=alpha, order=0)
    assert m.status == Status.OK
    B, C = complex(m.B), complex(m.C)
    assert abs(C - B - l2 * np.exp(1j * float(m.phi2))) < 1e-12 * (l1 + l2)
    along = np.exp(-1j * alpha) * C  # C in the guide frame: (s3, −e)
    assert along.imag == pytest.approx(-e, abs=1e-12 * (l1 + l2))
    assert along.real == pytest.approx(float(m.s3), abs=1e-12 * (l1 + l2))
    assert branch * math.cos(float(m.phi2) - alpha) > 0


@settings(max_examples=80, deadline=None)
@given(full_turn(), angles, branches, angles)
def test_finite_differences_of_the_crank_angle_derivatives(links, phi1, branch, alpha):
    l1, l2, e = links
    h = 1e-5
    m = slider_crank_motion(l1, l2, e, np.array([phi1 - h, phi1, phi1 + h]), branch, guide_angle=alpha)
    assert m.ok.all()
    phi2 = np.unwrap(m.phi2)
    for pos, d, scale in ((phi2, m.dphi2, 1.0), (m.s3, m.ds3, l1)):
        fd1 = (pos[2] - pos[0]) / (2 * h)
        fd2 = (d[0][2] - d[0][0]) / (2 * h)  # of the exact first derivative: no h² cancellation
        assert fd1 == pytest.approx(d[0][1], rel=1e-6, abs=1e-6 * scale)
        assert fd2 == pytest.approx(d[1][1], rel=1e-6, abs=1e-6 * scale)


@settings(max_examples=50, deadline=None)
@given(full_turn(), angles, st.floats(0.5, 20.0), st.sampled_from([1.0, -1.0]), st.floats(-50.0, 50.0))
def test_time_derivatives_either_direction_with_crank_acceleration(links, phi1, speed, sense, crank_alpha):
    # s3(φ(t)) with φ = φ1 + ωt + αt²/2, differentiated in time by central differences.
    l1, l2, e = links
    w, dt = sense * speed, 1e-6
    t = np.array([-dt, 0.0, dt])
    m = slider_crank_motion(l1, l2, e, phi1 + w * t + 0.5 * crank_alpha * t * t)
    v, a = time_derivatives(m.ds3, w + crank_alpha * t, crank_alpha)  # the speed at each instant
    assert (m.s3[2] - m.s3[0]) / (2 * dt) == pytest.approx(v[1], rel=1e-5, abs=1e-6 * l1 * speed)
    assert (v[2] - v[0]) / (2 * dt) == pytest.approx(a[1], rel=1e-5, abs=1e-6 * l1 * (speed**2 + abs(crank_alpha)))


@settings(max_examples=40, deadline=None)
@given(full_turn(), angles, branches)
def test_clockwise_flips_velocities_only(links, phi1, branch):
    m = slider_crank_motion(*links, phi1, branch)
    ccw, cw = time_derivatives(m.ds3, 3.0), time_derivatives(m.ds3, -3.0)
    assert cw[0] == -ccw[0] and cw[1] == ccw[1]
    rod_ccw, rod_cw = time_derivatives(m.dphi2, 3.0), time_derivatives(m.dphi2, -3.0)
    assert rod_cw[0] == -rod_ccw[0] and rod_cw[1] == rod_ccw[1]


@settings(max_examples=30, deadline=None)
@given(full_turn(), branches, angles)
def test_limits_against_a_dense_scan(links, branch, alpha):
    l1, l2, e = links
    lim = slider_crank_limits(l1, l2, e, branch, guide_angle=alpha)
    at = slider_crank_motion(l1, l2, e, [lim.phi_max, lim.phi_min], branch, guide_angle=alpha, order=1)
    np.testing.assert_allclose(at.ds3[0], 0.0, atol=1e-12 * (l1 + l2))
    np.testing.assert_allclose(at.s3, [lim.s_max, lim.s_min], rtol=1e-12, atol=1e-12 * l2)
    phi = np.linspace(0.0, 2 * math.pi, 20_001)
    s = slider_crank_motion(l1, l2, e, phi, branch, guide_angle=alpha, order=0).s3
    assert lim.s_max >= s.max() - 1e-12 * l2 and lim.s_min <= s.min() + 1e-12 * l2
    assert lim.stroke == pytest.approx(s.max() - s.min(), rel=1e-6)
    rising = np.mod(lim.phi_max - lim.phi_min, 2 * math.pi)  # CCW from the minimum to the maximum
    assert lim.time_ratio == pytest.approx(max(rising, 2 * math.pi - rising) / min(rising, 2 * math.pi - rising))
    assert lim.time_ratio >= 1.0 and lim.reversals == 2


def test_time_ratio_helper_rejects_a_slider_that_does_not_move():
    assert slider_time_ratio([0.0, 2.0], [1.0, 3.0]) == (pytest.approx((2 * math.pi - 2.0) / 2.0), 2)
    with pytest.raises(ValueError, match="back and forth"):
        slider_time_ratio([0.0, 2.0], [1.0, 1.0])


# --- errors ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(l1=0.0), "length l1 must be > 0"),
        (dict(l2=-1.0), "length l2 must be > 0"),
        (dict(l1=float("nan")), "length l1 must be finite"),
        (dict(e=float("inf")), "e must be finite"),
        (dict(phi1=float("nan")), "phi1 must be finite"),
        (dict(branch=2), "branch must be"),
    ],
)
def test_bad_values_raise(kwargs, message):
    args = dict(l1=1.0, l2=3.0, e=0.5, phi1=0.3) | kwargs
    with pytest.raises(AssemblyError, match=message):
        slider_crank_motion(**args)


def test_bad_options_raise_value_error():
    with pytest.raises(ValueError, match="on_degenerate must be one of 'flag', 'raise'"):
        slider_crank_motion(1.0, 3.0, 0.5, 0.3, on_degenerate="nan")
    with pytest.raises(ValueError, match="order must be 0, 1 or 2"):
        slider_crank_motion(1.0, 3.0, 0.5, 0.3, order=3)


def test_unreachable_position_names_the_condition_and_the_reach():
    with pytest.raises(
        AssemblyError,
        match=r"\|e \+ l1 sin\(phi1\)\| = 5 > l2 = 3.*reachable crank angles \[deg\]: \[160.529, 379.471\]",
    ):
        slider_crank_motion(3.0, 3.0, 2.0, [0.0, math.pi / 2], on_degenerate="raise")


def test_toggle_raises_in_raise_mode_only_with_derivatives():
    slider_crank_motion(1.0, 2.0, 1.0, math.pi / 2, order=0, on_degenerate="raise")
    with pytest.raises(AssemblyError, match=r"perpendicular to the guide \(cos phi2 = 0"):
        slider_crank_motion(1.0, 2.0, 1.0, math.pi / 2, on_degenerate="raise")


def test_limits_need_a_full_turn():
    with pytest.raises(AssemblyError, match=r"need a full-turn crank: l1 \+ \|e\| = 5 > l2 = 4"):
        slider_crank_limits(3.0, 4.0, -2.0)
    assert slider_crank_range(1.0, 0.5, 2.0) == []
    assert slider_crank_range(1.0, 3.0, 2.0) == [(-math.pi, math.pi)]
