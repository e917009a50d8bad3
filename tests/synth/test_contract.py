"""Contract of every public curvature kernel: shapes, dtypes, broadcasting, flags, no NaN/inf,
``on_degenerate``, frozen results; closed-form reference values (the paths of A and B)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from kinematics.fourbar import fourbar_motion
from kinematics.status import AssemblyError, Status
from synth import (
    ball_point,
    euler_savary,
    inflection_circle,
    line_scan,
    pole,
)

CRANK_ROCKER = (1.0, 3.0, 2.5, 3.0)


def _grid(n=3, m=5):
    rng = np.random.default_rng(1)
    b, c, d = rng.uniform(2.5, 3.5, (3, n, 1, 1))
    a = np.ones((n, 1, 1))
    phi = np.linspace(0, 2 * np.pi, m, endpoint=False)[:, None]
    return fourbar_motion(a, b, c, d, phi, 1)


def _all_arrays(result):
    for name in result.__slots__:
        value = getattr(result, name)
        yield from (value if isinstance(value, tuple) else (value,))


def test_shapes_and_dtypes_broadcast_linkages_angles_rays():
    motion = _grid(3, 5)
    pl = pole(motion)
    assert pl.shape == (3, 5, 1)
    alpha = np.linspace(0, np.pi, 7, endpoint=False)
    scan = line_scan(pl, alpha)
    for arr in (scan.circle_point, scan.circle_point_uv, scan.center_point):
        assert arr.shape == (3, 5, 7) and arr.dtype == np.complex128
    assert scan.radius.shape == (3, 5, 7) and scan.radius.dtype == np.float64
    assert scan.status.shape == (3, 5, 7) and scan.status.dtype == np.uint16
    circle, ball = inflection_circle(pl), ball_point(pl)
    for res in (circle, ball):
        assert res.status.shape == (3, 5, 1) and res.status.dtype == np.uint16
    assert circle.center.dtype == np.complex128 and circle.diameter.dtype == np.float64
    assert ball.point.dtype == ball.uv.dtype == ball.tangent.dtype == np.complex128
    centres = euler_savary(pl, pl.point + np.array([1.0, 2j]))
    assert centres.center.shape == (3, 5, 2) and centres.status.dtype == np.uint16


def test_general_broadcasting_matches_the_per_instant_fast_path():
    motion = _grid(2, 4)
    pl = pole(motion)
    alpha = np.linspace(0.1, 3.0, 5)
    fast = line_scan(pl, alpha)
    full = line_scan(pl, np.broadcast_to(alpha, (2, 4, 5)).copy())
    for name in ("circle_point", "circle_point_uv", "center_point", "radius", "status"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(full, name))
    one = pole(fourbar_motion(*CRANK_ROCKER, 0.7))
    assert one.shape == ()
    single = line_scan(one, 0.4)
    assert single.circle_point.shape == ()
    assert line_scan(one, [0.4]).circle_point[0] == single.circle_point


def test_no_nan_or_inf_anywhere_even_where_flagged():
    # a triple-rocker: most crank angles cannot assemble, two are toggles
    motion = fourbar_motion(np.array([[1.0], [2.0]]), 1.2, 1.5, 2.5, np.linspace(-np.pi, np.pi, 721), 1)
    pl = pole(motion)
    results = [pl, inflection_circle(pl), ball_point(pl), euler_savary(pl, pl.point + 1.0)]
    pl3 = pole(
        fourbar_motion(np.array([1.0, 2.0])[:, None, None], 1.2, 1.5, 2.5, np.linspace(-np.pi, np.pi, 721)[:, None], 1)
    )
    results.append(line_scan(pl3, np.linspace(0, np.pi, 9)))
    assert np.any(pl.status & Status.NOT_ASSEMBLABLE)
    for res in results:
        for arr in _all_arrays(res):
            arr = np.asarray(arr)
            if arr.dtype.kind in "fc":
                assert np.all(np.isfinite(arr)), type(res).__name__


def test_flagged_instants_carry_zero_placeholders():
    motion = fourbar_motion(1.0, 1.2, 1.5, 2.5, np.array([0.0, np.pi]), 1)  # φ = π cannot assemble
    pl = pole(motion)
    assert pl.status[1] & Status.NOT_ASSEMBLABLE
    circle, ball, scan = inflection_circle(pl), ball_point(pl), line_scan(pl, 0.3)
    assert pl.point[1] == 0 and circle.diameter[1] == 0 and ball.uv[1] == 0 and scan.circle_point[1] == 0
    assert scan.status[1] & Status.NOT_ASSEMBLABLE
    assert all(e[1] == 0 and e[0] > 0 for e in pl.dtheta_error)


def test_results_are_frozen_and_slotted():
    pl = pole(fourbar_motion(*CRANK_ROCKER, 0.7))
    for res in (pl, inflection_circle(pl), ball_point(pl), line_scan(pl, 0.2), euler_savary(pl, 1j)):
        with pytest.raises(dataclasses.FrozenInstanceError):
            res.status = None
        assert not hasattr(res, "__dict__")


def test_on_degenerate_is_validated_and_raise_mode_raises_assembly_error():
    motion = fourbar_motion(1.0, 1.2, 1.5, 2.5, np.array([0.0, np.pi]), 1)
    with pytest.raises(ValueError, match="'flag', 'raise'"):
        pole(motion, on_degenerate="ignore")
    with pytest.raises(AssemblyError, match="not assemblable"):
        pole(motion, on_degenerate="raise")
    pl = pole(motion)  # flag mode never raises
    for fn in (inflection_circle, ball_point):
        with pytest.raises(AssemblyError):
            fn(pl, on_degenerate="raise")
    with pytest.raises(AssemblyError):
        line_scan(pl, 0.1, on_degenerate="raise")
    with pytest.raises(ValueError, match="finite"):
        line_scan(pl, np.nan)


def _pole_at(phi):
    return pole(fourbar_motion(*CRANK_ROCKER, phi))


def test_rays_through_a_and_b_give_their_circles():
    """Closed form: A moves on a circle of radius a about A0, B on one of radius c about B0."""
    a, b, c, d = CRANK_ROCKER
    checked = 0
    for phi in np.linspace(0.1, 6.0, 9):
        motion = fourbar_motion(a, b, c, d, phi)
        pl = pole(motion)
        if pl.status:
            continue
        checked += 1
        for joint, pivot, radius, uv in ((motion.A, 0j, a, 0j), (motion.B, complex(d), c, complex(b))):
            alpha = np.angle(joint - pl.point)
            pair = line_scan(pl, alpha)
            assert pair.status == 0
            assert abs(pair.circle_point - joint) < 1e-12 * (1 + abs(joint - pl.point))
            assert abs(pair.center_point - pivot) < 1e-11 * (1 + abs(joint - pl.point))
            assert pair.radius == pytest.approx(radius, rel=1e-11)
            assert abs(pair.circle_point_uv - uv) < 1e-11
    assert checked == 9  # a crank-rocker has a finite pole at every crank angle


def test_euler_savary_agrees_with_line_scanning_and_with_the_joints():
    pl = _pole_at(1.1)
    alpha = np.linspace(0.05, 3.0, 11)
    scan = line_scan(pl, alpha)
    ok = scan.status == 0
    centres = euler_savary(pl, scan.circle_point)
    assert np.all(centres.status[ok] == 0)
    np.testing.assert_allclose(centres.center[ok], scan.center_point[ok], rtol=0, atol=1e-10)
    motion = fourbar_motion(*CRANK_ROCKER, 1.1)
    at_b = euler_savary(pl, motion.B)
    assert abs(at_b.center - CRANK_ROCKER[3]) < 1e-12 and at_b.radius == pytest.approx(CRANK_ROCKER[2], rel=1e-12)


def test_pole_tangent_is_the_direction_the_pole_moves():
    """I′ = i·Z2/θ′: compare the tangent with a central difference of the pole at a safe step."""
    phi, h = 0.9, 1e-5
    pl = _pole_at(phi)
    step = _pole_at(phi + h).point - _pole_at(phi - h).point
    assert abs(np.angle(step / pl.tangent)) < 1e-6
    assert abs(abs(step) / (2 * h) - abs(pl.z2) / abs(pl.dtheta[0])) < 1e-6 * abs(step) / h
    assert abs(pl.tangent - 1j * np.sign(pl.dtheta[0]) * pl.normal) < 1e-15


def test_inflection_circle_geometry():
    pl = _pole_at(2.0)
    circle = inflection_circle(pl)
    t1 = pl.dtheta[0]
    assert circle.diameter == pytest.approx(abs(pl.z2) / t1**2, rel=1e-14)
    assert abs(circle.center - pl.point - 0.5 * (circle.inflection_pole - pl.point)) < 1e-12
    assert abs(abs(pl.point - circle.center) - circle.diameter / 2) < 1e-12 * circle.diameter
    assert abs(np.angle((circle.inflection_pole - pl.point) / pl.normal)) < 1e-12


def test_rays_along_the_pole_tangent_and_normal_are_flagged():
    pl = _pole_at(0.4)
    tangent, normal = np.angle(pl.tangent), np.angle(pl.normal)
    scan = line_scan(pl, np.array([tangent + 1e-12, normal - 1e-12, tangent + np.pi, tangent + 0.3]))
    assert scan.status[0] & Status.RAY_ALONG_POLE_TANGENT
    assert scan.status[1] & Status.AT_POLE
    assert scan.status[2] & Status.RAY_ALONG_POLE_TANGENT
    assert scan.status[3] == 0
    assert np.all(scan.radius[:3] == 0) and np.all(scan.circle_point[:3] == pl.point)


def test_rays_along_the_asymptotes_are_skips_in_every_layout():
    """A ray with Re(ūV) = 0 meets the cubic at infinity and one with Re(ūW) = 0 has its centre
    point there: each is flagged, keeps the other point of its pair, radius 0, and one instant
    gives what a batch gives (the accuracy flags are decided after the scan, on candidates)."""
    pl = _pole_at(1.3)
    t1, t2 = pl.dtheta[0], pl.dtheta[1]
    w = t1 * pl.z3 - 3 * t2 * pl.z2
    v = w - 3j * t1**2 * pl.z2
    alpha = np.array([np.angle(v) + np.pi / 2, np.angle(w) + np.pi / 2, 0.7])
    batch = line_scan(pl, alpha)
    assert batch.status[0] == Status.CIRCLE_POINT_AT_INFINITY
    assert batch.circle_point[0] == pl.point and batch.center_point[0] != pl.point
    assert batch.status[1] == Status.CENTER_POINT_AT_INFINITY
    assert batch.center_point[1] == pl.point and batch.circle_point[1] != pl.point
    assert np.all(batch.radius[:2] == 0) and batch.status[2] == 0 and batch.radius[2] > 0
    for k, angle in enumerate(alpha):
        one = line_scan(pl, angle)
        for name in ("status", "circle_point", "circle_point_uv", "center_point", "radius"):
            assert getattr(one, name) == getattr(batch, name)[k], name


def test_pole_at_infinity_is_flagged_near_a_zero_of_theta_prime():
    t = lambda phi: fourbar_motion(*CRANK_ROCKER, phi, order=1).dtheta[0]  # noqa: E731
    grid = np.linspace(0, 2 * np.pi, 721)
    k = int(np.flatnonzero(np.sign(t(grid[:-1])) != np.sign(t(grid[1:])))[0])
    lo, hi = grid[k], grid[k + 1]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if np.sign(t(mid)) == np.sign(t(lo)) else (lo, mid)
    pl = _pole_at(0.5 * (lo + hi) + 1e-12)
    assert pl.status & Status.POLE_AT_INFINITY and pl.point == 0
    assert ball_point(pl).status & Status.POLE_AT_INFINITY


def test_ball_point_closed_form_equals_the_pole_formula():
    """docs/curvature.md §2: α_B = arg(θ′Z3 − 3θ″Z2) + π/2, r_B = R2(α_B)/θ′²."""
    checked = 0
    for phi in np.linspace(0.2, 6.2, 13):
        pl = _pole_at(phi)
        if pl.status:
            continue
        checked += 1
        t1, t2 = pl.dtheta[0], pl.dtheta[1]
        u = np.exp(1j * (np.angle(t1 * pl.z3 - 3 * t2 * pl.z2) + np.pi / 2))
        z = pl.point + (np.conj(u) * pl.z2).real / t1**2 * u
        ball = ball_point(pl)
        assert abs(ball.point - z) < 1e-12 * (1 + abs(z))
        z_dot = fourbar_motion(*CRANK_ROCKER, phi).coupler_point(ball.uv.real, ball.uv.imag, order=1)[1]
        assert abs(ball.tangent - z_dot / abs(z_dot)) < 1e-12
    assert checked == 13  # a crank-rocker has a finite pole at every crank angle
