"""The compiled pair search of the dwell refinement (:mod:`synth.mechanism.pair_search`) against the
numpy expressions it replaced, kept here as the reference: the same pairs and figures, bit
for bit, on random and on tied point sets."""

from __future__ import annotations

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from synth.mechanism.pair_search import longest_pair


def _numpy_pair_search(left_at, lv, right_at, rv, hi_in, lo_in, band):
    """The pair search as numpy expressions over (queries, starts, ends)."""
    R = lv.shape[0]
    sl_max = np.maximum.accumulate(lv[..., ::-1], axis=-1)[..., ::-1]
    sl_min = np.minimum.accumulate(lv[..., ::-1], axis=-1)[..., ::-1]
    pr_max = np.maximum.accumulate(rv, axis=-1)
    pr_min = np.minimum.accumulate(rv, axis=-1)
    Hl = np.maximum(hi_in[..., None], sl_max)
    Ll = np.minimum(lo_in[..., None], sl_min)
    b = np.broadcast_to(band.reshape((R,) + (1,) * (hi_in.ndim - 1)), hi_in.shape)[..., None]
    ok_l = (Hl - Ll) <= b
    ok_r = (pr_max - pr_min) <= b
    nl, nr = lv.shape[-1], rv.shape[-1]
    jl = np.empty(hi_in.shape, np.int64)
    jr = np.empty(hi_in.shape, np.int64)
    share = np.empty(hi_in.shape)
    along = lambda x, j: np.take_along_axis(x, j[..., None], -1)[..., 0]
    # (jl, jr) pairs in row chunks, so that many candidates stay within memory.
    chunk = R
    for r0 in range(0, R, chunk):
        q = slice(r0, r0 + chunk)
        bq = b[q][..., None]
        top = np.maximum(Hl[q][..., :, None], pr_max[q][..., None, :])
        bottom = np.minimum(Ll[q][..., :, None], pr_min[q][..., None, :])
        feasible = ok_l[q][..., :, None] & ok_r[q][..., None, :] & ((top - bottom) <= bq)
        # for each start the feasible ends are a prefix (the range only grows): its last end,
        # and the share of the next step the band still holds, ψ linear there — the lengths of
        # pairs that the points alone would tie (a slowly drifting output gives many) differ
        cnt = feasible.sum(axis=-1)
        last = np.maximum(cnt - 1, 0)
        has_next = cnt < nr
        rq = np.broadcast_to(rv[q][..., None, :], feasible.shape)
        u = along(rq, last)
        v = along(rq, np.minimum(last + 1, nr - 1))
        up, down = along(bottom, last) + b[q], along(top, last) - b[q]
        with np.errstate(invalid="ignore", divide="ignore"):
            f = np.where(v > up, (up - u) / (v - u), np.where(v < down, (u - down) / (u - v), 0.0))
        f = np.where(has_next & np.isfinite(f), np.clip(f, 0.0, 1.0), 0.0)
        score = np.where(cnt > 0, last + f - np.arange(nl), -np.inf)
        jl[q] = np.argmax(score, axis=-1)
        jr[q] = along(last, jl[q])
        share[q] = along(f, jl[q])
    take = lambda x, jj: np.take_along_axis(x, jj[..., None], -1)[..., 0]
    start, end = take(left_at, jl), take(right_at, jr)
    high = np.maximum(take(Hl, jl), take(pr_max, jr))
    low = np.minimum(take(Ll, jl), take(pr_min, jr))
    # what lies strictly inside (start + one point, end − one point): a finer stage's interior
    inner_hi = np.maximum(
        np.maximum(hi_in, np.where(jl + 1 < nl, take(sl_max, np.minimum(jl + 1, nl - 1)), -np.inf)),
        np.where(jr >= 1, take(pr_max, np.maximum(jr - 1, 0)), -np.inf),
    )
    inner_lo = np.minimum(
        np.minimum(lo_in, np.where(jl + 1 < nl, take(sl_min, np.minimum(jl + 1, nl - 1)), np.inf)),
        np.where(jr >= 1, take(pr_min, np.maximum(jr - 1, 0)), np.inf),
    )
    reach = end + share * (right_at[..., 1] - right_at[..., 0])  # the end, ψ linear beyond the last point
    return start, end, low, high, inner_hi, inner_lo, reach


@settings(max_examples=80, deadline=None)
@given(
    lead=st.sampled_from([(1,), (3,), (2, 3), (4, 2, 2)]),
    nl=st.integers(2, 9),
    nr=st.integers(2, 12),
    quantum=st.sampled_from([0.0, 0.25]),
    drift=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
@example(lead=(2, 3), nl=2, nr=2, quantum=0.25, drift=False, seed=0)
@example(lead=(4, 2, 2), nl=9, nr=12, quantum=0.0, drift=True, seed=1)
def test_compiled_pair_search_is_the_numpy_one_bit_for_bit(lead, nl, nr, quantum, drift, seed):
    rng = np.random.default_rng(seed)
    R = lead[0]
    start = rng.uniform(0, 6, lead)
    left_at = start[..., None] + np.linspace(-0.01, 0.0, nl)
    right_at = start[..., None] + rng.uniform(0.5, 2.0, lead)[..., None] + np.linspace(0.0, 0.02, nr)
    # ψ near rest with a drift, some values tied (quantised); the band from tight to loose. A
    # slow linear drift (``drift``) ties many pairs by their points: the linear share decides
    lv = rng.normal(0, 1e-3, lead + (nl,)) + rng.uniform(-2e-3, 2e-3, lead)[..., None] * np.arange(nl)
    rv = rng.normal(0, 1e-3, lead + (nr,)) + rng.uniform(-2e-3, 2e-3, lead)[..., None] * np.arange(nr)
    if drift:  # one spacing for both point sets, as the refinement uses, and nothing between them
        right_at = right_at[..., :1] + np.linspace(0.0, 0.01 * (nr - 1) / (nl - 1), nr)
        slope = rng.uniform(0.5e-3, 3e-3, lead)[..., None]
        lv, rv = slope * (left_at - start[..., None]), slope * (right_at - start[..., None])
    if quantum:
        lv, rv = np.round(lv / (quantum * 1e-3)) * quantum * 1e-3, np.round(rv / (quantum * 1e-3)) * quantum * 1e-3
    hi_in = rng.uniform(0, 1e-3, lead) * (rng.random(lead) < 0.7) + np.where(rng.random(lead) < 0.2, -np.inf, 0.0)
    lo_in = np.where(np.isfinite(hi_in), hi_in - rng.uniform(0, 2e-3, lead), np.inf)
    band = rng.uniform(5e-4, 6e-3, R)
    if drift:
        hi_in, lo_in = np.full(lead, -np.inf), np.full(lead, np.inf)
        band = np.min((rv[..., -1] - lv[..., 0]).reshape(R, -1), axis=1) * rng.uniform(0.9, 1.0, R)
    got = longest_pair(left_at, lv, right_at, rv, hi_in, lo_in, band)
    want = _numpy_pair_search(left_at, lv, right_at, rv, hi_in, lo_in, band)
    for g, w in zip(got, want):
        assert g.shape == lead
        np.testing.assert_array_equal(g, w)
