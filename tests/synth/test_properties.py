"""Hypothesis properties on bounded strategies: any input gives finite values and consistent
flags, scaling and mirroring act on the geometry as they should, bad input is refused."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from mp_fourbar import Instant, distance_to_ball_point, distance_to_cubic

from kinematics.fourbar import fourbar_motion
from kinematics.status import AssemblyError, Status
from synth import ball_point, double_ball_points, euler_savary, inflection_circle, line_scan, pole
from synth.types import INVALID

length = st.floats(1e-3, 1e3, allow_nan=False, allow_infinity=False)
angle = st.floats(-20.0, 20.0, allow_nan=False, allow_infinity=False)
branch = st.sampled_from([1, -1])
SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _evaluate(a, b, c, d, phi, br, alpha):
    pl = pole(fourbar_motion(a, b, c, d, phi, br))
    return pl, inflection_circle(pl), ball_point(pl), line_scan(pl, alpha), euler_savary(pl, pl.to_fixed(3.0 + 1j))


@SETTINGS
@given(length, length, length, length, angle, branch, st.lists(angle, min_size=1, max_size=5))
def test_any_linkage_gives_finite_values_and_flags_it_cannot_answer(a, b, c, d, phi, br, alpha):
    results = _evaluate(a, b, c, d, phi, br, np.array(alpha))
    pl = results[0]
    for res in results:
        for name in res.__slots__:
            value = getattr(res, name)
            for arr in value if isinstance(value, tuple) else (value,):
                arr = np.asarray(arr)
                if arr.dtype.kind in "fc":
                    assert np.all(np.isfinite(arr)), name
        # a flagged instant flags every result derived from it
        assert np.all((np.asarray(res.status) & int(pl.status)) == int(pl.status))
    if pl.status & INVALID:  # finite placeholders: no circle, no pair
        assert np.all(results[3].radius == 0) and np.all(results[1].diameter == 0)
    if pl.status & (INVALID & ~Status.INFLECTION_CIRCLE_COLLAPSED):  # the pole itself is unknown
        assert pl.point == 0


@SETTINGS
@given(st.floats(1.2, 6), st.floats(1.2, 6), st.floats(1.2, 6), angle, branch, angle, st.floats(1e-3, 1e3))
@example(b=1.4, c=1.2, d=1.2, phi=0.0, br=1, alpha=0.0, s=0.001)  # exactly at a toggle
def test_scaling_the_linkage_scales_the_geometry(b, c, d, phi, br, alpha, s):
    base = _evaluate(1.0, b, c, d, phi, br, alpha)
    scaled = _evaluate(s, s * b, s * c, s * d, phi, br, alpha)
    # exactly at a toggle (|R| = |b ± c|) rounding of the scaled lengths may tip the loop
    # either way: "toggle" in one copy and "cannot assemble" in the other are both right
    edge = int(Status.TOGGLE | Status.NOT_ASSEMBLABLE | Status.ILL_CONDITIONED)
    ignore = int(Status.CENTER_POINT_AT_INFINITY)
    if int(base[0].status) & edge and int(scaled[0].status) & edge:
        ignore |= edge
    for r1, r2 in zip(base, scaled):
        assert int(np.asarray(r1.status).flat[0]) & ~ignore == int(np.asarray(r2.status).flat[0]) & ~ignore
    pl, circle, ball, scan, _ = base
    pl_s, circle_s, ball_s, scan_s, _ = scaled
    if pl.status == 0:
        assert abs(pl_s.point - s * pl.point) <= 1e-9 * s * (1 + abs(pl.point))
        assert circle_s.diameter == pytest.approx(s * circle.diameter, rel=1e-9)
    if ball.status == 0:
        assert abs(ball_s.uv - s * ball.uv) <= 1e-9 * s * (1 + abs(ball.uv))
    if scan.status == 0 and scan_s.status == 0:
        assert abs(scan_s.circle_point_uv - s * scan.circle_point_uv) <= 1e-8 * s * (1 + abs(scan.circle_point_uv))


@SETTINGS
@given(st.floats(1.2, 6), st.floats(1.2, 6), st.floats(1.2, 6), angle, angle)
def test_mirroring_the_linkage_mirrors_the_geometry(b, c, d, phi, alpha):
    """Reflecting in the ground line: branch → −branch, φ → −φ, α → −α, z → conj(z)."""
    pl, circle, ball, scan, _ = _evaluate(1.0, b, c, d, phi, 1, alpha)
    pl_m, circle_m, ball_m, scan_m, _ = _evaluate(1.0, b, c, d, -phi, -1, -alpha)
    if pl.status or pl_m.status:
        return
    tol = lambda z: 1e-9 * (1 + abs(z))  # noqa: E731
    assert abs(pl_m.point - np.conj(pl.point)) <= tol(pl.point)
    if ball.status == 0 and ball_m.status == 0:
        assert abs(ball_m.point - np.conj(ball.point)) <= tol(ball.point)
        assert abs(ball_m.uv - np.conj(ball.uv)) <= tol(ball.uv)  # the coupler frame mirrors too
    if scan.status == 0 and scan_m.status == 0:
        assert abs(scan_m.circle_point - np.conj(scan.circle_point)) <= 1e-8 * (1 + abs(scan.circle_point))


@settings(max_examples=60, deadline=None)
@given(st.floats(1.2, 6), st.floats(1.2, 6), st.floats(1.2, 6), angle, branch, angle)
def test_circle_points_lie_on_the_40_digit_cubic(b, c, d, phi, br, alpha):
    pl, circle, ball, scan, _ = _evaluate(1.0, b, c, d, phi, br, alpha)
    if scan.status and ball.status:
        return  # the loop need not close at a drawn angle
    inst = Instant(1.0, b, c, d, br, phi)
    if scan.status == 0:
        p = complex(scan.circle_point_uv)
        assert distance_to_cubic(inst, p) <= 1e-9 * max(1.0, abs(p))
    if ball.status == 0:
        assert distance_to_ball_point(inst, complex(ball.uv)) <= 1e-9 * max(1.0, abs(ball.uv))


@settings(max_examples=40, deadline=None)
@given(st.one_of(st.floats(max_value=0.0), st.just(float("nan")), st.just(float("inf"))), st.integers(0, 3))
def test_impossible_lengths_are_refused_with_the_documented_error(bad, which):
    lengths = [1.0, 3.0, 2.5, 3.0]
    lengths[which] = bad
    with pytest.raises(AssemblyError, match="length"):
        double_ball_points(*lengths)


@settings(max_examples=40, deadline=None)
@given(st.text(max_size=8).filter(lambda s: s not in ("flag", "raise")))
def test_unknown_on_degenerate_is_refused(mode):
    pl = pole(fourbar_motion(1.0, 3.0, 2.5, 3.0, 0.5))
    for call in (
        lambda: pole(fourbar_motion(1.0, 3.0, 2.5, 3.0, 0.5), on_degenerate=mode),
        lambda: inflection_circle(pl, on_degenerate=mode),
        lambda: ball_point(pl, on_degenerate=mode),
        lambda: line_scan(pl, 0.1, on_degenerate=mode),
        lambda: euler_savary(pl, 1j, on_degenerate=mode),
    ):
        with pytest.raises(ValueError, match="on_degenerate"):
            call()
