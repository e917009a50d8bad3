"""The dwell and swing bounds of synth.segment_search.dwell_bounds are necessary: no real six-bar beats them.

Six-bars are built as the query builds them (segments of real linkages from
``synth.segment_search.segments.find_segments``, output dyads from ``synth.mechanism.dyad``) and simulated exactly
(``synth.mechanism.figures.sixbar_figures``); the bound uses the six-bar's own link ratio as the limit
(the tightest limit it meets; the coupler plate's sides counted, synth.mechanism.link_ratio) and the
shortest link its segment fixes (the plate's included), so a violation would be a six-bar the
query could wrongly prune.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from synth.mechanism.dyad import fit_rpr, fit_rrr
from synth.mechanism.figures import sixbar_figures
from synth.mechanism.link_ratio import segment_shortest
from synth.mechanism.sixbar import SixBar, crank_grid
from synth.segment_search.dwell_bounds import (
    STAIRCASE_SLACK,
    curve_extent,
    deviation_profile,
    deviation_profiles,
    dwell_bound,
    minimum_zone_halfwidth,
    path_tolerance,
    rpr_min_swing,
    rrr_min_swing,
)
from synth.segment_search.segments import SegmentSearch, find_segments

#: Grid of the profile in these tests (coarser than the default: the suite stays fast).
STEP = math.radians(2.0)
SEARCH = SegmentSearch(rays=12)


def _contains(dwell, phi: float) -> bool:
    return any(dwell.start - 1e-9 <= phi + k * 2 * math.pi <= dwell.end + 1e-9 for k in (-1, 0, 1))


def sixbar_cases(b: float, c: float, d: float, branch: int, swing: float, band: float, per_kind: int = 2):
    """(kind, figures, bound, swing bound, ratio of the dwell to its bound) for up to
    ``per_kind`` segments of each kind of one linkage with dyads fitted for ``swing``."""
    found = find_segments(np.array([b]), np.array([c]), np.array([d]), np.array([branch]), SEARCH)
    phi = crank_grid(360)
    out = []
    width, diameter = curve_extent(b, c, d, branch, found.uv) if len(found) else (np.zeros(0), np.zeros(0))
    for kind in (0, 1):
        rows = np.flatnonzero(found.kind == kind)[:per_kind]
        for i in rows:
            uv = complex(found.uv[i])
            has = np.flatnonzero(found.has_dwell[i, :, 0])
            if not has.size:
                continue
            level = int(has[-1])
            from kinematics.fourbar import fourbar_motion

            motion = fourbar_motion(1.0, b, c, d, phi, branch, order=0)
            path = motion.A + motion.e_theta * uv
            interval = (found.phi_start[i, level, 0], found.phi_end[i, level, 0])
            p = found.fit_point[i, level, 0]
            if kind == 0:
                fit = fit_rpr(p, float(np.angle(found.fit_direction[i, level, 0])), phi, path, interval, swing)
                dyads = fit.dyads()
            else:
                fit = fit_rrr(p, found.fit_radius[i, level, 0], phi, path, interval, swing, math.radians(20), keep=2)
                dyads = fit.dyads()
            if not dyads:
                continue
            profile = deviation_profile(b, c, d, branch, uv, float(found.phi_gen[i]), kind, step=STEP)
            # the shortest link the segment fixes, the coupler plate's sides included: every
            # link of a six-bar within a ratio is at most the ratio times it
            shortest = float(segment_shortest(1.0, b, c, d, uv.real, uv.imag))
            assert shortest <= min(1.0, b, c, d)
            for dyad in dyads:
                sb = SixBar(1.0, b, c, d, branch, uv.real, uv.imag, dyad)
                f = sixbar_figures(sb, band=band, footprint=False)
                if f.turns != 0 or f.status != 0 or not f.dwells:
                    continue
                name = "rpr" if kind == 0 else "rrr"
                eps = path_tolerance(name, band, f.link_ratio, shortest)
                bound = float(dwell_bound(profile.levels, profile.length, eps))
                if kind == 0:
                    smin = float(rpr_min_swing(width[i], f.link_ratio, shortest))
                else:
                    smin = float(rrr_min_swing(diameter[i], dyad.rod, f.link_ratio, shortest))
                # the same lemma with the dyad's own link (reach / rocker) instead of the ratio's
                # limit: how tight the lemma itself is
                own = float(np.abs(path - dyad.pivot).max()) if kind == 0 else dyad.rocker
                tight = float(dwell_bound(profile.levels, profile.length, path_tolerance(name, band, own, 1.0)))
                contains = _contains(f.dwells[0], float(found.phi_gen[i]))
                out.append((name, f, bound if contains else None, smin, tight if contains else None))
    return out


def grashof_crank(b: float, c: float, d: float) -> bool:
    """The crank (1, the shortest link here) turns fully: Grashof, s + l ≤ p + q."""
    longest = max(b, c, d)
    return 1 + longest <= b + c + d - longest


def _check(cases) -> None:
    for name, f, bound, smin, tight in cases:
        if bound is not None:
            assert f.dwells[0].angle <= tight + 1e-9, (name, math.degrees(f.dwells[0].angle), math.degrees(tight))
            assert tight <= bound + 1e-12
        assert f.swing >= smin - 1e-9, (name, math.degrees(f.swing), math.degrees(smin))


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    b=st.floats(2.0, 4.0),
    c=st.floats(2.0, 4.0),
    d=st.floats(2.0, 4.0),
    branch=st.sampled_from([1, -1]),
    swing=st.floats(math.radians(15), math.radians(70)),
    band=st.floats(math.radians(0.05), math.radians(1.0)),
)
@example(b=3.0, c=2.5, d=3.0, branch=1, swing=math.radians(30), band=math.radians(0.1))
def test_simulated_dwell_and_swing_never_beat_the_bounds(b, c, d, branch, swing, band):
    if not grashof_crank(b, c, d):
        return  # not a crank-rocker / Grashof crank: find_segments wants a full turn
    _check(sixbar_cases(b, c, d, branch, swing, band))


def test_bounds_hold_and_are_not_loose_on_a_sample():
    """A fixed sample of linkages: never violated, median bound/actual reported and capped."""
    rng = np.random.default_rng(13)
    ratios = {"rpr": [], "rrr": []}
    lemma = {"rpr": [], "rrr": []}
    checked = elsewhere = 0
    for _ in range(6):
        b, c, d = rng.uniform(2.0, 4.0, 3)
        if not grashof_crank(b, c, d):
            continue
        cases = sixbar_cases(
            float(b),
            float(c),
            float(d),
            1,
            math.radians(rng.uniform(15, 60)),
            math.radians(rng.choice([0.1, 0.5])),
            per_kind=2,
        )
        _check(cases)
        for name, f, bound, _, tight in cases:
            if bound is None:
                elsewhere += 1
                continue
            ratios[name].append(bound / f.dwells[0].angle)
            lemma[name].append(tight / f.dwells[0].angle)
            checked += 1
    print(f"checked {checked}, longest dwell elsewhere {elsewhere}")
    for name in ratios:
        if ratios[name]:
            print(
                name,
                "bound/actual with the ratio limit: median %.2f min %.2f max %.2f"
                % (np.median(ratios[name]), min(ratios[name]), max(ratios[name])),
                "| with the dyad's own link: median %.2f min %.2f" % (np.median(lemma[name]), min(lemma[name])),
            )
    assert checked >= 6
    # RPR: with the dyad's own reach the bound is within 1.5× of the real dwell (the lemma is
    # tight). RRR is looser (2–5× measured): the dyads fitted here put Q at the centre of the
    # stored level's circle, not of the minimum-zone annulus at ε*, which the bound allows
    # (the family's free parameters); only reported.
    assert lemma["rpr"] and np.median(lemma["rpr"]) < 1.5, np.median(lemma["rpr"])


def test_minimum_zone_halfwidth_closed_forms():
    """A circle's arc has annulus half-width 0 and line half-width r(1 − cos(θ/2))/2 (the
    sagitta over two); a line has 0 for both."""
    theta = np.linspace(-0.5, 0.5, 41)
    arc = 2.0 * np.exp(1j * theta)[None, :]
    sagitta = 2.0 * (1 - math.cos(0.5))
    assert minimum_zone_halfwidth(arc, 1)[0] == pytest.approx(0.0, abs=1e-9)
    assert minimum_zone_halfwidth(arc, 0)[0] == pytest.approx(sagitta / 2, rel=1e-3)
    line = (0.3 + 0.1j + np.linspace(0, 1, 21) * np.exp(0.4j))[None, :]
    assert minimum_zone_halfwidth(line, 0)[0] == pytest.approx(0.0, abs=1e-12)


def test_dwell_bound_reads_the_next_level_up():
    levels = np.array([1e-4, 1e-3, 1e-2])
    length = np.array([[0.5, 1.0, 2.0]])
    assert dwell_bound(levels, length, np.array([5e-4]))[0] == 1.0
    assert dwell_bound(levels, length, np.array([1e-3]))[0] == 1.0
    assert dwell_bound(levels, length, np.array([1e-5]))[0] == 0.5
    assert dwell_bound(levels, length, np.array([0.5]))[0] == pytest.approx(2 * math.pi)


def test_path_tolerance_closed_forms():
    beta = math.radians(1.0)
    assert path_tolerance("rpr", beta, 10.0, 0.5) == pytest.approx(5 * math.sin(beta / 2))
    assert path_tolerance("rrr", beta, 10.0, 0.5) == pytest.approx(10 * math.sin(beta / 4))
    with pytest.raises(ValueError, match="rpr"):
        path_tolerance("prp", beta, 10.0, 1.0)


def test_swing_bounds_closed_forms():
    # RPR: a curve of hull width W seen from within R subtends ≥ arcsin(W/R)
    assert rpr_min_swing(1.0, 2.0, 1.0) == pytest.approx(math.pi / 6)
    assert rpr_min_swing(5.0, 2.0, 1.0) == pytest.approx(math.pi / 2)
    # RRR: diameter ≤ chord + 2ρ
    assert rrr_min_swing(3.0, 0.5, 1.0, 1.0) == pytest.approx(2 * math.asin(1.0))
    assert rrr_min_swing(0.5, 0.5, 1.0, 1.0) == 0.0


@given(
    pivot=st.complex_numbers(max_magnitude=5.0),
    mid=st.floats(-math.pi, math.pi),
    band=st.floats(math.radians(0.01), math.radians(5.0)),
    r_lo=st.floats(0.2, 2.0),
    r_span=st.floats(0.1, 10.0),
    rocker=st.floats(0.2, 10.0),
    rod=st.floats(0.2, 10.0),
    seed=st.integers(0, 2**32 - 1),
)
# found by a random-seed run: the line's half-width from the (linearised) fitter was 0.0407
# against a bound of 0.0395; the line's minimum zone is now exact
@example(pivot=0j, mid=0.0, band=0.05859375, r_lo=1.25, r_span=0.1015625, rocker=1.0, rod=1.0, seed=16949)
def test_lemmas_on_random_outputs(pivot, mid, band, r_lo, r_span, rocker, rod, seed):
    """The two lemmas on their own: points P whose output angle stays within the band lie
    within r·sin(β/2) of a line (RPR) and within 2L·sin(β/4) of a circle (RRR); the profile's
    measure (the exact minimum-zone line, the fitted annulus) respects both."""
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0, 1, 21))
    psi = mid - band / 2 + band * rng.uniform(0, 1, 21)
    r = r_lo + r_span * t  # the pin moves outwards along the slot as the crank turns
    P = pivot + r * np.exp(1j * psi)
    assert minimum_zone_halfwidth(P[None, :], 0)[0] <= r.max() * math.sin(band / 2) * (1 + 1e-9) + 1e-12
    # RRR: Q on the rocker's arc within the band, P at distance ρ from Q in a smoothly turning
    # direction, Q moving smoothly as on a real dwell (on rough random points the annulus
    # fitter, a linearised Lawson fit, can miss the optimum: hypothesis found 0.38 against a
    # bound of 0.35 with ρ = 2.5, L = 9, β = 4.5°)
    psi = mid + band / 2 * np.sin(3 * t + rng.uniform(0, 2 * math.pi))
    Q = pivot + rocker * np.exp(1j * psi)
    P = Q + rod * np.exp(1j * (mid + 0.5 + 0.8 * t))
    assert minimum_zone_halfwidth(P[None, :], 1)[0] <= 2 * rocker * math.sin(band / 4) * (1 + 1e-6) + 1e-12


def test_profile_is_monotone_and_never_below_the_stored_dwells():
    """L(ε) is non-decreasing, and at the atlas's own levels it is at least the dwell
    find_segments stored (that interval contains the generating angle and passed a fit of
    half-width ≤ ε on the dense path)."""
    b, c, d = 3.0, 2.5, 3.0
    found = find_segments(np.array([b]), np.array([c]), np.array([d]), np.array([1]), SEARCH)
    tols = np.array(found.tolerances)
    checked = 0
    for i in [*np.flatnonzero(found.kind == 0)[:2], *np.flatnonzero(found.kind == 1)[:2]]:
        p = deviation_profile(
            b,
            c,
            d,
            1,
            complex(found.uv[i]),
            float(found.phi_gen[i]),
            int(found.kind[i]),
            levels=np.r_[tols, 1e-5, 1e-1],
            step=STEP,
        )
        assert np.all(np.diff(p.length) >= 0)
        stored = found.phi_end[i, :, 0] - found.phi_start[i, :, 0]
        at = np.searchsorted(p.levels, tols)
        has = found.has_dwell[i, :, 0]
        assert np.all(p.length[at][has] >= stored[has] - 1e-9)
        checked += int(has.sum())
    assert checked >= 6


@pytest.mark.parametrize("kind", [0, 1])
def test_staircase_profile_never_below_the_exhaustive_one(kind):
    """The batched staircase walk (the affordable one) is an upper estimate of the exhaustive
    search, at most its slack above it."""
    b, c, d = np.array([3.0, 2.5]), np.array([2.5, 2.0]), np.array([3.0, 2.8])
    found = find_segments(b, c, d, np.array([1, 1]), SEARCH)
    rows = np.flatnonzero(found.kind == kind)[:4]
    link = found.linkage[rows]
    levels = np.logspace(-5, -1, 9)
    walk = deviation_profiles(
        b[link],
        c[link],
        d[link],
        np.ones(rows.size, int),
        found.uv[rows],
        found.phi_gen[rows],
        kind,
        levels=levels,
        step=STEP,
    )
    for q, i in enumerate(rows):
        every = deviation_profile(
            float(b[link[q]]),
            float(c[link[q]]),
            float(d[link[q]]),
            1,
            complex(found.uv[i]),
            float(found.phi_gen[i]),
            kind,
            levels=levels,
            step=STEP,
        )
        capped = every.length < 2 * math.pi
        assert np.all(walk.length[q] >= every.length - 1e-9)
        assert np.all(walk.length[q][capped] <= every.length[capped] + (STAIRCASE_SLACK + 2) * STEP + 1e-9)
