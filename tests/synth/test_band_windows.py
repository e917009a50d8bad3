"""The compiled longest-window pass (``synth.mechanism.band_windows``) against an exhaustive search: for
every start, every window length, the spread taken directly — the same lengths and the same
extremes, bit for bit (max and min round nothing), on random walks, on plateaus of equal
values (ties in the queues), on any samples hypothesis draws, and on the output angles of
real six-bars with their parabola-vertex envelopes."""

from __future__ import annotations

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from synth.mechanism.band_windows import longest_windows
from synth.mechanism.sample_ranges import vertex_bounds


def exhaustive(upper, lower, band, m):
    """Per start s < m: the longest n ≤ m with max(upper[s:s+n]) − min(upper[s], lower[s+1:s+n])
    ≤ band (n = 1 always counts), and that window's two extremes."""
    R, T = upper.shape
    length = np.zeros((R, m), np.int64)
    hi = np.zeros((R, m))
    lo = np.zeros((R, m))
    for r in range(R):
        for s in range(m):
            best = 1
            for n in range(1, min(m, T - s) + 1):
                top = upper[r, s : s + n].max()
                bottom = min(upper[r, s], lower[r, s + 1 : s + n].min()) if n > 1 else upper[r, s]
                if top - bottom <= band[r]:
                    best = n
            length[r, s] = best
            hi[r, s] = upper[r, s : s + best].max()
            lo[r, s] = min(upper[r, s], lower[r, s + 1 : s + best].min()) if best > 1 else upper[r, s]
    return length, hi, lo


def check(upper, lower, band, m):
    got = longest_windows(upper, lower, band, m)
    want = exhaustive(upper, lower, band, m)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)
    return got


def test_random_walks_and_plateaus():
    rng = np.random.default_rng(3)
    for trial in range(60):
        R, m = int(rng.integers(1, 4)), int(rng.integers(2, 40))
        E = np.cumsum(rng.normal(size=(R, 2 * m)), axis=1)
        if trial % 2:
            E = np.round(E)  # plateaus: equal values in the queues
        upper, lower = vertex_bounds(E)
        length, _, _ = check(upper, lower, rng.uniform(0, 4, R), m)
        assert length.min() >= 1 and length.max() <= m


def test_whole_turn_and_zero_band():
    m = 12
    flat = np.zeros((1, 2 * m))
    length, hi, lo = check(flat, flat, np.array([0.0]), m)
    assert np.all(length == m) and np.all(hi == 0) and np.all(lo == 0)
    ramp = np.arange(2.0 * m)[None, :]
    length, _, _ = check(ramp, ramp, np.array([0.0]), m)
    assert np.all(length == 1)  # a strictly rising output: no two samples share a band of 0


def test_six_bar_outputs():
    """The outputs of six-bars with one and with two dwells (RPR and RRR)."""
    from harness.report_cases import double_dwell_candidates, single_dwell_candidates

    from synth.mechanism.sixbar import SixBars, crank_grid, simulate

    sixbars = SixBars.from_sixbars([c.sixbar for c in single_dwell_candidates() + double_dwell_candidates()])
    psi = simulate(sixbars, crank_grid(72), order=0).psi
    E = np.concatenate([psi, psi], axis=1)
    upper, lower = vertex_bounds(E)
    for band in (1e-3, 1e-2, 0.1, 1.0):
        check(upper, lower, np.full(len(psi), band), 72)


samples = hnp.arrays(
    np.float64,
    st.tuples(st.integers(1, 3), st.integers(4, 30)),
    elements=st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False),
)


@settings(max_examples=200, deadline=None)
@given(samples, st.floats(0.0, 50.0), st.data())
@example(np.zeros((1, 4)), 0.0, None)
def test_any_samples(E, band, data):
    R, T = E.shape
    m = T // 2 if data is None else data.draw(st.integers(1, (T + 1) // 2))
    upper, lower = vertex_bounds(E)
    check(upper, lower, np.full(R, band), m)
