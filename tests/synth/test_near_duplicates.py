"""Near-duplicate segments (synth.segment_search.near_duplicates) against the pairwise definition spelled out.

The reference builds the whole duplicate matrix of a group (coupler points within the reach,
intervals — a turn apart too — overlapping by more than half the shorter) and keeps greedily,
longest first; the compiled loop must drop exactly the same segments."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from synth.segment_search.near_duplicates import duplicates


def _reference(uv, start, end, dwell, bounds, reach):
    dead = np.zeros(uv.size, bool)
    for g0, g1 in zip(bounds[:-1], bounds[1:]):
        s, e, w, p = start[g0:g1], end[g0:g1], dwell[g0:g1], uv[g0:g1]
        lo, hi = np.maximum(s[:, None], s[None, :]), np.minimum(e[:, None], e[None, :])
        for shift in (-2 * math.pi, 2 * math.pi):
            lo2, hi2 = np.maximum(s[:, None], s[None, :] + shift), np.minimum(e[:, None], e[None, :] + shift)
            better = (hi2 - lo2) > (hi - lo)
            lo, hi = np.where(better, lo2, lo), np.where(better, hi2, hi)
        dup = (np.abs(p[:, None] - p[None, :]) < reach) & ((hi - lo) > 0.5 * np.minimum(w[:, None], w[None, :]))
        gone = np.zeros(g1 - g0, bool)
        for i in range(g1 - g0):
            if not gone[i]:
                gone[i + 1 :] |= dup[i, i + 1 :]
        dead[g0:g1] = gone
    return dead


@settings(max_examples=80, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.integers(0, 3), st.floats(0, 0.02), st.floats(0, 0.02), st.floats(0, 2 * math.pi), st.floats(0.05, 4.0)
        ),
        min_size=1,
        max_size=30,
    )
)
@example([(0, 0.0, 0.0, 6.2, 0.5), (0, 0.001, 0.0, 0.1, 0.4)])  # the same stretch a turn apart
def test_compiled_loop_drops_what_the_pairwise_definition_drops(segments):
    segments.sort(key=lambda s: (s[0], -s[4]))  # grouped, longest first
    group = np.array([s[0] for s in segments])
    uv = np.array([complex(s[1], s[2]) for s in segments])
    start = np.array([s[3] for s in segments])
    dwell = np.array([s[4] for s in segments])
    end = start + dwell
    bounds = np.r_[0, np.flatnonzero(np.diff(group)) + 1, group.size]
    got = duplicates(uv, start, end, dwell, bounds, 0.01)
    assert np.array_equal(got, _reference(uv, start, end, dwell, bounds, 0.01))
    if segments == [(0, 0.0, 0.0, 6.2, 0.5), (0, 0.001, 0.0, 0.1, 0.4)]:
        assert got.tolist() == [False, True]
