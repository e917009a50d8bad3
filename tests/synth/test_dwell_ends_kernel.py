"""The compiled refinements on the exact path (:mod:`synth.mechanism.dwell_ends_kernel`) against the numpy
stages they replace (:func:`synth.mechanism.output_range._refine_candidates` and ``_refine_window``, run
when ψ comes from a plain callable): the same dwell ends and deviation windows on random
six-bars and on six-bars with real dwells, and the rows of a repeated batch mapped to their
six-bars."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from test_sixbar import sixbar_strategy  # tests/synth: any six-bar

from synth.mechanism.output_range import dwell_intervals, output_deviation, output_swing
from synth.mechanism.sixbar import ExactOutput, OutputDyad, SixBar, SixBars, crank_grid, simulate

DEG = math.pi / 180


def _both(batch: SixBars, samples: int, band: float, count: int):
    """dwell_intervals refined by the compiled pass (ExactOutput) and by the numpy stages (the
    same evaluator behind a plain function), and which rows are acceptable six-bars: they
    assemble over the turn and the output rocks."""
    phi = crank_grid(samples)
    motion = simulate(batch, phi, order=2)
    exact = ExactOutput(batch)
    compiled = dwell_intervals(phi, motion.psi, band, count=count, psi_at=exact, dpsi1=motion.dpsi[0])
    numpy_ = dwell_intervals(phi, motion.psi, band, count=count, psi_at=lambda at: exact(at), dpsi1=motion.dpsi[0])
    _, turns = output_swing(phi, motion.psi, dpsi=motion.dpsi)
    return compiled, numpy_, np.all(motion.status == 0, axis=1) & (turns == 0)


def _assert_same(compiled, numpy_, rows) -> None:
    np.testing.assert_array_equal(compiled.found[rows], numpy_.found[rows])
    # the ends are crank angles the two forms pick by the same comparisons: equal; the band's
    # extremes are ψ values, which the batch evaluator rounds differently in the last bits
    np.testing.assert_array_equal(compiled.start[rows], numpy_.start[rows])
    np.testing.assert_array_equal(compiled.end[rows], numpy_.end[rows])
    np.testing.assert_allclose(compiled.low[rows], numpy_.low[rows], rtol=0, atol=1e-12)
    np.testing.assert_allclose(compiled.high[rows], numpy_.high[rows], rtol=0, atol=1e-12)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@example([SixBar(1.0, 2.0, 2.0, 2.0, 1, 0.0, 0.0, OutputDyad.rpr(0j))], 0.5, 72, 1)  # ψ = φ
@given(
    st.lists(sixbar_strategy(), min_size=1, max_size=4),
    st.floats(0.0, 0.5),
    st.sampled_from([72, 180, 720]),
    st.sampled_from([1, 2]),
)
def test_the_compiled_refinement_gives_the_numpy_dwells(sbs, band, samples, count):
    compiled, numpy_, acceptable = _both(SixBars.from_sixbars(sbs), samples, band, count)
    # A six-bar that does not assemble or whose output revolves is rejected whatever its
    # dwells: they are only kept finite. (A revolving output turning at an even rate, found by
    # hypothesis, has windows of equal length all round; the two forms' last-bit differences
    # break that tie at different places.)
    _assert_same(compiled, numpy_, acceptable)
    for x in (compiled.start, compiled.end, compiled.low, compiled.high):
        assert np.all(np.isfinite(x))


def _dwelling_sixbars() -> SixBars:
    """Crank-rocker six-bars with long rests: slot pivots far along the Ball point's tangent and
    rockers resting near a circle point's centre, on three four-bars."""
    out = []
    for a, b, c, d, br, u, v in [
        (1.0, 3.0, 3.0, 3.5, 1, 1.2, 0.8),
        (1.0, 2.5, 3.0, 3.0, -1, 2.0, -0.5),
        (1.0, 4.0, 2.5, 3.5, 1, 1.5, 1.0),
    ]:
        for k in range(6):
            out.append(SixBar(a, b, c, d, br, u, v, OutputDyad.rpr(complex(6.0 + k, -2.0 + 0.7 * k))))
            out.append(
                SixBar(
                    a,
                    b,
                    c,
                    d,
                    br,
                    u,
                    v,
                    OutputDyad.rrr(complex(2.0 + 0.3 * k, -3.0), 2.5 + 0.2 * k, 3.5, 1 if k % 2 else -1),
                )
            )
    return SixBars.from_sixbars(out)


def test_the_same_dwells_on_six_bars_that_rest():
    batch = _dwelling_sixbars()
    for band in (0.05 * DEG, 0.1 * DEG, 1.0 * DEG):
        for count in (1, 2):
            compiled, numpy_, acceptable = _both(batch, 720, band, count)
            assert acceptable.sum() >= 12
            assert np.median(compiled.angle[acceptable, 0]) > 10 * DEG  # real rests, not a sample or two
            _assert_same(compiled, numpy_, acceptable)


def test_rows_that_repeat_a_six_bar_are_refined_on_its_path():
    """ψ of shape (N, 2, M) — each six-bar's twice, as the figures' deviation windows ask — with
    the batch's evaluator: each row on its own six-bar's path, as the (N, M) call refines it."""
    batch = _dwelling_sixbars()
    phi = crank_grid(720)
    motion = simulate(batch, phi, order=2)
    exact = ExactOutput(batch)
    once = dwell_intervals(phi, motion.psi, 0.1 * DEG, psi_at=exact, dpsi1=motion.dpsi[0])
    twice = dwell_intervals(
        phi,
        np.repeat(motion.psi[:, None], 2, axis=1),
        0.1 * DEG,
        psi_at=exact,
        dpsi1=np.repeat(motion.dpsi[0][:, None], 2, axis=1),
    )
    for k in range(2):
        np.testing.assert_array_equal(twice.start[:, k], once.start)
        np.testing.assert_array_equal(twice.end[:, k], once.end)


def _deviations(batch: SixBars, samples: int, centre, length: float):
    """output_deviation refined by the compiled pass and by the numpy stages, ψ of shape
    (N, 2, M) as the figures give it (each six-bar's twice, one window per dwell)."""
    phi = crank_grid(samples)
    motion = simulate(batch, phi, order=2)
    exact = ExactOutput(batch)
    psi = np.repeat(motion.psi[:, None], 2, axis=1)
    d1 = np.repeat(motion.dpsi[0][:, None], 2, axis=1)
    compiled = output_deviation(phi, psi, centre, length, psi_at=exact, dpsi1=d1)
    numpy_ = output_deviation(phi, psi, centre, length, psi_at=lambda at: exact(at), dpsi1=d1)
    _, turns = output_swing(phi, motion.psi, dpsi=motion.dpsi)
    return compiled, numpy_, np.all(motion.status == 0, axis=1) & (turns == 0)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(sixbar_strategy(), min_size=1, max_size=4),
    st.sampled_from([72, 180, 720]),
    st.floats(0.0, 2 * math.pi),
    st.floats(0.0, 3.5),
)
def test_the_compiled_window_refinement_gives_the_numpy_deviation(sbs, samples, centre, extra):
    batch = SixBars.from_sixbars(sbs)
    length = 2 * (2 * math.pi / samples) + extra  # a dwell of two grid steps at least, as a request asks
    centres = centre + np.array([[0.0, 1.0]] * len(batch))
    (dev, start), (dev_np, start_np), acceptable = _deviations(batch, samples, centres, length)
    assert np.all(np.isfinite(dev)) and np.all(np.isfinite(start))
    np.testing.assert_array_equal(start[acceptable], start_np[acceptable])
    np.testing.assert_allclose(dev[acceptable], dev_np[acceptable], rtol=0, atol=1e-12)


def test_the_same_deviation_windows_around_real_rests():
    batch = _dwelling_sixbars()
    found = _both(batch, 720, 0.1 * DEG, 2)[0]
    for length in (10 * DEG, 30 * DEG, 60 * DEG):
        (dev, start), (dev_np, start_np), acceptable = _deviations(batch, 720, 0.5 * (found.start + found.end), length)
        assert np.median(dev[acceptable]) < 2 * DEG  # windows around rests, not across the swing
        np.testing.assert_array_equal(start[acceptable], start_np[acceptable])
        np.testing.assert_allclose(dev[acceptable], dev_np[acceptable], rtol=0, atol=1e-12)
