"""Dwell segments: every stored interval re-measured on the exact path, independently.

The independent checks march along the exact coupler path in 0.05° steps from the middle of a
stored interval until it leaves the stored band, then bisect 40 times — no code shared with
``synth.segment_search.segments`` except the four-bar position itself. The minimum-zone claim is checked
against an exact linear program (scipy.optimize.linprog) over the stored interval.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import linprog

from atlas.sweep import PRESETS, sweep_linkages
from kinematics.fourbar import fourbar_motion
from synth import ball_point, pole
from synth.kinds import SEGMENT_KINDS, SegmentKind
from synth.segment_search.segments import SegmentSearch, find_segments

SPEC = PRESETS["demo"]
N = 6


@pytest.fixture(scope="module")
def batch():
    sw = sweep_linkages(SPEC)
    b, c, d = (np.repeat(x[:N], 2) for x in (sw.b, sw.c, sw.d))
    br = np.tile([1, -1], N)
    return b, c, d, br, find_segments(b, c, d, br, SegmentSearch.from_spec(SPEC))


def _geometry(found, i, level, part):
    return found.fit_point[i, level, part], found.fit_direction[i, level, part], found.fit_radius[i, level, part]


def _distance(z, is_arc, geometry):
    point, direction, radius = geometry
    if is_arc:
        return abs(z - point) - radius
    return ((z - point) * np.conj(direction)).imag


def _path(b, c, d, br, uv, phi):
    m = fourbar_motion(1.0, b, c, d, np.atleast_1d(phi), br, order=0)
    return m.A + m.e_theta * uv


def _dwells(found):
    for i in range(len(found)):
        for level in range(len(found.tolerances)):
            for part in range(2 if SEGMENT_KINDS[found.kind[i]] is SegmentKind.DOUBLE_LINE else 1):
                if found.has_dwell[i, level, part]:
                    yield i, level, part


def test_batch_finds_every_kind_and_no_nan(batch):
    *_, found = batch
    assert len(found) > 50
    assert set(np.unique(found.kind)) == {0, 1, 2}
    for name in ("phi_start", "phi_end", "fit_radius", "radius", "excursion"):
        assert np.all(np.isfinite(getattr(found, name)))
    for name in ("uv", "fit_point", "fit_direction", "center", "intersection"):
        assert np.all(np.isfinite(getattr(found, name)))
    assert found.skipped  # pruning and merging are counted, by reason
    assert all(v > 0 for v in found.skipped.values())


def test_interval_ends_match_an_independent_bisection(batch):
    b, c, d, br, found = batch
    worst = 0.0
    checked = 0
    for i, level, part in _dwells(found):
        k = found.linkage[i]
        eps = found.tolerances[level]
        geometry = _geometry(found, i, level, part)
        is_arc = SEGMENT_KINDS[found.kind[i]] is SegmentKind.ARC
        start, end = found.phi_start[i, level, part], found.phi_end[i, level, part]

        def outside(phi, k=k, i=i, geometry=geometry, is_arc=is_arc, eps=eps):
            return np.abs(_distance(_path(b[k], c[k], d[k], br[k], found.uv[i], phi), is_arc, geometry)) > eps

        mid = 0.5 * (start + end)
        for sign, stored in ((-1, start), (1, end)):
            phis = mid + sign * np.radians(np.arange(0.0, 200.0, 0.05))
            j = int(np.argmax(outside(phis)))
            assert j > 0
            inside_phi, out_phi = phis[j - 1], phis[j]
            for _ in range(40):
                m = 0.5 * (inside_phi + out_phi)
                if outside(m)[0]:
                    out_phi = m
                else:
                    inside_phi = m
            worst = max(worst, math.degrees(abs(inside_phi - stored)))
        checked += 1
        # the generating angle lies inside its interval; the band holds on the whole interval
        gen = found.phi_gen[i] if part == 0 else found.phi_gen2[i]
        assert (gen - start) % (2 * np.pi) <= end - start + 1e-12
        dense = np.linspace(start, end, 4001)
        assert not outside(dense).any()
    assert checked > 100
    assert worst < 0.01


def test_fitted_band_is_close_to_the_minimum_zone(batch):
    """Over each stored interval the best possible band (exact LP, linearised about the
    stored geometry) is not much narrower than the stored tolerance: the interval could not
    be stretched much further with any line or circle."""
    b, c, d, br, found = batch
    ratios = []
    for i, level, part in list(_dwells(found))[::3]:
        k = found.linkage[i]
        point, direction, radius = _geometry(found, i, level, part)
        phis = np.linspace(found.phi_start[i, level, part], found.phi_end[i, level, part], 300)
        z = _path(b[k], c[k], d[k], br[k], found.uv[i], phis)
        if SEGMENT_KINDS[found.kind[i]] is SegmentKind.ARC:
            rel = z - point
            unit = rel / abs(rel)
            design, r = np.c_[unit.real, unit.imag, np.ones(z.size)], abs(rel) - radius
        else:
            rel = (z - point) * np.conj(direction)
            design, r = np.c_[np.ones(z.size), rel.real], rel.imag
        p = design.shape[1]
        ones = np.ones((z.size, 1))
        res = linprog(
            np.r_[np.zeros(p), 1.0],
            A_ub=np.r_[np.c_[-design, -ones], np.c_[design, -ones]],
            b_ub=np.r_[-r, r],
            bounds=[(None, None)] * p + [(0, None)],
        )
        assert res.status == 0
        ratios.append(res.x[-1] / found.tolerances[level])
    ratios = np.array(ratios)
    assert ratios.max() <= 1 + 1e-6  # the stored geometry itself is feasible
    assert np.median(ratios) > 0.85
    assert ratios.min() > 0.3


def test_osculating_geometry_is_the_curvature_theorys(batch):
    """Ball-point segments: the stored line is Ball's point and its path tangent at the
    generating angle; arcs: the stored circle is the path's circle of curvature there."""
    b, c, d, br, found = batch
    for i in np.flatnonzero(found.kind == 0)[:20]:
        k = found.linkage[i]
        m = fourbar_motion(1.0, b[k], c[k], d[k], found.phi_gen[i], br[k], order=3)
        bp = ball_point(pole(m))
        assert abs(bp.uv - found.uv[i]) < 1e-12 * max(1.0, abs(found.uv[i]))
        assert abs(bp.point - found.point[i]) < 1e-12 * max(1.0, abs(found.point[i]))
    for i in np.flatnonzero(found.kind == 1)[:40]:
        k = found.linkage[i]
        m = fourbar_motion(1.0, b[k], c[k], d[k], found.phi_gen[i], br[k], order=2)
        z, z1, z2 = m.coupler_point(found.uv[i].real, found.uv[i].imag, order=2)
        cross = (np.conj(z1) * z2).imag
        centre = z + 1j * z1 * abs(z1) ** 2 / cross
        scale = max(1.0, found.radius[i])
        assert abs(centre - found.center[i]) < 1e-8 * scale
        assert abs(abs(z - centre) - found.radius[i]) < 1e-8 * scale


def test_minimum_zone_dwell_beats_the_osculating_one(batch):
    """The fitted geometry gives at least the dwell of the osculating one, and longer on
    average (for a Δφ⁴ stretch the minimum zone is ~8^¼ ≈ 1.7× longer)."""
    b, c, d, br, found = batch
    gains = []
    for i in np.flatnonzero(found.kind == 1)[::4]:
        k = found.linkage[i]
        level = 1
        if not found.has_dwell[i, level, 0]:
            continue
        eps = found.tolerances[level]
        phis = found.phi_gen[i] + np.radians(np.arange(-180.0, 180.0, 0.05))
        z = _path(b[k], c[k], d[k], br[k], found.uv[i], phis)
        inside = np.abs(abs(z - found.center[i]) - found.radius[i]) <= eps
        centre = phis.size // 2
        left = np.argmin(inside[centre::-1]) if not inside[centre::-1].all() else centre
        right = np.argmin(inside[centre:]) if not inside[centre:].all() else phis.size - centre
        osculating = math.radians(0.05) * (left + right - 1)
        stored = found.phi_end[i, level, 0] - found.phi_start[i, level, 0]
        gains.append(stored / osculating)
    gains = np.array(gains)
    assert gains.size > 10
    assert gains.min() > 0.99
    assert np.median(gains) > 1.2


def test_double_ball_point_stores_both_stretches_and_their_intersection(batch):
    *_, found = batch
    idx = np.flatnonzero(found.kind == 2)
    assert idx.size > 0
    for i in idx:
        p = found.intersection[i]
        for point, direction in ((found.point[i], found.direction[i]), (found.point2[i], found.direction2[i])):
            assert abs(((p - point) * np.conj(direction)).imag) < 1e-9 * max(1.0, abs(p))
        assert found.has_dwell[i, -1].all()
        assert found.phi_gen2[i] > found.phi_gen[i]


def test_excursion_is_the_paths_farthest_distance_from_the_circle(batch):
    """The arc's excursion (what the dwell key scales by) against a 0.05° march over the whole
    turn, which holds the search's fine grid: never above it, and short of it by at most the
    grid's sampling (≤ 1 %; 0.15 % at worst over the 513 arc rows here); zero for lines."""
    b, c, d, br, found = batch
    phi = np.arange(7200) * (2 * np.pi / 7200)
    worst, arcs = 0.0, 0
    for i in range(len(found)):
        arc = SEGMENT_KINDS[found.kind[i]] is SegmentKind.ARC
        for level in range(len(found.tolerances)):
            if not (arc and found.has_dwell[i, level, 0]):
                assert found.excursion[i, level] == 0.0
                continue
            lk = found.linkage[i]
            z = _path(b[lk], c[lk], d[lk], br[lk], found.uv[i], phi)
            dense = np.abs(_distance(z, True, _geometry(found, i, level, 0))).max()
            assert found.excursion[i, level] <= dense * (1 + 1e-12)
            worst = max(worst, 1 - found.excursion[i, level] / dense)
            arcs += 1
    assert arcs > 100 and worst < 0.01


def test_same_input_same_output(batch):
    b, c, d, br, found = batch
    again = find_segments(b[:4], c[:4], d[:4], br[:4], SegmentSearch.from_spec(SPEC))
    mine = found.linkage < 4
    np.testing.assert_array_equal(again.uv, found.uv[mine])
    np.testing.assert_array_equal(again.phi_start, found.phi_start[mine])
    np.testing.assert_array_equal(again.fit_point, found.fit_point[mine])


def test_no_linkages_no_segments():
    found = find_segments(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, int), SegmentSearch())
    assert len(found) == 0  # and no rows from it: tests/db/test_rows.py::test_no_segments_no_rows


def test_one_straight_stretch_seen_twice_is_no_double_line():
    """A standard-sweep linkage whose Ball-point track crosses itself on one straight stretch: two
    osculating lines 0° apart met "somewhere" by rounding. They are one stretch, not a double
    Ball point (the loop kernel's 1e-9 parallel test let 64 of them into the standard atlas)."""
    from atlas.sweep import PRESETS
    from synth.segment_search.segments import DOUBLE_LINE_MIN_SIN

    search = SegmentSearch.from_spec(PRESETS["standard"])
    found = find_segments(
        np.array([4.490699319525161]),
        np.array([3.1460127548771815]),
        np.array([4.6768594773215915]),
        np.array([1]),
        search,
    )
    double = found.kind == SegmentKind.DOUBLE_LINE.code
    sines = np.abs(np.imag(np.conj(found.direction[double]) * found.direction2[double]))
    assert double.sum() == 6 and np.all(sines >= DOUBLE_LINE_MIN_SIN)
