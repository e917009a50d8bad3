"""Output-dyad fitting: RPR slot pivots on Ball-point lines, double Ball point pivots, RRR
dyads on circle points — each checked by the exact simulation of the resulting six-bar
(swing to 0.01°, dwell, transmission), plus batches, refusals and no NaN/inf."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kinematics.fourbar import fourbar_motion
from kinematics.status import Status
from synth import ball_point, double_ball_points, line_scan, pole
from synth.mechanism.dyad import SWING_TOL, fit_rpr, fit_rrr, rpr_double
from synth.mechanism.figures import sixbar_figures
from synth.mechanism.sixbar import SixBar, crank_grid, simulate

DEG = math.pi / 180
PHI = crank_grid(720)
#: (a, b, c, d, branch, generating crank angle) of Grashof crank-rockers.
FOURBARS = [(1.0, 3.0, 3.0, 3.5, 1, 1.2), (1.0, 2.5, 3.0, 3.0, -1, 4.0), (1.0, 4.0, 2.5, 3.5, 1, 2.5)]


def _path(a, b, c, d, br, uv):
    return fourbar_motion(a, b, c, d, PHI, br, order=0).coupler_point(uv.real, uv.imag)[0]


def _ball_segment(a, b, c, d, br, phi0):
    """Ball's point at φ₀: its tangent line and path (a nearly straight stretch around φ₀)."""
    bp = ball_point(pole(fourbar_motion(a, b, c, d, phi0, br)))
    assert bp.status == 0
    uv = complex(bp.uv)
    return complex(bp.point), float(np.angle(bp.tangent)), uv, _path(a, b, c, d, br, uv)


# ---------------------------------------------------------------------------------------------
# RPR
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("fb", FOURBARS)
def test_rpr_on_a_ball_point_line_gives_the_swing_and_a_dwell(fb):
    a, b, c, d, br, phi0 = fb
    P0, delta, uv, path = _ball_segment(*fb)
    interval = (phi0 - 0.25, phi0 + 0.25)
    fit = fit_rpr(P0, delta, PHI, path, interval, 30 * DEG)
    assert fit.pivot.shape == (2,)
    dyads = fit.dyads()
    assert dyads
    e = np.exp(1j * delta)
    t_dwell = ((path - P0) * np.conj(e)).real[np.abs(np.angle(np.exp(1j * (PHI - phi0)))) <= 0.25]
    for k, dyad in zip(np.flatnonzero(fit.found), dyads):
        D = fit.pivot[k]
        assert dyad.pivot == D
        assert abs(((D - P0) * np.conj(e)).imag) < 1e-12  # on the line
        t = fit.position[k]
        assert t > t_dwell.max() or t < t_dwell.min()  # outside the stretch
        assert abs(fit.swing[k] - 30 * DEG) <= SWING_TOL
        sb = SixBar(a, b, c, d, br, uv.real, uv.imag, dyad)
        f = sixbar_figures(sb, band=0.1 * DEG, dwell_length=20 * DEG)
        assert abs(f.swing - 30 * DEG) <= 0.01 * DEG
        assert f.acceptable
        (dwell,) = f.dwells
        # the straight stretch around φ₀ is a dwell of the output
        assert dwell.start < phi0 < dwell.end or dwell.start < phi0 + 2 * np.pi < dwell.end
        assert dwell.angle > 30 * DEG
        band = simulate(sb, np.linspace(phi0 - 0.1, phi0 + 0.1, 201), order=0).psi
        assert band.max() - band.min() < 0.05 * DEG


def test_rpr_sides_are_ordered_and_unreachable_swings_are_not_found():
    P0, delta, _, path = _ball_segment(*FOURBARS[0])
    fit = fit_rpr(P0, delta, PHI, path, (1.0, 1.4), np.array([5 * DEG, 170 * DEG])[:, None] * np.ones(2))
    assert fit.pivot.shape == (2, 2, 2)
    assert np.all(fit.position[..., 0] < fit.position[..., 1])
    assert fit.found[0, 0].any()
    assert not fit.found[1].any()  # 170° needs the pivot inside the stretch
    for arr in (fit.pivot, fit.position, fit.swing, fit.clearance):
        assert np.all(np.isfinite(arr))


def test_rpr_batch_equals_single_fits():
    segments = [_ball_segment(*fb) for fb in FOURBARS]
    swings = np.array([20.0, 30.0, 45.0]) * DEG
    intervals = np.array([fb[-1] for fb in FOURBARS])
    batch = fit_rpr(
        np.array([s[0] for s in segments]),
        np.array([s[1] for s in segments]),
        PHI,
        np.array([s[3] for s in segments]),
        (intervals - 0.2, intervals + 0.2),
        swings,
    )
    for k, (P0, delta, _, path) in enumerate(segments):
        one = fit_rpr(P0, delta, PHI, path, (intervals[k] - 0.2, intervals[k] + 0.2), swings[k])
        np.testing.assert_array_equal(one.found, batch.found[k])
        np.testing.assert_allclose(one.pivot, batch.pivot[k], rtol=0, atol=1e-12)


def test_rpr_refuses_bad_input():
    P0, delta, _, path = _ball_segment(*FOURBARS[0])
    with pytest.raises(ValueError, match="swing"):
        fit_rpr(P0, delta, PHI, path, (1.0, 1.4), 0.0)
    with pytest.raises(ValueError, match="samples"):
        fit_rpr(P0, delta, PHI, path[:100], (1.0, 1.4), 0.3)
    with pytest.raises(ValueError, match="finite"):
        fit_rpr(np.nan, delta, PHI, path, (1.0, 1.4), 0.3)
    with pytest.raises(ValueError, match="end >= start"):
        fit_rpr(P0, delta, PHI, path, (1.4, 1.0), 0.3)


# ---------------------------------------------------------------------------------------------
# Double Ball point
# ---------------------------------------------------------------------------------------------


def test_rpr_double_intersects_lines_and_flags_parallel_ones():
    piv = rpr_double(
        (np.array([0j, 1 + 0j, 0j]), np.array([0.0, 0.0, 0.0])),
        (np.array([2 + 1j, 2 + 1j, 5j]), np.array([np.pi / 2, np.pi / 4, 1e-12])),
    )
    assert piv.pivot[0] == pytest.approx(2 + 0j, abs=1e-15)
    assert piv.pivot[1] == pytest.approx(1 + 0j, abs=1e-15)
    assert piv.status.tolist() == [0, 0, Status.AT_INFINITY]
    assert piv.found.tolist() == [True, True, False]
    assert np.all(np.isfinite(piv.pivot))
    assert piv.dyad((2,)) is None and piv.dyad((0,)).kind == "RPR"
    far = rpr_double((0j, 0.0), (1j, 1e-5))  # meets 1e5 away
    assert not far.found


def test_double_ball_point_rpr_dwells_twice_per_turn():
    a, b, c, d, br = 1.0, 3.0, 3.0, 3.5, 1
    found = double_ball_points(a, b, c, d, br)
    k = 0
    piv = rpr_double((found.point1[k], np.angle(found.tangent1[k])), (found.point2[k], np.angle(found.tangent2[k])))
    dyad = piv.dyad()
    assert dyad is not None
    sb = SixBar(a, b, c, d, br, found.uv[k].real, found.uv[k].imag, dyad)
    f = sixbar_figures(sb, band=0.2 * DEG, dwells=2, dwell_length=20 * DEG)
    assert f.acceptable and len(f.dwells) == 2
    for phi_k in (found.phi1[k], found.phi2[k]):
        assert any(dw.start < phi_k < dw.end or dw.start < phi_k + 2 * np.pi < dw.end for dw in f.dwells)
    assert all(dw.angle > 25 * DEG for dw in f.dwells)
    assert all(dev < 0.2 * DEG for dev in f.deviations)


# ---------------------------------------------------------------------------------------------
# RRR
# ---------------------------------------------------------------------------------------------


def _circle_segment(a, b, c, d, br, phi0, alpha):
    scan = line_scan(pole(fourbar_motion(a, b, c, d, phi0, br)), alpha)
    assert scan.status == 0
    uv = complex(scan.circle_point_uv)
    return complex(scan.center_point), float(scan.radius), uv, _path(a, b, c, d, br, uv)


RRR_CASES = [(FOURBARS[0], 90 * DEG), (FOURBARS[0], 140 * DEG), (FOURBARS[1], 50 * DEG), (FOURBARS[2], 120 * DEG)]


@pytest.mark.parametrize("fb,alpha", RRR_CASES)
def test_rrr_on_a_circle_point_gives_the_swing_with_the_transmission_asked(fb, alpha):
    a, b, c, d, br, phi0 = fb
    C0, rho, uv, path = _circle_segment(*fb, alpha)
    fit = fit_rrr(C0, rho, PHI, path, (phi0 - 0.2, phi0 + 0.2), 40 * DEG, 20 * DEG)
    assert fit.pivot.shape == (3,)
    dyads = fit.dyads()
    assert dyads
    mu = fit.transmission[fit.found]
    assert np.all(np.diff(mu) <= 0)  # best first
    for k, dyad in enumerate(dyads):
        assert dyad.rod == rho and dyad.rocker == pytest.approx(abs(dyad.pivot - C0), rel=1e-12)
        sb = SixBar(a, b, c, d, br, uv.real, uv.imag, dyad)
        f = sixbar_figures(sb, band=0.2 * DEG, dwell_length=20 * DEG)
        assert f.acceptable, f.status
        assert abs(f.swing - 40 * DEG) <= 0.01 * DEG
        assert f.transmission_output >= 20 * DEG - 0.01 * DEG
        assert f.transmission_output == pytest.approx(mu[k], abs=0.01 * DEG)
        # Q rests at C₀ at the generating instant, on the branch chosen
        m = simulate(sb, np.array([phi0]))
        assert abs(m.moving_pivot[0] - C0) < 1e-9
        (dwell,) = f.dwells
        assert dwell.start < phi0 < dwell.end or dwell.start < phi0 + 2 * np.pi < dwell.end


def test_rrr_transmission_is_the_best_over_rocker_directions():
    """No rocker direction on a fine scan beats the fitted one by more than the fine step allows."""
    fb, alpha = RRR_CASES[0]
    phi0 = fb[-1]
    C0, rho, _, path = _circle_segment(*fb, alpha)
    best = fit_rrr(C0, rho, PHI, path, (phi0 - 0.2, phi0 + 0.2), 40 * DEG, 20 * DEG, keep=1)
    assert best.found[0]
    dense = fit_rrr(C0, rho, PHI, path, (phi0 - 0.2, phi0 + 0.2), 40 * DEG, 20 * DEG, directions=360, keep=1)
    assert best.transmission[0] >= dense.transmission[0] - 1.0 * DEG


def test_rrr_impossible_requests_find_nothing_and_stay_finite():
    fb, alpha = RRR_CASES[0]
    C0, rho, _, path = _circle_segment(*fb, alpha)
    fit = fit_rrr(C0, rho, PHI, path, (1.0, 1.4), 40 * DEG, 89 * DEG)
    assert not fit.found.any() and fit.dyads() == []
    tiny = fit_rrr(C0, 1e-3, PHI, path, (1.0, 1.4), 40 * DEG, 20 * DEG)  # rod cannot reach the curve
    assert not tiny.found.any()
    for res in (fit, tiny):
        for arr in (res.pivot, res.rocker, res.swing, res.transmission, res.direction):
            assert np.all(np.isfinite(arr))


def test_rrr_batch_equals_single_fits():
    """A batch gives every row what it gets alone, bit for bit — also with rows between them
    that find nothing (a rod too short to reach the curve: no feasible direction in the coarse
    scan, so fit_rrr leaves them out of the fine scans and solves)."""
    segs = [(_circle_segment(*fb, alpha), fb[-1]) for fb, alpha in RRR_CASES]
    C0 = np.array([s[0][0] for s in segs])
    rho = np.array([s[0][1] for s in segs])
    paths = np.array([s[0][3] for s in segs])
    phi0 = np.array([s[1] for s in segs])
    batch = fit_rrr(C0, rho, PHI, paths, (phi0 - 0.2, phi0 + 0.2), 40 * DEG, 20 * DEG)
    assert batch.pivot.shape == (4, 3)
    for k in range(4):
        one = fit_rrr(C0[k], rho[k], PHI, paths[k], (phi0[k] - 0.2, phi0[k] + 0.2), 40 * DEG, 20 * DEG)
        np.testing.assert_array_equal(one.found, batch.found[k])
        np.testing.assert_allclose(one.pivot, batch.pivot[k], rtol=0, atol=1e-9)
    dead = np.arange(8) % 2 == 1  # every other row: the same segment with a 1e-3 rod
    mixed = fit_rrr(
        np.repeat(C0, 2),
        np.where(dead, 1e-3, np.repeat(rho, 2)),
        PHI,
        np.repeat(paths, 2, axis=0),
        (np.repeat(phi0, 2) - 0.2, np.repeat(phi0, 2) + 0.2),
        40 * DEG,
        20 * DEG,
    )
    assert not mixed.found[dead].any() and mixed.found[~dead].any()
    np.testing.assert_array_equal(mixed.pivot[dead], np.repeat(np.repeat(C0, 2)[dead, None], 3, axis=1))
    for f in dataclasses.fields(batch):
        np.testing.assert_array_equal(getattr(mixed, f.name)[~dead], getattr(batch, f.name), err_msg=f.name)


def test_rrr_fitted_in_blocks_is_bit_for_bit_the_whole_batch(monkeypatch):
    """fit_rrr works through large batches in blocks of rows (cache blocking): the same
    numbers, in the same (2-D) shape, as in one block."""
    import synth.mechanism.dyad as dyad

    segs = [(_circle_segment(*fb, alpha), fb[-1]) for fb, alpha in RRR_CASES]
    C0 = np.array([s[0][0] for s in segs] * 2).reshape(2, 4)
    rho = np.array([s[0][1] for s in segs] * 2).reshape(2, 4)
    paths = np.array([s[0][3] for s in segs] * 2).reshape(2, 4, -1)
    phi0 = np.array([s[1] for s in segs] * 2).reshape(2, 4)
    args = (C0, rho, PHI, paths, (phi0 - 0.2, phi0 + 0.2), 40 * DEG, 20 * DEG)
    whole = fit_rrr(*args)
    monkeypatch.setattr(dyad, "_CHUNK_ROWS", 3)
    blocks = fit_rrr(*args)
    assert whole.found.shape == (2, 4, 3) and whole.found.any()
    for f in dataclasses.fields(whole):
        a, b = getattr(whole, f.name), getattr(blocks, f.name)
        assert a.dtype == b.dtype and a.shape == b.shape, f.name
        np.testing.assert_array_equal(a, b, err_msg=f.name)


def test_rrr_refuses_bad_input():
    fb, alpha = RRR_CASES[0]
    C0, rho, _, path = _circle_segment(*fb, alpha)
    with pytest.raises(ValueError, match="min_transmission"):
        fit_rrr(C0, rho, PHI, path, (1.0, 1.4), 0.5, 0.0)
    with pytest.raises(ValueError, match="radius"):
        fit_rrr(C0, -1.0, PHI, path, (1.0, 1.4), 0.5, 0.3)
    with pytest.raises(ValueError, match="swing"):
        fit_rrr(C0, rho, PHI, path, (1.0, 1.4), 4.0, 0.3)


# ---------------------------------------------------------------------------------------------
# Properties: random segments give finite results, and what is found is what was asked
# ---------------------------------------------------------------------------------------------

coord = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    coord,
    coord,
    st.floats(0.0, 2 * np.pi),
    st.floats(0.01, 20.0),
    st.floats(0.0, 2 * np.pi),
    st.floats(0.01, 3.0),
    st.floats(1 * DEG, 170 * DEG),
    st.sampled_from(range(3)),
)
def test_random_segments_give_finite_fits(x, y, delta, radius, start, span, swing, which):
    a, b, c, d, br, _ = FOURBARS[which]
    path = _path(a, b, c, d, br, complex(x, y) / 3)
    rpr = fit_rpr(complex(x, y), delta, PHI, path, (start, start + span), swing)
    rrr = fit_rrr(complex(x, y), radius, PHI, path, (start, start + span), swing, 15 * DEG)
    for res in (rpr, rrr):
        for name in res.__slots__:
            arr = np.asarray(getattr(res, name))
            if arr.dtype.kind in "fc":
                assert np.all(np.isfinite(arr)), name
    assert np.all(np.abs(rpr.swing[rpr.found] - swing) <= SWING_TOL)
    assert np.all(np.abs(rrr.swing[rrr.found] - swing) <= SWING_TOL)
    assert np.all(rrr.transmission[rrr.found] >= 15 * DEG - 1e-12)


def _numpy_estimate(terms, alpha, target, ratio):
    """The RRR direction ranking written as numpy expressions over (rows, directions,
    samples): the reference the compiled ranking must match bit for bit."""
    c, s = np.cos(alpha)[..., None], np.sin(alpha)[..., None]
    p, q = terms.wx * c + terms.wy * s, terms.wy * c - terms.wx * s
    centre = -p * terms.inv_a_rho
    u_hi = (centre + terms.half).min(axis=-1)
    u_lo = np.maximum((centre - terms.half).max(axis=-1), 0.0)
    q_mid = (terms.w_mid[:, None] * np.exp(-1j * alpha)).imag
    branch = np.where(q_mid > 0, -1, 1)
    s_ = q + branch[..., None] * np.sqrt(np.maximum(terms.rho**2 - p * p, 0.0))
    u_est = target[:, None] / np.maximum(s_.max(axis=-1) - s_.min(axis=-1), 1e-12)
    u_try = ratio * u_est
    feasible = (u_lo <= u_hi) & (u_try <= u_hi)
    u_use = np.clip(u_try, u_lo, np.maximum(u_hi, u_lo))
    cos_max = np.abs(terms.A * u_use[..., None] + p / terms.rho).max(axis=-1)
    return branch, u_lo, u_hi, u_est, np.where(feasible, np.arccos(np.minimum(cos_max, 1.0)), -1.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compiled_rrr_ranking_is_the_numpy_expressions_bit_for_bit(seed):
    from synth.mechanism.dyad import RrrTerms

    rng = np.random.default_rng(seed)
    R, S, J = 40, 120, 24
    t = np.linspace(0, 2 * np.pi, S, endpoint=False)
    # near-circular paths about C₀ (as on an arc segment), some crossing their circle exactly
    rho = rng.uniform(0.3, 4.0, R)
    w = (
        rho[:, None]
        * (1 + rng.uniform(0, 0.3, (R, 1)) * np.sin(t * rng.integers(1, 4, (R, 1))))
        * np.exp(1j * (t + rng.uniform(0, 6, (R, 1))))
    )
    w[::7, 3] = rho[::7] + 0j
    terms = RrrTerms(w, rho, math.cos(math.radians(rng.uniform(20, 50))), w[:, 5])
    alpha = rng.uniform(0, 2 * np.pi, (R, J))
    target = rng.uniform(0.1, 1.5, R)
    for ratio in (1.0, rng.uniform(0.5, 2.0, (R, J))):
        got, want = terms.estimate(alpha, target, ratio), _numpy_estimate(terms, alpha, target, ratio)
        for g, x in zip(got, want):
            np.testing.assert_array_equal(g, x)
        assert np.count_nonzero(want[-1] > 0) > 10 and np.count_nonzero(want[-1] < 0) > 10


def _check_swing(swing, reference, u):
    """A compiled swing ``swing(u) -> (S, dS/du, invalid)`` against its numpy ``reference`` at
    ``u``: the same invalid dyads (some of each kind), S and dS/du to rounding (numpy's
    ``arctan2`` and complex products may run on other instructions), and dS/du against central
    differences of S at a safe step — ∂ψ/∂u at the extremes (the envelope theorem), taken at
    the extreme samples, not at the refined vertices: agreement to the sampling's order (0.25°
    here; a Newton step needs no more), closer for most dyads."""
    S, dS, invalid = swing(u)
    S_ref, dS_ref, invalid_ref = reference
    np.testing.assert_array_equal(invalid, invalid_ref)
    ok = ~invalid
    assert 10 < np.count_nonzero(ok) < ok.size  # both kinds are exercised
    np.testing.assert_allclose(S[ok], S_ref[ok], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(dS[ok], dS_ref[ok], rtol=1e-9, atol=1e-12)
    h = 1e-6 * u
    up, down = swing(u + h), swing(u - h)
    fd = (up[0] - down[0]) / (2 * h)
    smooth = ok & ~up[2] & ~down[2]
    error = np.abs(dS[smooth] / fd[smooth] - 1)
    assert np.max(error) < 0.03 and np.median(error) < 1e-3
    assert np.max(error) > 1e-9  # not the same formula twice


def _numpy_swing(w, e, rho, branch, u):
    """The RRR swing S(u) and ∂S/∂u as numpy expressions over (dyads, samples) — the loop by
    :func:`circle_intersection`, the extremes by :func:`sampled_extreme`: the reference of the
    compiled :func:`synth.mechanism.dyad_kernel.rrr_swing`."""
    from kinematics.loop import circle_intersection, sampled_extreme

    L = 1.0 / u[:, None]
    e = e[:, None]
    loop = circle_intersection(L * e - w, rho[:, None], L, branch[:, None])
    eta = np.angle(loop.e2 * -np.conj(e))
    hi, khi = sampled_extreme(eta, +1)
    lo, klo = sampled_extreme(eta, -1)
    singular = loop.status != 0

    def g(k):
        at = lambda x: np.take_along_axis(x, k[:, None], -1)[:, 0]  # noqa: E731
        inv_s = 1.0 / np.where(at(singular), np.inf, -at(loop.height) / L[:, 0])
        return ((e[:, 0] + at(loop.e2)) * np.conj(at(loop.cos1) + 1j * at(loop.sin1))).real * inv_s / (L[:, 0] * u**2)

    jumps = np.any(np.abs(np.diff(eta, axis=-1, append=eta[:, :1])) > math.pi, axis=-1)
    return hi - lo, g(khi) - g(klo), np.any(singular, axis=-1) | jumps


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compiled_rrr_swing_is_the_numpy_loop_and_its_derivative(seed):
    """The compiled swing equals the numpy evaluation (to rounding: numpy's arctan2 and complex
    products may use other instructions) and its derivative a central difference; dyads
    whose loop cannot close at some sample, or whose rocker revolves, are invalid in both."""
    from synth.mechanism.dyad_kernel import rrr_swing

    rng = np.random.default_rng(seed)
    N, M = 60, 1440
    t = np.linspace(0, 2 * np.pi, M, endpoint=False)
    rho = rng.uniform(0.5, 4.0, N)
    # paths about C₀ near the rod's circle (an arc segment), rockers from short to long
    w = (
        rho[:, None]
        * (1 + rng.uniform(0, 0.4, (N, 1)) * np.sin(t * rng.integers(1, 4, (N, 1))))
        * np.exp(1j * (0.3 * np.sin(t + rng.uniform(0, 6, (N, 1)))))
    )
    e = np.exp(1j * rng.uniform(0, 2 * np.pi, N))
    branch = rng.choice([-1.0, 1.0], N)
    u = 1.0 / rng.uniform(0.5, 20.0, N)
    wx, wy = np.ascontiguousarray(w.real), np.ascontiguousarray(w.imag)
    _check_swing(
        lambda uu: rrr_swing(wx, wy, np.arange(N), e.real.copy(), e.imag.copy(), branch, rho, uu),
        _numpy_swing(w, e, rho, branch, u),
        u,
    )


def _numpy_rpr_swing(t_s, n_s, side, t_end, u):
    """The RPR swing S(u) and ∂S/∂u as numpy expressions over (dyads, samples): the slot's
    angle by ``arctan2``, its extremes by :func:`sampled_extreme` — the reference of the
    compiled :func:`synth.mechanism.dyad_kernel.rpr_swing`."""
    from kinematics.loop import sampled_extreme

    sg = side[:, None]
    tD = t_end + side / u
    dt, nn = t_s - tD[:, None], n_s
    psi = np.arctan2(-sg * nn, -sg * dt)
    hi, khi = sampled_extreme(psi, +1)
    lo, klo = sampled_extreme(psi, -1)

    def g(k):
        a, b = (np.take_along_axis(x, k[:, None], -1)[:, 0] for x in (dt, nn))
        return b / (a * a + b * b)

    jumps = np.any(np.abs(np.diff(psi, axis=-1, append=psi[:, :1])) > math.pi, axis=-1)
    return hi - lo, (g(khi) - g(klo)) * (-side / (u * u)), jumps


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compiled_rpr_swing_is_the_numpy_angle_and_its_derivative(seed):
    """As for the RRR: the compiled RPR swing equals the numpy evaluation to rounding, slots
    whose path crosses the angle's cut beyond D are invalid in both, and ∂S/∂u matches
    central differences."""
    from synth.mechanism.dyad_kernel import rpr_swing

    rng = np.random.default_rng(seed)
    N, M = 80, 1440
    t = np.linspace(0, 2 * np.pi, M, endpoint=False)
    # closed paths in a line's frame: a stretch along the axis, excursions across it
    centre = rng.uniform(-1, 1, N)[:, None]
    t_s = np.ascontiguousarray(centre + rng.uniform(0.5, 2, (N, 1)) * np.cos(t + rng.uniform(0, 6, (N, 1))))
    n_s = np.ascontiguousarray(
        rng.uniform(0.05, 1.5, (N, 1))
        * (1 - np.cos(t + rng.uniform(0, 6, (N, 1)))) ** 2
        * rng.choice([-1.0, 1.0], (N, 1))
        + rng.uniform(-0.3, 0.3, (N, 1))
    )
    side = rng.choice([-1.0, 1.0], N)
    t_end = np.where(side > 0, t_s.max(axis=1), t_s.min(axis=1)) + side * 0.1
    inside = rng.random(N) < 0.25  # pivots within the path's extent: the cut beyond D may cross it
    t_end = np.where(inside, t_s.mean(axis=1), t_end)
    u = rng.uniform(0.05, 4.0, N) * np.where(inside, 30.0, 1.0)
    _check_swing(
        lambda uu: rpr_swing(t_s, n_s, np.arange(N), side, t_end, uu), _numpy_rpr_swing(t_s, n_s, side, t_end, u), u
    )


def _numpy_rtsafe(F, lo, hi, u0, target, active, check_far):
    """The safeguarded Newton (Numerical Recipes' ``rtsafe``) vectorised over dyads with numpy,
    ``F(rows, u) -> (S, dS/du, invalid)`` evaluating only the dyads still iterating: the
    reference of the compiled :func:`synth.mechanism.dyad_kernel.solve_rrr` and ``solve_rpr`` (the form
    the fits used before, kept here)."""
    from synth.mechanism.dyad import SWING_MAX_ITER

    lo, hi, target = lo.astype(float).copy(), hi.astype(float).copy(), target.astype(float)
    active = active.copy()
    u = np.clip(u0.astype(float), lo, hi)
    if check_far:
        sel = np.flatnonzero(active)
        S_hi, _, inv_hi = F(sel, hi[sel])
        active[sel] = inv_hi | (S_hi >= target[sel] - SWING_TOL)
    S, converged = np.zeros_like(u), np.zeros(u.shape, bool)
    todo = np.flatnonzero(active)
    for _ in range(SWING_MAX_ITER):
        if todo.size == 0:
            break
        ut, lt, ht = u[todo], lo[todo], hi[todo]
        St, dS, invalid = F(todo, ut)
        f = St - target[todo]
        conv = ~invalid & (np.abs(f) <= SWING_TOL)
        S[todo], converged[todo] = St, conv
        big = invalid | (f > 0)
        ht, lt = np.where(big, ut, ht), np.where(big, lt, ut)
        ok_d = ~invalid & (dS > 0)
        newton = ut - np.where(ok_d, f / np.where(ok_d, dS, 1.0), 0.0)
        step = np.where(ok_d & (newton > lt) & (newton < ht), newton, 0.5 * (lt + ht))
        lo[todo], hi[todo] = lt, ht
        go_on = ~conv & ((ht - lt) > 1e-15 * ht)
        u[todo[go_on]] = step[go_on]
        todo = todo[go_on]
    return u, np.where(converged, S, 0.0), converged


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("kind", ["rrr", "rpr"])
def test_compiled_newton_is_the_numpy_rtsafe_bit_for_bit(seed, kind):
    """The compiled swing solves (one dyad at a time, split over threads) give the numpy
    iteration's u, S and convergence flags bit for bit, for targets both reachable and not,
    some dyads inactive, with and without the far-end check; and a root found has S(u) within
    SWING_TOL of the target."""
    from synth import parallel_rows
    from synth.mechanism.dyad import SWING_MAX_ITER
    from synth.mechanism.dyad_kernel import rpr_swing, rrr_swing, solve_rpr, solve_rrr

    rng = np.random.default_rng(seed)
    N, M = 90, 360
    t = np.linspace(0, 2 * np.pi, M, endpoint=False)
    if kind == "rrr":
        rho = rng.uniform(0.5, 4.0, N)
        w = (
            rho[:, None]
            * (1 + rng.uniform(0, 0.4, (N, 1)) * np.sin(t * rng.integers(1, 4, (N, 1))))
            * np.exp(1j * (0.3 * np.sin(t + rng.uniform(0, 6, (N, 1)))))
        )
        wx, wy = np.ascontiguousarray(w.real), np.ascontiguousarray(w.imag)
        e = np.exp(1j * rng.uniform(0, 2 * np.pi, N))
        ex, ey, branch, rows = e.real.copy(), e.imag.copy(), rng.choice([-1.0, 1.0], N), np.arange(N)
        F = lambda sel, u: rrr_swing(wx, wy, rows[sel], ex[sel], ey[sel], branch[sel], rho[sel], u)  # noqa: E731
        solve = lambda *a: solve_rrr(wx, wy, rows, ex, ey, branch, rho, *a, SWING_TOL, SWING_MAX_ITER)  # noqa: E731
        lo, hi = np.full(N, 0.05), np.full(N, 2.0)
    else:
        phase = lambda: t + rng.uniform(0, 6, (N, 1))  # noqa: E731
        t_s = np.ascontiguousarray(rng.uniform(-1, 1, (N, 1)) + rng.uniform(0.5, 2, (N, 1)) * np.cos(phase()))
        n_s = np.ascontiguousarray(rng.uniform(0.05, 1.5, (N, 1)) * (1 - np.cos(t + rng.uniform(0, 6, (N, 1)))) ** 2)
        side, rows = rng.choice([-1.0, 1.0], N), np.arange(N)
        t_end = np.where(side > 0, t_s.max(axis=1), t_s.min(axis=1)) + side * 0.1
        F = lambda sel, u: rpr_swing(t_s, n_s, rows[sel], side[sel], t_end[sel], u)  # noqa: E731
        solve = lambda *a: solve_rpr(t_s, n_s, rows, side, t_end, *a, SWING_TOL, SWING_MAX_ITER)  # noqa: E731
        lo, hi = np.zeros(N), np.full(N, 10.0)
    target = np.radians(rng.uniform(5, 120, N))
    u0 = rng.uniform(0.01, 3.0, N)  # some outside the RRR bracket: clipped
    active = rng.random(N) < 0.9
    for check_far in (True, False):
        want = _numpy_rtsafe(F, lo, hi, u0, target, active, check_far)
        for threads in (1, 3):
            parallel_rows.set_threads(threads)
            try:
                got = solve(lo, hi, u0, target, active, check_far)
            finally:
                parallel_rows.set_threads(parallel_rows._default_threads())
            for a, b in zip(got, want):
                np.testing.assert_array_equal(a, b)
        u, S, ok = want
        assert 10 < np.count_nonzero(ok) < np.count_nonzero(active)  # roots found and missed
        assert np.all(np.abs(F(np.flatnonzero(ok), u[ok])[0] - target[ok]) <= SWING_TOL)
        assert np.all(S[~ok] == 0)


def test_pseudo_angle_orders_directions_as_atan2_signed_zeros_and_cut_included():
    from synth.mechanism.dyad_kernel import pseudo_angle

    rng = np.random.default_rng(5)
    angles = np.concatenate([rng.uniform(-np.pi, np.pi, 400), np.linspace(-np.pi, np.pi, 17)])
    xy = [(math.sin(a), math.cos(a)) for a in angles] + [
        (0.0, 1.0),
        (-0.0, 1.0),
        (0.0, -1.0),
        (-0.0, -1.0),
        (1.0, 0.0),
        (-1.0, -0.0),
        (1e-300, -1.0),
        (-1e-300, -1.0),
    ]
    exact = np.array([math.atan2(y, x) for y, x in xy])
    pseudo = np.array([pseudo_angle(y, x) for y, x in xy])
    assert np.all(np.abs(pseudo) <= 2.0)
    i, j = np.triu_indices(len(xy), 1)
    apart = np.abs(exact[i] - exact[j]) > 1e-12
    np.testing.assert_array_equal(np.sign(pseudo[i] - pseudo[j])[apart], np.sign(exact[i] - exact[j])[apart])
    # the cut (−x axis): on it or just above it the largest direction, below it the smallest,
    # as atan2 has them (+π, −π) — signed zeros included
    assert pseudo_angle(0.0, -1.0) == pseudo_angle(1e-300, -1.0) == 2.0
    assert pseudo_angle(-0.0, -1.0) == pseudo_angle(-1e-300, -1.0) == -2.0
    # the extremes agree up to a tie within rounding (what the kernels' docstring allows)
    assert exact[np.argmax(pseudo)] >= exact.max() - 1e-12 and exact[np.argmin(pseudo)] <= exact.min() + 1e-12
