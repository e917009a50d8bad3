"""The batched double-Ball-point search against a per-linkage one (an independent reference).

The references below search one linkage at a time with shapely's ``STRtree`` (the form the
batched search replaced), bisect one kind of event at a time and solve the plain four-bar
motion: the batched pieces must give the same crossing seeds (as sets: the batch orders them
by segment), the same merged samples and the same track, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from test_accuracy import crank_rockers

import synth.curvature.double_ball as module
from kinematics.fourbar import fourbar_motion
from synth.curvature.ball import ball_point_offset_rate
from synth.curvature.pole import loop_condition
from synth.types import MAX_CONDITION

TWO_PI = 2 * np.pi


def same(x, y) -> bool:
    x, y = np.asarray(x), np.asarray(y)
    if x.dtype != y.dtype or x.shape != y.shape or not np.array_equal(x, y):
        return False
    return np.array_equal(np.ascontiguousarray(x).view(np.uint8), np.ascontiguousarray(y).view(np.uint8))


# -- the per-linkage search ------------------------------------------------------------------


def reference_crossings(phi, p, t1, ok):
    """Self-crossings of one linkage's sampled track (φ sorted over one turn) as φ seeds."""
    n = phi.size
    nxt = np.roll(np.arange(n), -1)
    seg_ok = ok & ok[nxt] & (np.sign(t1) == np.sign(t1[nxt]))
    idx = np.flatnonzero(seg_ok)
    if idx.size < 2:
        return np.zeros(0), np.zeros(0)
    extent = np.abs(p[idx] - p[idx].mean()).max()
    idx = idx[np.abs(p[nxt[idx]] - p[idx]) > 1e-15 * extent]
    if idx.size < 2:
        return np.zeros(0), np.zeros(0)
    p0, p1 = p[idx], p[nxt[idx]]
    z = np.concatenate([p0, p1])
    z = z - z.mean()
    axis = np.exp(0.5j * np.angle(np.sum(z * z)))
    if np.abs((z * np.conj(axis)).imag).max() <= 1e-9 * np.abs(z).max():
        return np.zeros(0), np.zeros(0)
    coords = np.stack([np.c_[p0.real, p0.imag], np.c_[p1.real, p1.imag]], axis=1)
    segments = shapely.linestrings(coords)
    i, j = shapely.STRtree(segments).query(segments)
    keep = i < j
    i, j = i[keep], j[keep]
    si, sj = idx[i], idx[j]
    adjacent = (nxt[si] == sj) | (nxt[sj] == si)
    i, j = i[~adjacent], j[~adjacent]
    r, s = p1[i] - p0[i], p1[j] - p0[j]
    qp = p0[j] - p0[i]
    cross = lambda u, v: (np.conj(u) * v).imag  # noqa: E731
    den = cross(r, s)
    with np.errstate(divide="ignore", invalid="ignore"):
        ti = cross(qp, s) / den
        tj = cross(qp, r) / den
    hit = (den != 0) & (ti >= 0) & (ti <= 1) & (tj >= 0) & (tj <= 1)
    i, j, ti, tj = i[hit], j[hit], ti[hit], tj[hit]
    span = np.mod(phi[nxt] - phi, TWO_PI)
    return phi[idx[i]] + ti * span[idx[i]], phi[idx[j]] + tj * span[idx[j]]


def reference_all(phi, p, t1, ok, ext_link, ext_phi, ep, et1, eok):
    """Seeds (linkage, φ₁, φ₂) of a batch, one linkage at a time, as the per-linkage search."""
    links, s1s, s2s = [], [], []
    for k in range(p.shape[0]):
        sel = ext_link == k
        ph = np.concatenate([phi, ext_phi[sel]])
        order = np.argsort(ph, kind="stable")
        s1, s2 = reference_crossings(
            ph[order],
            np.concatenate([p[k], ep[sel]])[order],
            np.concatenate([t1[k], et1[sel]])[order],
            np.concatenate([ok[k], eok[sel]])[order],
        )
        links.append(np.full(s1.size, k))
        s1s.append(s1)
        s2s.append(s2)
    return np.concatenate(links).astype(np.int64), np.concatenate(s1s), np.concatenate(s2s)


def reference_event_samples(phi, values, usable, value_at, depth):
    nxt = np.roll(np.arange(phi.size), -1)
    change = usable & usable[:, nxt] & (values != values[:, nxt])
    link, k = np.nonzero(change)
    if link.size == 0:
        return np.zeros(0, np.int64), np.zeros(0)
    lo = phi[k]
    hi = np.where(k + 1 < phi.size, phi[np.minimum(k + 1, phi.size - 1)], TWO_PI)
    at_lo = values[link, k]
    for _ in range(48):
        mid = 0.5 * (lo + hi)
        same_side = value_at(link, mid) == at_lo
        lo, hi = np.where(same_side, mid, lo), np.where(same_side, hi, mid)
    step = (phi[1] - phi[0]) * 0.5 ** np.arange(1, depth + 1)
    offsets = np.concatenate([-step, step])
    ext = (0.5 * (lo + hi))[:, None] + offsets
    return np.repeat(link, offsets.size).astype(np.int64), np.mod(ext.ravel(), TWO_PI)


def reference_track(a, b, c, d, branch, phi):
    m = fourbar_motion(a, b, c, d, phi, branch, order=3)
    t1, t2, t3 = m.dtheta
    w, dw = ball_point_offset_rate(t1, t2, t3, module.theta4(m))
    rot = np.conj(m.e_theta) * m.A
    p = rot * w
    dp = rot * (1j * (1.0 - t1) * w + dw)
    ok = (m.status == 0) & (loop_condition(m) <= MAX_CONDITION) & np.isfinite(p) & np.isfinite(dp) & (t1 != 0)
    size = np.maximum(np.maximum(a, b), np.maximum(c, d))
    ok &= np.abs(dp) > module.STILL_SPEED * size
    return np.where(ok, p, 0j), np.where(ok, dp, 0j), t1, ok


# -- fixtures -----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def batch():
    """40 random crank-rockers, a double-rocker (its limited crank range gives edge events) and
    a rhombus (a track folded onto a line)."""
    rows = crank_rockers(40, 17)
    a, b, c, d, br = (
        np.r_[rows[:, k], extra] for k, extra in enumerate(([3.0, 1.0], [2.0, 1.0], [2.5, 1.0], [3.0, 1.0], [1.0, 1.0]))
    )
    return a, b, c, d, br


@pytest.fixture(scope="module")
def captured(batch):
    """What double_ball_points hands to the crossing search, and what it gets back."""
    got = {}
    rings, crossings = module._rings, module._crossings

    def grab_rings(*args):
        got["rings_args"] = args
        got["rings"] = rings(*args)
        return got["rings"]

    def grab_crossings(r):
        got["seeds"] = crossings(r)
        return got["seeds"]

    mp = pytest.MonkeyPatch()
    mp.setattr(module, "_rings", grab_rings)
    mp.setattr(module, "_crossings", grab_crossings)
    try:
        got["found"] = module.double_ball_points(*batch, samples=1024)
    finally:
        mp.undo()
    return got


# -- the pieces ----------------------------------------------------------------------------------


def as_set(seeds):
    """Seeds (linkage, φ₁, φ₂) in one canonical order, to compare as sets."""
    order = np.lexsort((seeds[2], seeds[1], seeds[0]))
    return [np.asarray(x)[order] for x in seeds]


def test_batched_seeds_equal_the_per_linkage_strtree_search(captured):
    reference = reference_all(*captured["rings_args"])
    assert reference[0].size > 100
    for mine, theirs in zip(as_set(captured["seeds"]), as_set(reference)):
        assert same(mine, theirs)


def test_merged_rings_are_each_linkages_stable_sort(captured):
    phi, p, t1, ok, ext_link, ext_phi, ep, et1, eok = captured["rings_args"]
    r = captured["rings"]
    for k in range(p.shape[0]):
        sel = ext_link == k
        ph = np.concatenate([phi, ext_phi[sel]])
        order = np.argsort(ph, kind="stable")
        ring = slice(r.start[k], r.start[k + 1])
        assert same(r.phi[ring], ph[order])
        assert same(r.p[ring], np.concatenate([p[k], ep[sel]])[order])
        assert same(r.ok[ring], np.concatenate([ok[k], eok[sel]])[order])


def test_joint_bisection_equals_one_kind_at_a_time(batch, captured):
    a, b, c, d, br = (np.asarray(x, float) for x in batch)
    phi = np.linspace(0.0, TWO_PI, 1024, endpoint=False)
    col = lambda x: x[:, None]  # noqa: E731
    _, _, t1, moving = reference_track(col(a), col(b), col(c), col(d), col(br), phi)
    g1 = fourbar_motion(col(a), col(b), col(c), col(d), phi, col(br), order=1).dgamma[0]

    def rate_sign(which):
        def at(link, angles):
            m = fourbar_motion(a[link], b[link], c[link], d[link], angles, br[link], order=1)
            return np.sign((m.dtheta, m.dgamma)[which][0])

        return at

    def usable_at(link, angles):
        return reference_track(a[link], b[link], c[link], d[link], br[link], angles)[3]

    parts = [
        reference_event_samples(phi, np.sign(t1), moving, rate_sign(0), 40),
        reference_event_samples(phi, np.sign(g1), moving, rate_sign(1), 24),
        reference_event_samples(phi, moving, np.ones_like(moving), usable_at, 24),
    ]
    assert all(part[0].size for part in parts), "every kind of event occurs in the batch"
    ext_link, ext_phi = (np.concatenate(x) for x in zip(*parts))
    assert same(captured["rings_args"][4], ext_link)
    assert same(captured["rings_args"][5], ext_phi)


@pytest.mark.parametrize("shape", ["grid", 40, 20000])
def test_track_with_the_kept_motion_arrays_has_the_plain_bits(batch, shape):
    """Above 16384 elements numpy computes some products in place, which rounds differently:
    both sizes, and the (linkages × angles) grid, must give the plain motion's bits."""
    a, b, c, d, br = (np.asarray(x, float) for x in batch)
    if shape == "grid":
        phi = np.linspace(0, TWO_PI, 1024, endpoint=False)
        args = (a[:, None], b[:, None], c[:, None], d[:, None], br[:, None], phi)
    else:
        rng = np.random.default_rng(shape)
        k = rng.integers(0, a.size, shape)
        args = (a[k], b[k], c[k], d[k], br[k], rng.uniform(0, TWO_PI, shape))
    for mine, theirs in zip(module._track(*args), reference_track(*args)):
        assert same(mine, theirs)


# -- synthetic tracks: the corner cases of the crossing search -----------------------------------


def synthetic_rings(tracks, t1=None):
    """Rings of polylines ``tracks`` (linkages × samples, complex), all samples usable."""
    p = np.asarray(tracks, complex)
    n_link, m = p.shape
    phi = np.linspace(0.0, TWO_PI, m, endpoint=False)
    t1 = np.ones(p.shape) if t1 is None else t1
    empty = np.zeros(0)
    args = (
        phi,
        p,
        t1,
        np.ones(p.shape, bool),
        np.zeros(0, np.int64),
        empty,
        empty.astype(complex),
        empty,
        np.zeros(0, bool),
    )
    return module._rings(*args), args


def lattice_walk(rng, m):
    """A closed walk on an integer lattice: crossings at vertices, overlapping collinear
    stretches, repeated points and touching boxes."""
    walk = np.cumsum(rng.choice(np.array([1, -1, 1j, -1j, 1 + 1j, 0]), m))
    return walk.real % 7 + 1j * (walk.imag % 5)


def test_synthetic_tracks_cross_like_the_strtree_search():
    rng = np.random.default_rng(5)
    m = 160
    tracks = [
        rng.uniform(-1, 1, m) + 1j * rng.uniform(-1, 1, m),  # a scribble: many partners per segment
        lattice_walk(rng, m),
        lattice_walk(rng, m) * (0.3 + 0.1j),
        np.exp(1j * np.linspace(0, 6 * np.pi, m, endpoint=False)) * np.linspace(1, 2, m),  # a spiral
    ]
    t1 = np.ones((len(tracks), m))
    t1[0, 40:60] = -1  # θ′ changes sign: the segments across the change are not searched
    r, args = synthetic_rings(tracks, t1)
    mine = module._crossings(r)
    theirs = reference_all(*args)
    for x, y in zip(as_set(mine), as_set(theirs)):
        assert same(x, y)
    # the corner cases occur: several partners of one segment
    link = mine[0]
    assert np.bincount(link, minlength=len(tracks))[0] > 1000


def test_box_pairs_are_the_strtree_pairs():
    rng = np.random.default_rng(11)
    m = 300
    p = lattice_walk(rng, m)  # many boxes that only touch
    r, _ = synthetic_rings([p])
    seg = np.arange(m)
    i, j = module._box_pairs(r.p[seg], r.p[r.nxt[seg]], seg, r.nxt[seg], r.link[seg])
    p0, p1 = r.p[seg], r.p[r.nxt[seg]]
    lines = shapely.linestrings(np.stack([np.c_[p0.real, p0.imag], np.c_[p1.real, p1.imag]], axis=1))
    ti, tj = shapely.STRtree(lines).query(lines)
    keep = (ti < tj) & (r.nxt[ti] != tj) & (r.nxt[tj] != ti)
    assert sorted(zip(i.tolist(), j.tolist())) == sorted(zip(ti[keep].tolist(), tj[keep].tolist()))


def test_degenerate_tracks_give_no_seeds_and_the_others_the_references():
    """Still and flat tracks cross nothing; a track only partly still, or 1e-7 off a line, or
    with segments of zero length is searched as the reference searches it."""
    rng = np.random.default_rng(2)
    m = 200
    line = np.linspace(-1, 1, m) * (0.6 + 0.8j) + (0.2 - 0.1j)
    loop = np.exp(1j * np.linspace(0, 3 * TWO_PI, m, endpoint=False)) * np.linspace(1, 1.5, m)
    still = np.full(m, 0.3 + 0.4j) + 1e-17 * rng.standard_normal(m)
    tracks = [
        line,  # flat
        line + 1e-11 * 1j * (0.6 + 0.8j) * rng.standard_normal(m),  # flat within rounding
        still,  # still: no segment kept
        line + 1e-7 * 1j * (0.6 + 0.8j) * rng.standard_normal(m),  # not flat
        np.where(np.arange(m) < 150, still, loop),  # partly still
        np.r_[loop[:100], np.repeat(loop[100], 100)],  # zero-length segments
        loop,
    ]
    r, args = synthetic_rings(tracks)
    mine, theirs = as_set(module._crossings(r)), as_set(reference_all(*args))
    for x, y in zip(mine, theirs):
        assert same(x, y)
    assert not np.isin([0, 1, 2], mine[0]).any()
    assert np.isin([3, 6], mine[0]).all()
