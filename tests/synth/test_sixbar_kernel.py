"""The compiled six-bar kernel (``synth.mechanism.sixbar_kernel``, what ``simulate`` runs) against the
numpy reference path (``synth.mechanism.sixbar.simulate_numpy``, itself checked against an independent
per-angle solution and central differences in ``test_sixbar.py``), at derivative orders 0, 1
and 2: the same statuses and, where the dyad is well conditioned, the same positions, angles
and derivatives to ~1e-11 — on mechanisms with
every kind of degenerate position (a dyad or a four-bar that cannot assemble, the RPR pin on
its pivot, coincident circle centres, lengths near 1e±70 that need the scaled Heron form) and
on any six-bar hypothesis draws. The two are not bitwise equal: numpy's complex product may
fuse a multiply and an add (FMA) where the kernel does not."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from test_sixbar import sixbar_strategy  # tests/synth: any six-bar

from kinematics.status import AssemblyError, Status
from synth.mechanism.sixbar import OutputDyad, SixBar, SixBars, crank_grid, output_angle, simulate, simulate_numpy

NA = int(Status.NOT_ASSEMBLABLE)


def random_batch(n: int, seed: int) -> SixBars:
    """Mixed RPR/RRR six-bars on both branches, a third of them with dyads or four-bars that
    cannot assemble over part of the turn, a few with the slot pivot on the coupler path."""
    rng = np.random.default_rng(seed)
    a = np.ones(n)
    b, c, d = rng.uniform(0.5, 5.0, (3, n))
    u, v = rng.uniform(-2.0, 2.0, (2, n))
    pivot = rng.uniform(-6, 6, n) + 1j * rng.uniform(-6, 6, n)
    rocker, rod = rng.uniform(0.2, 8.0, (2, n))
    sign = lambda: np.where(rng.random(n) < 0.5, 1.0, -1.0)  # noqa: E731
    rpr = rng.random(n) < 0.4
    return SixBars(a, b, c, d, sign(), u, v, rpr, pivot, rocker, rod, sign())


def assert_same_motion(fast, ref, batch: SixBars) -> None:
    """Statuses equal; positions within 1e-12·size and angles within 1e-11 rad (transmission
    angles: times 1e-4 of the longest over the shortest link where that is above 1e4) wherever the
    dyad and the four-bar close away from a toggle (there the angles' condition number is
    below 1e3); finite everywhere; the output's transmission placeholders (π/2 for a slotted
    rocker, 0 where an RRR dyad cannot close)."""
    np.testing.assert_array_equal(fast.status, ref.status)
    np.testing.assert_array_equal(fast.fourbar.status, ref.fourbar.status)
    assert fast.psi.shape == ref.psi.shape and fast.status.dtype == np.uint16
    for arr in (fast.psi, fast.z[0], fast.moving_pivot, fast.transmission_fourbar, fast.transmission_output):
        assert np.all(np.isfinite(arr))
    shape = ref.psi.shape
    column = (lambda x: x[0]) if len(shape) == 1 else (lambda x: x[:, None])  # noqa: E731
    size, rpr = (np.broadcast_to(column(x), shape) for x in (_size(batch), batch.rpr))
    ok = (ref.status == 0) & (ref.transmission_output > 1e-3) & (ref.transmission_fourbar > 1e-3)
    tol = 1e-12 * size[ok]
    assert np.all(np.abs(fast.z[0] - ref.z[0])[ok] <= tol)
    assert np.all(np.abs(fast.moving_pivot - ref.moving_pivot)[ok] <= tol)
    assert np.all(np.abs(fast.fourbar.e_theta - ref.fourbar.e_theta)[ok] <= 1e-12)
    wrapped = np.angle(np.exp(1j * (fast.psi - ref.psi)))
    assert np.all(np.abs(wrapped[ok]) <= 1e-11)
    # derivatives: ψ′, ψ″ ∝ 1/sin μ (≤ 1e3 here), so 1e-9 relative; 0 wherever flagged
    assert len(fast.dpsi) == len(ref.dpsi) and len(fast.z) == len(ref.z)
    for k in range(len(ref.dpsi)):
        for got, want in (
            (fast.dpsi[k], ref.dpsi[k]),
            (fast.fourbar.dtheta[k], ref.fourbar.dtheta[k]),
            (fast.fourbar.dgamma[k], ref.fourbar.dgamma[k]),
            (fast.z[k + 1], ref.z[k + 1]),
        ):
            got, want = np.broadcast_to(got, shape), np.broadcast_to(want, shape)
            assert np.all(np.isfinite(got))
            assert np.all((np.abs(got - want) <= 1e-9 * (np.abs(want) + size))[ok])
        assert np.all(fast.dpsi[k][ref.status != 0] == 0)
    # a transmission angle is an arccos of lengths up to `size` over sides down to the shortest
    # link: its rounding grows with that ratio (rod 0.0078 under a 954 rocker: 1.6e-11 rad)
    ratio = np.broadcast_to(column(_size(batch) / _shortest(batch)), shape)
    angle_tol = 1e-11 * np.maximum(1.0, 1e-4 * ratio[ok])
    for name in ("transmission_fourbar", "transmission_output"):
        assert np.all(np.abs(getattr(fast, name) - getattr(ref, name))[ok] <= angle_tol), name
    assert np.all(fast.transmission_output[rpr] == 0.5 * math.pi)
    dyad_apart = ((ref.status & NA) != 0) & ((ref.fourbar.status & NA) == 0) & ~rpr
    assert np.all(fast.transmission_output[dyad_apart] == 0.0)


def _size(batch: SixBars) -> np.ndarray:
    return np.maximum.reduce([batch.a, batch.b, batch.c, batch.d, np.abs(batch.pivot), batch.rocker, batch.rod])


def _shortest(batch: SixBars) -> np.ndarray:
    """The shortest link of each row (an RPR has no rocker or rod)."""
    dyad = np.where(batch.rpr, np.inf, np.minimum(batch.rocker, batch.rod))
    return np.minimum.reduce([batch.a, batch.b, batch.c, batch.d, dyad])


@pytest.mark.parametrize("order", [0, 1, 2])
def test_kernel_matches_the_numpy_path_on_random_six_bars(order):
    batch = random_batch(4000, 7)
    phi = crank_grid(360)
    fast, ref = simulate(batch, phi, order=order), simulate_numpy(batch, False, phi, order, "flag")
    assert_same_motion(fast, ref, batch)
    # the sample holds every case: running, dyad apart, four-bar apart
    assert np.count_nonzero(ref.status == 0) > 100_000
    assert np.count_nonzero((ref.status & NA) != 0) > 10_000
    assert np.count_nonzero((ref.fourbar.status & NA) != 0) > 10_000
    assert len(fast.dpsi) == order and len(fast.z) == order + 1
    if order == 0:  # ψ alone: the same numbers as the whole simulation's, bit for bit
        np.testing.assert_array_equal(output_angle(batch, phi), fast.psi)
        rows = np.sort(np.random.default_rng(1).uniform(0, 7, (len(batch), 9)), axis=1)
        np.testing.assert_array_equal(output_angle(batch, rows), simulate(batch, rows, order=0).psi)
        # a shape the kernel does not take (one angle for all) goes through simulate
        np.testing.assert_array_equal(output_angle(batch, 0.3), simulate(batch, 0.3, order=0).psi)


@pytest.mark.parametrize("order", [0, 2])
def test_kernel_takes_one_crank_grid_per_six_bar(order):
    batch = random_batch(50, 3)
    rng = np.random.default_rng(0)
    phi = np.sort(rng.uniform(0, 2 * math.pi, (50, 97)), axis=1)
    fast, ref = simulate(batch, phi, order=order), simulate_numpy(batch, False, phi, order, "flag")
    assert_same_motion(fast, ref, batch)
    shared = simulate(batch, phi[:1], order=order)  # (1, M): one grid for all
    assert_same_motion(shared, simulate_numpy(batch, False, phi[:1], order, "flag"), batch)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_single_six_bar_and_shapes_the_kernel_does_not_take(order):
    sb = SixBar(1.0, 3.0, 3.0, 3.5, 1, 0.8, -0.6, OutputDyad.rrr(2.0 - 3.0j, 2.5, 3.0, -1))
    phi = crank_grid(360)
    one = simulate(sb, phi, order=order)
    assert one.psi.shape == (360,) and one.fourbar.A.shape == (360,) and np.ndim(one.pivot) == 0
    assert all(x.shape == (360,) for x in (*one.z, *one.dpsi, *one.fourbar.dtheta))
    one_batch = SixBars.from_sixbars([sb])
    assert_same_motion(one, simulate_numpy(one_batch, True, phi, order, "flag"), one_batch)
    batch = SixBars.from_sixbars([sb, sb])
    np.testing.assert_array_equal(simulate(batch, phi, order=order).psi[1], one.psi)
    # a scalar crank angle goes through the numpy path
    at = simulate(sb, 0.3, order=order)
    assert at.psi.shape == ()
    assert math.isfinite(float(at.psi))
    # the buildability check reads the four-bar's joints from the motion
    m = simulate(batch, phi, order=order)
    assert m.fourbar.A.shape == (2, 360) and m.fourbar.B.shape == (2, 360)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_degenerate_positions_are_flagged_alike(order):
    phi = crank_grid(720)
    cases = [
        SixBar(1.0, 3.0, 3.0, 3.5, 1, 0.5, 0.5, OutputDyad.rrr(6.0 + 0j, 1.0, 1.0, 1)),  # dyad cannot close
        SixBar(1.0, 1.5, 1.2, 3.2, 1, 0.3, 0.2, OutputDyad.rpr(5.0 + 5.0j)),  # crank cannot turn
        SixBar(1.0, 3.0, 3.0, 3.5, 1, 0.0, 0.0, OutputDyad.rpr(1.0 + 0j)),  # pin passes over the pivot at φ = 0
        SixBar(1.0, 3.0, 3.0, 3.5, 1, 0.0, 0.0, OutputDyad.rrr(1.0 + 0j, 1.0, 1.0, 1)),  # P = D at φ = 0: centres meet
        SixBar(1e-70, 3e-70, 3e-70, 3.5e-70, 1, 1e-70, 1e-70, OutputDyad.rrr(2e-70 + 3e-70j, 3e-70, 2e-70, 1)),
        SixBar(1e70, 3e70, 3e70, 3.5e70, -1, 1e70, -1e70, OutputDyad.rrr(2e70 - 3e70j, 4e70, 3e70, -1)),
    ]
    batch = SixBars.from_sixbars(cases)
    fast, ref = simulate(batch, phi, order=order), simulate_numpy(batch, False, phi, order, "flag")
    assert_same_motion(fast, ref, batch)
    assert fast.status[0].any() and fast.status[1].any() and fast.status[2][0] & NA and fast.status[3][0] & NA
    assert np.all(fast.transmission_output[2] == 0.5 * math.pi)
    with pytest.raises(AssemblyError, match="not assemblable"):
        simulate(cases[0], phi, order=order, on_degenerate="raise")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(sixbar_strategy(1e3, 1e-3), min_size=1, max_size=5),
    st.integers(8, 200),
    st.floats(-10.0, 10.0),
    st.sampled_from([0, 1, 2]),
)
@example([SixBar(1.0, 1.0, 1.0, 1.0, 1, 0.0, 0.0, OutputDyad.rrr(0j, 1.0, 1.0, 1))], 8, 0.0, 2)
@example(  # a rod 1.2e5 times shorter than its rocker: the transmission angle rounds to 1.6e-11
    [
        SixBar(
            286.9375,
            546.65625,
            697.71875,
            817.27734375,
            1,
            0.015625,
            -740.4375,
            OutputDyad.rrr(336.25j, 954.53125, 0.0078125, 1),
        )
    ],
    164,
    1.6319200393713302,
    0,
)
def test_any_six_bar_runs_the_same_in_the_kernel(sbs, samples, start, order):
    batch = SixBars.from_sixbars(sbs)
    phi = crank_grid(samples, start)
    fast, ref = simulate(batch, phi, order=order), simulate_numpy(batch, False, phi, order, "flag")
    assert_same_motion(fast, ref, batch)
