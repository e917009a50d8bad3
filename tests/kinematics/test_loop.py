"""kinematics.loop: closed-form values of the shared loop kernels."""

import math
import warnings

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from kinematics.loop import (
    circle_intersection,
    line_intersection,
    parabola_vertex,
    sampled_extreme,
    transmission_fold,
)
from kinematics.status import Status


def test_circle_intersection_is_the_3_4_5_triangle():
    # centres 0 and 5, radii 3 and 4: the right angle sits at 1.8 + 2.4i (branch +1, left of 0 → 5)
    loop = circle_intersection(5 + 0j, 3.0, 4.0, np.array([1.0, -1.0]))
    np.testing.assert_allclose(3 * loop.e1, [1.8 + 2.4j, 1.8 - 2.4j], atol=1e-15)
    np.testing.assert_allclose(5 + 4 * loop.e2, 3 * loop.e1, atol=1e-15)
    np.testing.assert_allclose(loop.transmission, math.pi / 2, atol=1e-7)  # arccos near 0: ~1e-8
    np.testing.assert_allclose(np.abs(loop.sin_relative), 1.0, rtol=1e-15)
    assert not loop.status.any()


def test_circle_intersection_flags_with_unit_placeholders():
    loop = circle_intersection(np.array([10 + 0j, 0j, 7 + 0j]), 3.0, 4.0, 1.0)
    assert list(loop.status) == [Status.NOT_ASSEMBLABLE, Status.NOT_ASSEMBLABLE, Status.TOGGLE]
    np.testing.assert_allclose(np.abs(loop.e1), 1.0, rtol=1e-15)
    np.testing.assert_allclose(np.abs(loop.e2), 1.0, rtol=1e-15)
    assert np.all(np.isfinite(loop.rates(np.ones(3) + 1j)))
    assert not np.any(loop.rates(np.ones(3) + 1j)[0])  # flagged: rates are 0


@pytest.mark.parametrize("scale", [1e-150, 1e77, 1e100, 1e150])
def test_circle_intersection_does_not_depend_on_the_unit(scale):
    """Heron's product of four lengths overflows beyond ~1e77 (it did: NaN poles from
    `dwell curvature --a 1e100 …`); the angles and status must be those of the same loop at
    unit scale, at every scale the command line accepts."""
    R = np.array([5 + 0j, 6.9 + 0.1j, 10 + 0j, 3 + 4j])
    unit = circle_intersection(R, 3.0, 4.0, 1.0)
    big = circle_intersection(R * scale, 3.0 * scale, 4.0 * scale, 1.0)
    assert list(big.status) == list(unit.status)
    for a, b in ((big.e1, unit.e1), (big.e2, unit.e2)):
        assert np.all(np.isfinite(a))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-14)
    np.testing.assert_allclose(big.height, unit.height * scale, rtol=1e-13)


#: a length the command line accepts, spread over its whole range (1e-150 … 1e150)
_lengths = st.floats(-150.0, 150.0).map(lambda e: 10.0**e)


@settings(max_examples=300, deadline=None)
@given(r=_lengths, l1=_lengths, l2=_lengths)
@example(r=1e100, l1=1.0, l2=1.0)  # `dwell analyze fourbar --d 1e100`: numpy's overflow warning on the terminal
@example(r=1e150, l1=1e-150, l2=1e-150)
@example(r=1e61, l1=1.0, l2=1.0)
@example(r=1e-150, l1=1e150, l2=1e150)
@example(r=1.0, l1=1e-87, l2=1e111)  # links 1e198 apart: cos β overflowed (a random seed found it)
@example(r=1e-159, l1=1e-150, l2=1e-150)  # 1/(2·l1·r) overflowed: NaN at status OK in the kernel
def test_circle_intersection_is_quiet_and_finite_at_every_scale(r, l1, l2):
    """At any distance and radii the command line accepts, the closing point is computed
    without a floating-point warning (they reach the user's terminal), every value is finite,
    a loop that clearly cannot close is flagged and one that clearly can is not; the compiled
    scalar form (``synth.mechanism.sixbar_kernel.closing_point``) gives the same angles and status."""
    from synth.mechanism.sixbar_kernel import closing_point

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        loop = circle_intersection(np.array([r + 0j]), l1, l2, 1.0)
    values = [loop.cos1, loop.sin1, loop.cos2, loop.sin2, loop.height, loop.k1, loop.k2]
    assert all(np.all(np.isfinite(v)) for v in values)
    low, high = abs(l1 - l2), l1 + l2
    status = int(loop.status[0])
    if r > high * (1 + 1e-9) or r < low * (1 - 1e-9):
        assert status == Status.NOT_ASSEMBLABLE
    elif low * (1 + 1e-6) < r < high * (1 - 1e-6) and r > 1e-9 * high:
        assert status == 0
    c1, s1, c2, s2, k_status, _, _ = closing_point(r, 0.0, l1, l2, 1.0)
    assert k_status == status
    assert (c1, s1, c2, s2) == (loop.cos1[0], loop.sin1[0], loop.cos2[0], loop.sin2[0])


@pytest.mark.parametrize("scale", [1e-150, 1e-100, 1e100, 1e150])
def test_a_loop_whose_centres_nearly_meet_is_the_same_at_every_scale(scale):
    """Centres 1e-9 of the links apart: at 1e-150, 1/(2·l1·r) overflowed (NaN angles at status
    OK from the compiled kernel, nulls from `dwell analyze fourbar`). Solved in units of the
    links, the angles are those of the loop at unit scale, the height and rate factors scaled."""
    from synth.mechanism.sixbar_kernel import closing_point

    R = np.array([2e-9 + 0j, 3e-9 + 1e-9j])
    unit = circle_intersection(R, 1.0, 1.0 + 1e-9, 1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        big = circle_intersection(R * scale, scale, (1.0 + 1e-9) * scale, 1.0)
    assert list(big.status) == list(unit.status) == [0, 0]
    # the scaled inputs round differently, and the angles' condition number here is ~l/r = 1e9
    for a, b in ((big.e1, unit.e1), (big.e2, unit.e2)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-6)
    np.testing.assert_allclose(big.height, unit.height * scale, rtol=1e-6)
    np.testing.assert_allclose(big.k1 * scale, unit.k1, rtol=1e-6)
    for z, e1 in zip(R * scale, big.e1):
        c1, s1, *_ = closing_point(z.real, z.imag, scale, (1.0 + 1e-9) * scale, 1.0)
        assert complex(c1, s1) == e1  # the same operations


def test_rates_match_a_finite_difference():
    # R(t) = 5 + t·i moves centre 2 up; l1, l2 fixed: θ′, γ′ from i·l1·θ′e1 − i·l2·γ′e2 = R′
    h = 1e-6
    theta = [np.angle(circle_intersection(5 + t * 1j, 3.0, 4.0, 1.0).e1) for t in (-h, h)]
    gamma = [np.angle(circle_intersection(5 + t * 1j, 3.0, 4.0, 1.0).e2) for t in (-h, h)]
    x, y = circle_intersection(5 + 0j, 3.0, 4.0, 1.0).rates(1j)
    assert float(x) == pytest.approx((theta[1] - theta[0]) / (2 * h), rel=1e-8)
    assert float(y) == pytest.approx((gamma[1] - gamma[0]) / (2 * h), rel=1e-8)


def test_line_intersection():
    hit = line_intersection(0j, 1 + 0j, 3 + 4j, np.exp(0.5j * math.pi))  # the x-axis and x = 3
    assert (float(hit.t1), float(hit.t2), int(hit.status)) == (pytest.approx(3.0), pytest.approx(-4.0), 0)
    assert line_intersection(0j, 1 + 0j, 1j, np.exp(1e-10j)).parallel  # |sin| 1e-10 < PARALLEL_EPS


def test_parabola_vertex_is_exact_for_a_parabola():
    # y = 2 − 3(x − 0.25)² sampled at −1, 0, 1: vertex at +0.25 steps, value 2
    y = [2 - 3 * (x - 0.25) ** 2 for x in (-1.0, 0.0, 1.0)]
    v = parabola_vertex(*y)
    assert float(v.offset) == pytest.approx(0.25) and float(y[1] + v.rise) == pytest.approx(2.0)
    assert float(v.curvature) == pytest.approx(-6.0)
    assert parabola_vertex(1.0, 2.0, 3.0) == (0.0, 0.0, 0.0)  # a straight line has no vertex


def test_sampled_extreme_refines_a_cosine():
    phi = np.arange(360) * (2 * math.pi / 360) + 0.3 * math.pi / 180  # peak between samples
    hi, k = sampled_extreme(np.cos(phi - 0.5), +1)
    lo, _ = sampled_extreme(np.cos(phi - 0.5), -1)
    # the samples miss the peak by ~1e-5; the vertex is within h⁴/24 ≈ 4e-9 (h = 1°)
    assert 1 - np.cos(phi - 0.5).max() > 1e-6
    assert float(hi) == pytest.approx(1.0, abs=5e-9) and float(lo) == pytest.approx(-1.0, abs=5e-9)
    assert abs(phi[k] - 0.5) <= math.pi / 360


def test_transmission_fold():
    mu = transmission_fold(np.exp(1j * np.radians([0.0, 30.0, 90.0, 150.0, 180.0, -120.0])))
    np.testing.assert_allclose(np.degrees(mu), [0.0, 30.0, 90.0, 30.0, 0.0, 60.0], atol=1e-6)
