"""Six-bar simulation and figures: against an independent per-angle re-implementation,
closed-form derivatives against central differences, loop closure, known dwell intervals and
window deviations on synthetic output curves, flags for revolving and non-assemblable
mechanisms, and no NaN/inf on random input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from harness.plain_sixbar import reference_psi
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

from kinematics.fourbar import fourbar_motion
from kinematics.status import AssemblyError, Status
from synth import ball_point, line_scan, pole
from synth.mechanism.dyad import fit_rrr
from synth.mechanism.figures import sixbar_figures
from synth.mechanism.output_range import dwell_intervals, output_deviation, output_swing
from synth.mechanism.sixbar import OutputDyad, SixBar, SixBars, crank_grid, simulate

DEG = math.pi / 180


def _wrapped(x: float) -> float:
    return (x + math.pi) % (2 * math.pi) - math.pi


# ---------------------------------------------------------------------------------------------
# Mechanisms with a real dwell: Ball points (RPR) and circle points (RRR) of crank-rockers
# ---------------------------------------------------------------------------------------------

FOURBARS = [(1.0, 3.0, 3.0, 3.5, 1, 1.2), (1.0, 2.5, 3.0, 3.0, -1, 4.0), (1.0, 4.0, 2.5, 3.5, 1, 2.5)]
#: Ray angles whose circle points admit an RRR with 40° swing and ≥ 20° transmission.
RAYS = [90 * DEG, 50 * DEG, 100 * DEG]


def _ball_rpr(a, b, c, d, br, phi0, distance=6.0):
    bp = ball_point(pole(fourbar_motion(a, b, c, d, phi0, br)))
    assert bp.status == 0
    D = complex(bp.point + distance * bp.tangent)
    return SixBar(a, b, c, d, br, float(bp.uv.real), float(bp.uv.imag), OutputDyad.rpr(D))


def _circle_rrr(a, b, c, d, br, phi0, alpha=100 * DEG, swing=40 * DEG):
    """RRR on the circle point of the ray at ``alpha`` (line scanning), fitted by fit_rrr."""
    scan = line_scan(pole(fourbar_motion(a, b, c, d, phi0, br)), alpha)
    assert scan.status == 0
    C0, rho, uv = complex(scan.center_point), float(scan.radius), complex(scan.circle_point_uv)
    phi = crank_grid(720)
    path = fourbar_motion(a, b, c, d, phi, br, order=0).coupler_point(uv.real, uv.imag)[0]
    fit = fit_rrr(C0, rho, phi, path, (phi0 - 0.2, phi0 + 0.2), swing, 20 * DEG)
    dyads = fit.dyads()
    assert dyads, "fixture needs an RRR that assembles"
    return SixBar(a, b, c, d, br, uv.real, uv.imag, dyads[0]), C0


@pytest.fixture(scope="module")
def mechanisms() -> list[SixBar]:
    out = [_ball_rpr(*fb) for fb in FOURBARS]
    out += [_circle_rrr(*fb, alpha=ray)[0] for fb, ray in zip(FOURBARS, RAYS)]
    out.append(SixBar(1.0, 3.0, 3.0, 3.5, 1, 0.8, -0.6, OutputDyad.rrr(2.0 - 3.0j, 2.5, 3.0, -1)))
    return out


def test_psi_matches_an_independent_per_angle_solution(mechanisms):
    phi = crank_grid(360)
    for sb in mechanisms:
        motion = simulate(sb, phi)
        assert motion.psi.shape == (360,)
        checked = 0
        for k, p in enumerate(phi):
            ref = reference_psi(sb, float(p))
            if ref is None:
                assert motion.status[k] & Status.NOT_ASSEMBLABLE
                continue
            psi, P, Q = ref
            assert abs(_wrapped(motion.psi[k] - psi)) <= 1e-9
            assert abs(motion.z[0][k] - P) <= 1e-12 * 10
            assert abs(motion.moving_pivot[k] - Q) <= 1e-9
            checked += 1
        assert checked >= 300


def test_batch_equals_single_simulations(mechanisms):
    phi = crank_grid(180)
    batch = SixBars.from_sixbars(mechanisms)
    both = simulate(batch, phi)
    assert both.psi.shape == (len(mechanisms), 180)
    for k, sb in enumerate(mechanisms):
        one = simulate(sb, phi)
        np.testing.assert_array_equal(one.status, both.status[k])
        np.testing.assert_allclose(one.psi, both.psi[k], rtol=0, atol=1e-13)
        np.testing.assert_allclose(one.dpsi[1], both.dpsi[1][k], rtol=1e-13, atol=1e-13)
        assert batch[k] == sb


def test_psi_derivatives_match_central_differences(mechanisms):
    """ψ′ and ψ″ (closed form) against central differences of ψ at safe steps."""
    rng = np.random.default_rng(3)
    checked = 0
    for sb in mechanisms:
        for p in rng.uniform(0, 2 * np.pi, 8):
            m = simulate(sb, np.array([p]))
            if m.status[0]:
                continue
            checked += 1
            h1, h2 = 1e-5, 1e-3
            ps = simulate(sb, p + np.array([-h2, -h1, 0.0, h1, h2]), order=0).psi
            d1 = (ps[3] - ps[1]) / (2 * h1)
            d2 = (ps[4] - 2 * ps[2] + ps[0]) / (h2 * h2)
            assert m.dpsi[0][0] == pytest.approx(d1, rel=1e-7, abs=1e-8)
            assert m.dpsi[1][0] == pytest.approx(d2, rel=1e-4, abs=1e-5)
    assert checked >= 6 * len(mechanisms)  # most sampled angles assemble: the check is not vacuous


def test_rrr_loop_closure(mechanisms):
    phi = crank_grid(720)
    for sb in mechanisms:
        if sb.dyad.kind != "RRR":
            continue
        m = simulate(sb, phi)
        ok = m.assembled
        assert ok.sum() > 600
        Q, D, P = m.moving_pivot[ok], sb.dyad.pivot, m.z[0][ok]
        np.testing.assert_allclose(np.abs(Q - D), sb.dyad.rocker, rtol=0, atol=1e-12 * 10)
        np.testing.assert_allclose(np.abs(Q - P), sb.dyad.rod, rtol=0, atol=1e-12 * 10)
        # the branch is the documented side: Q left of P → D for +1
        side = np.sign(((D - P).conjugate() * (Q - P)).imag)
        assert np.all(side == sb.dyad.branch)


def test_rrr_moving_pivot_rests_at_the_arc_centre_at_the_generating_instant():
    for fb, ray in zip(FOURBARS, RAYS):
        sb, C0 = _circle_rrr(*fb, alpha=ray)
        m = simulate(sb, np.array([fb[-1]]))
        assert m.status[0] == 0
        assert abs(m.moving_pivot[0] - C0) < 1e-9


def test_unwrapped_psi_is_continuous_over_the_turn(mechanisms):
    phi = crank_grid(720)
    for sb in mechanisms:
        m = simulate(sb, phi)
        step = np.abs(np.diff(m.psi))
        assert step.max() < 0.5


def test_transmission_angles(mechanisms):
    phi = crank_grid(90)
    for sb in mechanisms:
        m = simulate(sb, phi)
        assert np.all((0 <= m.transmission_fourbar) & (m.transmission_fourbar <= np.pi / 2))
        assert np.all((0 <= m.transmission_output) & (m.transmission_output <= np.pi / 2))
        if sb.dyad.kind == "RPR":
            assert np.all(m.transmission_output == np.pi / 2)
        else:
            # law of cosines at Q, folded
            P, D = m.z[0], sb.dyad.pivot
            cos_mu = (sb.dyad.rod**2 + sb.dyad.rocker**2 - np.abs(P - D) ** 2) / (2 * sb.dyad.rod * sb.dyad.rocker)
            ok = m.assembled
            np.testing.assert_allclose(m.transmission_output[ok], np.arccos(np.abs(cos_mu[ok])), atol=1e-7)
        # four-bar: coupler vs rocker at B, by the law of cosines
        fb = m.fourbar
        cos_fb = (sb.b**2 + sb.c**2 - np.abs(fb.A - sb.d) ** 2) / (2 * sb.b * sb.c)
        np.testing.assert_allclose(m.transmission_fourbar, np.arccos(np.abs(cos_fb)), atol=1e-7)


# ---------------------------------------------------------------------------------------------
# Flags, rejection, bad input
# ---------------------------------------------------------------------------------------------


def test_dyad_that_cannot_assemble_is_flagged_with_finite_placeholders():
    sb = SixBar(1.0, 3.0, 3.0, 3.5, 1, 0.5, 0.5, OutputDyad.rrr(6.0 + 0j, 1.0, 1.0, 1))
    m = simulate(sb, crank_grid(360))
    bad = (m.status & Status.NOT_ASSEMBLABLE) != 0
    assert bad.any() and not m.assembled.all()
    for arr in (m.psi, m.moving_pivot, *m.dpsi, m.transmission_output):
        assert np.all(np.isfinite(arr))
    assert np.all(m.dpsi[0][bad] == 0)
    f = sixbar_figures(sb, band=0.01)
    assert not f.assembled and not f.acceptable
    assert f.transmission_output == 0.0
    with pytest.raises(AssemblyError, match="not assemblable"):
        simulate(sb, crank_grid(360), on_degenerate="raise")


def test_rpr_pin_on_the_pivot_is_flagged():
    sb0 = _ball_rpr(*FOURBARS[0])
    P = complex(simulate(sb0, np.array([0.3]), order=0).z[0][0])
    sb = SixBar(sb0.a, sb0.b, sb0.c, sb0.d, sb0.branch, sb0.u, sb0.v, OutputDyad.rpr(P))
    m = simulate(sb, np.array([0.3, 0.4]))
    assert m.status[0] & Status.NOT_ASSEMBLABLE and m.status[1] == 0
    assert np.all(np.isfinite(m.psi)) and np.all(np.isfinite(m.dpsi[1]))


def test_revolving_output_is_detected_and_rejected():
    # The pin at the crank pin itself (p = 0) runs on the unit circle around A0; a slot pivot
    # inside that circle makes the output turn with the crank.
    sb = SixBar(1.0, 3.0, 3.0, 3.5, 1, 0.0, 0.0, OutputDyad.rpr(0.2 + 0.1j))
    f = sixbar_figures(sb, band=0.01)
    assert f.turns == 1 and f.revolving and not f.acceptable and f.status == 0
    sb0 = _ball_rpr(*FOURBARS[0])
    ok = sixbar_figures(sb0, band=0.01)
    assert ok.turns == 0 and ok.acceptable


def test_four_bar_that_cannot_turn_is_flagged():
    # non-Grashof: the crank cannot make a full turn
    sb = SixBar(1.0, 1.5, 1.2, 3.2, 1, 0.3, 0.2, OutputDyad.rpr(5.0 + 5.0j))
    m = simulate(sb, crank_grid(360))
    assert np.any(m.status & Status.NOT_ASSEMBLABLE)
    assert np.all(np.isfinite(m.psi))


def test_bad_input_is_refused():
    with pytest.raises(AssemblyError):
        SixBar(1.0, -3.0, 3.0, 3.5, 1, 0.0, 0.0, OutputDyad.rpr(0j))
    with pytest.raises(ValueError, match="kind"):
        OutputDyad("PRP", 0j)
    with pytest.raises(AssemblyError):
        OutputDyad.rrr(0j, 0.0, 1.0, 1)
    with pytest.raises(ValueError, match="branch"):
        OutputDyad.rrr(0j, 1.0, 1.0, 0)
    assert OutputDyad.rpr((1.0, 2.0)).pivot == 1 + 2j
    sb = _ball_rpr(*FOURBARS[0])
    with pytest.raises(ValueError, match="order"):
        simulate(sb, [0.0], order=3)
    with pytest.raises(ValueError, match="on_degenerate"):
        simulate(sb, [0.0], on_degenerate="ignore")
    with pytest.raises(ValueError, match="finite"):
        simulate(sb, [np.nan])
    with pytest.raises(ValueError, match="uniform"):
        dwell_intervals(np.linspace(0, 1, 50), np.zeros(50), 0.1)
    with pytest.raises(ValueError, match="count"):
        dwell_intervals(crank_grid(50), np.zeros(50), 0.1, count=3)


# ---------------------------------------------------------------------------------------------
# Figures on synthetic output curves with known answers
# ---------------------------------------------------------------------------------------------

TWO_PI = 2 * math.pi
# Two rests: ψ = 0 on [0.5, 1.5], ψ = 1 on [3.5, 4.0]; smoothstep rise and fall between.
REST1, REST2 = (0.5, 1.5), (3.5, 4.0)


def _smooth(x):
    return 3 * x * x - 2 * x**3


def two_rest_psi(phi):
    p = np.mod(np.asarray(phi, float) - REST1[0], TWO_PI) + REST1[0]  # into [0.5, 0.5 + 2π)
    rise = _smooth(np.clip((p - REST1[1]) / (REST2[0] - REST1[1]), 0, 1))
    fall = _smooth(np.clip((p - REST2[1]) / (REST1[0] + TWO_PI - REST2[1]), 0, 1))
    return np.where(p <= REST2[1], rise, 1 - fall)


def _expected_rest(rest, level, band):
    """Ends of the band around one rest, solved independently (brentq on the formula)."""
    lo_end = brentq(lambda x: abs(two_rest_psi(x) - level) - band, rest[0] - 1.9, rest[0])
    hi_end = brentq(lambda x: abs(two_rest_psi(x) - level) - band, rest[1], rest[1] + 1.9)
    return lo_end, hi_end


@pytest.mark.parametrize("samples", [720, 500])
def test_dwell_intervals_find_known_rests_to_a_hundredth_of_a_degree(samples):
    phi = crank_grid(samples, start=0.2)
    band = 0.02
    found = dwell_intervals(phi, two_rest_psi(phi), band, count=2, psi_at=two_rest_psi)
    lo1, hi1 = _expected_rest(REST1, 0.0, band)
    lo2, hi2 = _expected_rest(REST2, 1.0, band)
    assert found.found.tolist() == [True, True]
    assert abs(found.start[0] - lo1) < 0.01 * DEG and abs(found.end[0] - hi1) < 0.01 * DEG
    assert abs(found.start[1] - lo2) < 0.01 * DEG and abs(found.end[1] - hi2) < 0.01 * DEG
    # conservative: inside the exact interval
    assert found.start[0] >= lo1 - 1e-12 and found.end[0] <= hi1 + 1e-12
    assert found.angle[0] == pytest.approx(found.end[0] - found.start[0])
    assert found.high[0] - found.low[0] <= band
    # without the exact path: sample ends, within one grid step
    grid = dwell_intervals(phi, two_rest_psi(phi), band, count=2)
    step = TWO_PI / samples
    assert abs(grid.start[0] - lo1) < step and abs(grid.end[0] - hi1) < step


def test_dwell_intervals_wrap_past_the_turn_and_vectorise():
    shift = 1.0  # puts the first rest across φ = 0
    phi = crank_grid(720)
    rows = np.stack([two_rest_psi(phi + shift), two_rest_psi(phi)])
    found = dwell_intervals(
        phi, rows, np.array([0.02, 0.02]), psi_at=lambda at: two_rest_psi(at + np.array([[shift], [0.0]]))
    )
    lo1, hi1 = _expected_rest(REST1, 0.0, 0.02)
    assert found.start.shape == (2, 1)
    assert abs(found.start[1, 0] - lo1) < 0.01 * DEG
    assert found.start[0, 0] == pytest.approx(np.mod(lo1 - shift, TWO_PI), abs=0.01 * DEG)
    assert found.end[0, 0] == pytest.approx(np.mod(lo1 - shift, TWO_PI) + (hi1 - lo1), abs=0.02 * DEG)
    assert found.end[0, 0] > TWO_PI  # wraps past 2π


def test_dwell_of_a_resting_output_is_the_whole_turn():
    phi = crank_grid(100)
    found = dwell_intervals(phi, 1e-4 * np.sin(phi), 1e-3, count=2, psi_at=lambda at: 1e-4 * np.sin(at))
    assert found.angle[0] == pytest.approx(TWO_PI)
    assert found.found.tolist() == [True, False] and found.angle[1] == 0.0


def test_one_drifting_rest_is_not_two_dwells():
    """A single rest whose output drifts slowly at one end: the grid finds a second window
    next to the first, which refinement on the exact path slides back into the first. Found by
    the query's refined near misses (the same interval reported as both dwells of a "double
    dwell", step 0): the second dwell is not found, the first is the rest itself."""
    from synth.query.candidate_ids import candidate_dimensions

    sb = candidate_dimensions("26600020-dbl0.0@free~AUBV0QtAbVtfQD58GECTNV2_qdBMPcBOQ8CfRgM")
    f = sixbar_figures(sb, band=math.radians(0.1), dwell_length=math.radians(50), dwells=2)
    assert len(f.dwells) == 1 and f.step is None
    assert math.degrees(f.dwells[0].angle) == pytest.approx(52.484, abs=0.01)
    # the output leaves the band on both sides (a brute-force 0.05° walk around the rest)
    phi = np.radians(np.arange(200.0, 380.0, 0.05))
    psi = np.unwrap(simulate(sb, phi, order=0).psi.ravel())
    inside = np.abs(psi - f.dwells[0].rest) <= math.radians(0.05) + 1e-12
    assert not inside[0] and not inside[-1]
    runs = np.flatnonzero(np.diff(inside.astype(int)))
    assert len(runs) == 2  # one run within the band: one rest


def test_output_deviation_of_a_window_longer_than_the_rest():
    # ψ = k·dist(φ, [0.5, 1.5])² near the rest: the best window of length 1.4 overhangs the
    # rest by 0.2 on each side, so the deviation is k·0.2².
    k = 0.7

    def psi_fn(at):
        at = np.asarray(at, float)
        return k * (np.maximum(0.5 - at, 0) ** 2 + np.maximum(at - 1.5, 0) ** 2)

    phi = crank_grid(720, start=-2.0)
    dev, start = output_deviation(phi, psi_fn(phi), 1.0, 1.4, psi_at=psi_fn)
    assert dev == pytest.approx(k * 0.04, rel=2e-3)
    assert start == pytest.approx(0.3, abs=0.02 * DEG)
    dev_in, _ = output_deviation(phi, psi_fn(phi), 1.0, 0.8, psi_at=psi_fn)
    assert dev_in == 0.0
    grid, _ = output_deviation(phi, psi_fn(phi), 1.0, 1.4)
    assert grid == pytest.approx(k * 0.04, rel=0.05)


def test_output_swing_and_turns():
    phi = crank_grid(360)
    psi = 0.3 * np.sin(phi - 0.123)
    dpsi = (0.3 * np.cos(phi - 0.123), -0.3 * np.sin(phi - 0.123))
    swing, turns = output_swing(phi, psi, dpsi=dpsi, psi_at=lambda at: 0.3 * np.sin(at - 0.123))
    assert swing == pytest.approx(0.6, abs=1e-12) and turns == 0
    swing_p, _ = output_swing(phi, psi)  # parabolic refinement only
    assert swing_p == pytest.approx(0.6, abs=1e-7)
    _, turns = output_swing(phi, phi + 0.1 * np.sin(phi))
    assert turns == 1


# ---------------------------------------------------------------------------------------------
# Figures of real mechanisms
# ---------------------------------------------------------------------------------------------


def test_ball_point_rpr_dwells_and_figures_come_from_the_exact_path():
    a, b, c, d, br, phi0 = FOURBARS[0]
    sb = _ball_rpr(a, b, c, d, br, phi0)
    f = sixbar_figures(sb, band=0.1 * DEG, dwell_length=40 * DEG)
    (dwell,) = f.dwells
    assert dwell.start < phi0 < dwell.end and dwell.angle > 60 * DEG
    # the reported band holds on a dense exact evaluation of the interval
    dense = simulate(sb, np.linspace(dwell.start, dwell.end, 4001), order=0).psi
    assert dense.max() - dense.min() <= 0.1 * DEG + 1e-9
    # and it is maximal: 0.01° more on either side leaves the band
    for more in (
        np.linspace(dwell.start - 0.01 * DEG, dwell.end, 4001),
        np.linspace(dwell.start, dwell.end + 0.01 * DEG, 4001),
    ):
        wider = simulate(sb, more, order=0).psi
        assert wider.max() - wider.min() > 0.1 * DEG - 1e-6
    assert 0 <= f.deviations[0] < 0.1 * DEG
    dense = simulate(sb, np.linspace(0, TWO_PI, 200001), order=0).psi
    assert f.swing == pytest.approx(dense.max() - dense.min(), abs=1e-9)
    assert f.turns == 0 and f.status == 0
    assert 0 < f.transmission_fourbar <= np.pi / 2 and f.transmission_output == np.pi / 2
    assert f.link_ratio >= max(b, c, d) / a
    xmin, ymin, xmax, ymax = f.bounds
    assert 0 < f.footprint < (xmax - xmin) * (ymax - ymin)


def test_figures_of_a_batch_equal_single_figures(mechanisms):
    batch = SixBars.from_sixbars(mechanisms)
    together = sixbar_figures(batch, band=0.2 * DEG, dwell_length=20 * DEG)
    for sb, fb in zip(mechanisms, together):
        one = sixbar_figures(sb, band=0.2 * DEG, dwell_length=20 * DEG)
        assert one.status == fb.status and one.turns == fb.turns
        assert one.swing == pytest.approx(fb.swing, abs=1e-12)
        for x, y in zip(one.dwells, fb.dwells):
            assert x == pytest.approx(y, abs=1e-12)
        assert one.deviations == pytest.approx(fb.deviations, abs=1e-12)
        assert one.footprint == pytest.approx(fb.footprint, rel=1e-12)


# ---------------------------------------------------------------------------------------------
# Properties: any input gives finite values
# ---------------------------------------------------------------------------------------------


def sixbar_strategy(longest: float = 20.0, shortest: float = 0.05) -> st.SearchStrategy[SixBar]:
    """Any six-bar (RPR or RRR, either branch) with lengths in [shortest, longest] and
    coordinates within ±longest."""
    length = st.floats(shortest, longest, allow_nan=False, allow_infinity=False)
    coord = st.floats(-longest, longest, allow_nan=False, allow_infinity=False)
    sign = st.sampled_from([1, -1])

    @st.composite
    def sixbars(draw):
        kind = draw(st.sampled_from(["RPR", "RRR"]))
        dyad = OutputDyad(kind, complex(draw(coord), draw(coord)), draw(length), draw(length), draw(sign))
        return SixBar(
            draw(length), draw(length), draw(length), draw(length), draw(sign), draw(coord), draw(coord), dyad
        )

    return sixbars()


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(sixbar_strategy(), min_size=1, max_size=4), st.floats(0.0, 0.5))
def test_any_six_bar_gives_finite_motion_and_figures(sbs, band):
    batch = SixBars.from_sixbars(sbs)
    m = simulate(batch, crank_grid(72))
    for arr in (m.psi, m.moving_pivot, *m.z, *m.dpsi, m.transmission_fourbar, m.transmission_output):
        assert np.all(np.isfinite(arr))
    assert np.all(m.dpsi[0][m.status != 0] == 0)
    for f in sixbar_figures(batch, band=band, dwell_length=0.5, dwells=2, samples=72):
        values = [
            f.swing,
            f.transmission_fourbar,
            f.transmission_output,
            f.link_ratio,
            f.footprint,
            *f.bounds,
            *f.deviations,
            *(x for dw in f.dwells for x in dw),
        ]
        assert all(math.isfinite(x) for x in values)
        assert 1 <= len(f.dwells) <= 2
