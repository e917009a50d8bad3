"""Buildability figures (synth.mechanism.buildability) against independent checks: the spectral ψ‴
against a closed form and central differences of ψ″, the torque arm and the clearance against
a brute-force walk of every pair on a 10x finer crank grid, the dynamics' scaling with speed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from harness.report_cases import double_dwell_candidates, single_dwell_candidates

from synth.mechanism.buildability import buildability, output_rates
from synth.mechanism.figures import sixbar_figures
from synth.mechanism.sixbar import SixBars, crank_grid, simulate


@pytest.fixture(scope="module")
def sixbars():
    return [c.sixbar for c in single_dwell_candidates() + double_dwell_candidates()]


@pytest.mark.parametrize("k", [1, 3, 7])
def test_spectral_derivative_of_a_trigonometric_polynomial_is_exact(k):
    phi = crank_grid(720)
    got = output_rates(np.cos(k * phi) + 0.5 * np.sin(2 * phi))
    np.testing.assert_allclose(got, -k * np.sin(k * phi) + np.cos(2 * phi), atol=1e-10)


def test_third_derivative_matches_central_differences_of_the_second(sixbars):
    phi = crank_grid(720)
    motion = simulate(SixBars.from_sixbars(sixbars), phi, order=2)
    d3 = output_rates(motion.dpsi[1])
    h = 1e-4
    for k, sb in enumerate(sixbars):
        for i in range(0, 720, 37):
            plus = simulate(sb, np.array([phi[i] + h]), order=2).dpsi[1][0]
            minus = simulate(sb, np.array([phi[i] - h]), order=2).dpsi[1][0]
            fd = (plus - minus) / (2 * h)
            assert d3[k, i] == pytest.approx(fd, rel=2e-3, abs=2e-3 * (1 + np.abs(d3[k]).max())), (k, i)


def _pairs(sb, samples=7200, every=1):
    """|P − D| and every pair the module considers (inf for those of the other dyad kind), over
    every ``every``-th of ``samples`` crank angles, written out one by one in numpy."""
    phi = crank_grid(samples)[::every]
    m = simulate(sb, phi, order=0)
    A, B, P, Q = m.fourbar.A * np.ones(phi.size), m.fourbar.B, m.z[0], m.moving_pivot
    A0, B0, D = 0j, complex(sb.d), sb.dyad.pivot

    def seg(p, a, b):
        t = np.clip(((p - a) * np.conj(b - a)).real / np.abs(b - a) ** 2, 0, 1)
        return np.abs(p - (a + t * (b - a)))

    none = np.full(phi.size, np.inf)
    pairs = [np.abs(A - B0), np.abs(A - D), np.abs(B - A0), np.abs(B - D), np.abs(P - A0), np.abs(P - B0)]
    if sb.dyad.kind == "RRR":
        pairs += [
            np.abs(P - D),
            np.abs(Q - A0),
            np.abs(Q - B0),
            seg(A0, P, Q),
            seg(B0, P, Q),
            seg(D, P, Q),
            seg(A0, D, Q),
            seg(B0, D, Q),
            none,
            none,
        ]
    else:
        end = D + np.abs(P - D).max() * np.exp(1j * m.psi)
        pairs += [none] * 8 + [seg(A0, D, end), seg(B0, D, end)]
    return np.abs(P - D), np.array([p.min() for p in pairs])


def _brute_force(sb, samples=7200):
    """min over the turn of |P − D| (the arm) and of every pair the module considers."""
    reach, pairs = _pairs(sb, samples)
    return reach.min(), pairs.min()


def test_arm_and_clearance_against_a_fine_brute_force(sixbars):
    phi = crank_grid(720)
    batch = SixBars.from_sixbars(sixbars)
    found = buildability(batch, simulate(batch, phi, order=2))
    for sb, b in zip(sixbars, found):
        arm, clearance = _brute_force(sb)
        size = max(sb.a, sb.b, sb.c, sb.d)
        # the 720-sample minimum is above the true one by at most the path's travel in half a step
        assert clearance - 1e-12 <= b.clearance <= clearance + 5e-3 * size, (b, clearance)
        if sb.dyad.kind == "RPR":
            assert arm - 1e-12 <= b.arm <= arm + 5e-3 * size
            assert b.slot[0] == b.arm and b.slot[1] > b.slot[0]
        else:
            assert b.arm is None and b.slot is None


@pytest.mark.parametrize("every", [1, 4])
def test_every_pair_on_the_samples_is_its_distance_written_out(sixbars, every):
    """The compiled clearances (synth.mechanism.clearance_kernel) against each pair's numpy distance on
    the same samples: to rounding, and the pair they name sets the smallest of them."""
    from synth.mechanism.buildability import CLEARANCE_PAIRS, clearances
    from synth.mechanism.clearance_kernel import pair_clearances

    phi = crank_grid(720)
    batch = SixBars.from_sixbars(sixbars)
    motion = simulate(batch, phi, order=2)
    reach, clearance, which, rpr = clearances(batch, motion, every=every)
    m = motion.psi.shape[1]
    smallest, _ = pair_clearances(
        *(
            np.broadcast_to(x, motion.psi.shape)
            for x in (motion.fourbar.A, motion.fourbar.B, motion.z[0], motion.moving_pivot)
        ),
        motion.psi,
        batch.d,
        batch.pivot,
        batch.rpr,
        every,
    )
    assert smallest.shape == (len(sixbars), len(CLEARANCE_PAIRS))
    for k, sb in enumerate(sixbars):
        want_reach, want = _pairs(sb, 720, every)
        size = max(sb.a, sb.b, sb.c, sb.d, np.abs(want_reach).max())
        np.testing.assert_allclose(reach[k], want_reach, rtol=0, atol=1e-13 * size)
        np.testing.assert_array_equal(np.isinf(smallest[k]), np.isinf(want))
        finite = np.isfinite(want)
        np.testing.assert_allclose(smallest[k][finite], want[finite], rtol=0, atol=1e-12 * size)
        assert clearance[k] == smallest[k].min() and want[which[k]] <= want.min() + 1e-12 * size
        assert rpr[k] == (sb.dyad.kind == "RPR") and reach[k].size == len(range(0, m, every))


def test_joint_a_to_b0_closed_form():
    """A runs on the circle |A| = a, B0 is d from its centre: their clearance is d − a."""
    from synth.mechanism.sixbar import OutputDyad, SixBar

    sb = SixBar(1.0, 3.0, 2.5, 3.0, 1, 1.0, 1.0, OutputDyad.rrr(complex(1.5, 30.0), 5.0, 30.0, 1))
    phi = crank_grid(720)
    b = buildability(SixBars.from_sixbars([sb]), simulate(SixBars.from_sixbars([sb]), phi, order=2))[0]
    arm, clearance = _brute_force(sb)
    assert b.clearance <= 2.0 + 1e-9  # d − a: A passes B0 at φ = 0 (a sample)
    assert b.clearance == pytest.approx(clearance, abs=5e-3)


def test_dynamics_scale_with_the_crank_speed(sixbars):
    f = sixbar_figures(sixbars[0], band=math.radians(0.1))
    v60, a60, j60 = f.build.dynamics(60.0)
    v120, a120, j120 = f.build.dynamics(120.0)
    assert (v120, a120, j120) == pytest.approx((2 * v60, 4 * a60, 8 * j60))
    assert v60 == pytest.approx(f.build.peak_rates[0] * 2 * math.pi)
