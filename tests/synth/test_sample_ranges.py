"""The compiled range extremes (:mod:`synth.mechanism.sample_ranges`) against numpy's max and min of
each range read on its own: the same floats, ranges off the samples ±inf, any query shape."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from synth.mechanism.sample_ranges import range_extremes, sliding_extremes


def _reference(upper, lower, start, count):
    hi, lo = np.empty(start.shape), np.empty(start.shape)
    for index in np.ndindex(start.shape):
        s, n = int(start[index]), int(count[index])
        inside = 0 <= s and n >= 1 and s + n <= upper.shape[1]
        hi[index] = upper[index[0], s : s + n].max() if inside else math.inf
        lo[index] = lower[index[0], s : s + n].min() if inside else -math.inf
    return hi, lo


@settings(max_examples=60, deadline=None)
@given(rows=st.integers(1, 5), samples=st.integers(1, 40), queries=st.integers(1, 6), seed=st.integers(0, 2**32 - 1))
def test_range_extremes_are_the_ranges_own_max_and_min(rows, samples, queries, seed):
    rng = np.random.default_rng(seed)
    upper = rng.normal(size=(rows, samples))
    lower = upper - rng.uniform(0, 1, (rows, samples)) * (rng.random((rows, samples)) < 0.3)
    start = rng.integers(-2, samples + 2, (rows, queries, 2))
    count = rng.integers(-1, samples + 3, (rows, queries, 2))
    got = range_extremes(upper, lower, start, count)
    want = _reference(upper, lower, start, count)
    for g, w in zip(got, want):
        assert g.shape == start.shape
        np.testing.assert_array_equal(g, w)
    inside = (start >= 0) & (count >= 1) & (start + count <= samples)
    assert np.all(got[0][inside] >= got[1][inside])  # a range's max is never below its min


@settings(max_examples=80, deadline=None)
@given(
    rows=st.integers(1, 4),
    samples=st.integers(1, 60),
    first=st.integers(-2, 10),
    count=st.integers(0, 50),
    seed=st.integers(0, 2**32 - 1),
    ties=st.booleans(),
)
def test_sliding_extremes_are_each_windows_own_max_and_min(rows, samples, first, count, seed, ties):
    rng = np.random.default_rng(seed)
    values = rng.normal(size=(rows, samples))
    if ties:  # plateaus: equal values leave and enter the queues
        values = np.round(values)
    width = rng.integers(-1, samples + 3, rows)
    got = sliding_extremes(values, first, count, width)
    start = np.broadcast_to(first + np.arange(count)[None, :], (rows, count))
    want = _reference(values, values, start, np.broadcast_to(width[:, None], (rows, count)))
    for g, w in zip(got, want):
        assert g.shape == (rows, count)
        np.testing.assert_array_equal(g, w)


def test_range_extremes_broadcast_and_refuse_a_foreign_first_axis():
    upper = np.arange(12.0).reshape(2, 6)
    hi, lo = range_extremes(upper, upper, np.array([[0], [2]]), 3)
    np.testing.assert_array_equal(hi, [[2.0], [10.0]])
    np.testing.assert_array_equal(lo, [[0.0], [8.0]])
    with pytest.raises(ValueError, match="first axis"):
        range_extremes(upper, upper, np.zeros((3, 1), int), 1)


def _numpy_vertex_bounds(E):
    """The vertex bounds as the numpy expressions they replaced (the reference)."""
    from kinematics.loop import parabola_vertex

    ym, y0, yp = E[:, :-2], E[:, 1:-1], E[:, 2:]
    vertex = parabola_vertex(ym, y0, yp)
    den = vertex.curvature
    lift = np.abs(vertex.rise)
    peak = (den < 0) & (y0 >= ym) & (y0 >= yp)
    dip = (den > 0) & (y0 <= ym) & (y0 <= yp)
    upper, lower = E.copy(), E.copy()
    upper[:, 1:-1] += np.where(peak, np.minimum(lift, np.abs(den)), 0.0)
    lower[:, 1:-1] -= np.where(dip, np.minimum(lift, np.abs(den)), 0.0)
    return upper, lower


@settings(max_examples=40, deadline=None)
@given(rows=st.integers(1, 4), samples=st.integers(3, 60), seed=st.integers(0, 2**32 - 1))
def test_vertex_bounds_are_the_numpy_expressions_bit_for_bit(rows, samples, seed):
    from synth.mechanism.sample_ranges import vertex_bounds

    rng = np.random.default_rng(seed)
    t = np.linspace(0, 4 * np.pi, samples)
    # smooth rows with peaks between samples, flat and tied stretches, signed zeros
    E = np.sin(t * rng.uniform(0.5, 3, (rows, 1)) + rng.uniform(0, 6, (rows, 1))) * rng.uniform(0, 2, (rows, 1))
    E[:, rng.random(samples) < 0.2] = rng.choice([0.0, -0.0, 0.5])
    upper, lower = vertex_bounds(E)
    want_upper, want_lower = _numpy_vertex_bounds(E)
    for got, want in ((upper, want_upper), (lower, want_lower)):
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(np.signbit(got), np.signbit(want))
    assert np.all(upper >= E) and np.all(lower <= E)
