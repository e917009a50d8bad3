"""Two dwells are two rests with motion between them (issue #41): the dwell finder
(:func:`synth.mechanism.output_range.dwell_intervals`, ``count=2``) reports a second dwell only if it is
separated from the first by :func:`synth.mechanism.output_range.rests_separated` — the crank turns ≥ 5°
and the output leaves both rests' bands by ≥ the swing tolerance between them, each way
round — and the query holds its answers to the same rule."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from synth.mechanism.output_range import REST_GAP, dwell_intervals, rests_separated
from synth.mechanism.sixbar import crank_grid

DEG = math.pi / 180
TWO_PI = 2 * math.pi
BAND = 0.1 * DEG
LEAVE = 0.5 * DEG


def _smooth(x):
    x = np.clip(x, 0.0, 1.0)
    return 3 * x * x - 2 * x**3


def _ramps(phi, knots):
    """ψ(φ), piecewise: ``knots`` = [(φ_k, ψ_k)] ascending in [0, 2π), joined by smoothsteps
    (flat where two knots have the same level), periodic."""
    p = np.mod(np.asarray(phi, float), TWO_PI)
    xs = [k[0] for k in knots] + [knots[0][0] + TWO_PI]
    ys = [k[1] for k in knots] + [knots[0][1]]
    p = np.where(p < xs[0], p + TWO_PI, p)
    out = np.full(p.shape, float(ys[0]))
    for x0, x1, y0, y1 in zip(xs[:-1], xs[1:], ys[:-1], ys[1:]):
        out = np.where((p >= x0) & (p <= x1), y0 + (y1 - y0) * _smooth((p - x0) / (x1 - x0)), out)
    return out


#: One long rest the band splits in two: level 0 on [0.2, 0.7] rad, a step of 1.5 bands over
#: 0.01 rad of crank (0.57°), level 1.5·band on [0.71, 1.3] — as the demo atlas's
#: 138000012-dbl0.2 did (two "rests" 0.14° of crank apart, the output turning 0.088°) — then
#: the output swings out to 1 rad and back (smoothsteps: it lingers a few degrees at the top).
SPLIT = [(0.2, 0.0), (0.7, 0.0), (0.71, 1.5 * BAND), (1.3, 1.5 * BAND), (2.5, 1.0)]
#: The same with a real second rest at 1 rad on [3.5, 3.9] (0.4 rad: shorter than either half).
SPLIT_AND_REST = [
    (0.2, 0.0),
    (0.7, 0.0),
    (0.71, 1.5 * BAND),
    (1.3, 1.5 * BAND),
    (2.5, 0.8),
    (3.5, 1.0),
    (3.9, 1.0),
    (5.0, 0.3),
]


def _found(knots, samples=720, leave=LEAVE):
    phi = crank_grid(samples)
    return dwell_intervals(phi, _ramps(phi, knots), BAND, count=2, psi_at=lambda at: _ramps(at, knots), leave=leave)


def test_a_rest_split_by_the_band_is_not_two_dwells():
    found = _found(SPLIT)
    # the longer half (0.59 rad and what the band adds of the step) is the first dwell; the
    # other half (0.5 rad), 0.01 rad of crank away with the output 1.5 bands off, is no second
    # rest: the second is where the output lingers at the top of its swing (~7° of crank)
    assert found.found.tolist() == [True, True]
    assert found.start[0] == pytest.approx(0.7, abs=0.01) and found.end[0] == pytest.approx(1.3, abs=0.05)
    assert found.start[1] < 2.5 < found.end[1] and found.angle[1] < 10 * DEG
    assert bool(rests_separated(found.gap, found.leave, LEAVE))


def test_the_second_dwell_is_the_real_rest_not_the_other_half():
    """Before the rule the finder took the other half of the split rest (0.5 rad, longer than
    the real rest of 0.4 rad) as the second dwell."""
    found = _found(SPLIT_AND_REST)
    assert found.found.tolist() == [True, True]
    # (the smoothsteps linger: the band holds ~0.05 rad beyond each end of the flat)
    assert 3.4 < found.start[1] < 3.5 and 3.9 < found.end[1] < 4.0
    assert bool(rests_separated(found.gap, found.leave, LEAVE))
    # each way round: from the first rest up to the second (the output turns by ~1 rad) and
    # back (again ~1 rad from the second's band, 1.5 bands from the first's: the smaller)
    assert found.gap[0] == pytest.approx(found.start[1] - found.end[0], abs=1e-12)
    assert found.gap[1] == pytest.approx(found.start[0] + TWO_PI - found.end[1], abs=1e-12)
    spans = [(found.start[k], found.end[k]) for k in range(2)]
    for k, (gap, leave) in enumerate(_brute_force_gaps(SPLIT_AND_REST, *spans)):
        assert found.gap[k] == pytest.approx(gap, abs=1e-12)
        assert leave - 0.05 * DEG <= found.leave[k] <= leave  # the grid samples of the gap: never more
    assert found.leave[0] == pytest.approx(1.0 - 2.5 * BAND, abs=2 * BAND)


def test_the_swing_tolerance_decides_a_small_step():
    """Rests at 0 and at 0.5° (1 rad of crank each, 1 rad apart): between them the output gets
    0.3° beyond either band (0.5° less the 0.1° band the rests take, less the 0.1° the band
    holds on the way) — two rests at a swing tolerance of 0.1°, one (the longer) at 0.5°."""
    knots = [(0.5, 0.0), (1.5, 0.0), (2.5, 0.5 * DEG), (3.5, 0.5 * DEG), (4.5, 0.0)]
    two = _found(knots, leave=0.1 * DEG)
    assert two.found.tolist() == [True, True]
    assert two.leave[0] == pytest.approx(0.3 * DEG, abs=0.02 * DEG)
    assert _found(knots, leave=0.5 * DEG).found.tolist() == [True, False]


def test_the_rule_is_both_ways_round_and_both_limits():
    gap = np.array([[REST_GAP, REST_GAP], [REST_GAP, REST_GAP - 1e-9], [1.0, 1.0]])
    leave = np.array([[LEAVE, LEAVE], [1.0, 1.0], [1.0, LEAVE - 1e-9]])
    assert rests_separated(gap, leave, LEAVE).tolist() == [True, False, False]


def _brute_force_gaps(knots, first, second, fine=0.01 * DEG):
    """The crank gaps and the output's least excursion out of both rests' bands, each way
    round, on a fine grid of the exact ψ: what :func:`rests_separated` is told."""
    out = []
    psi = lambda at: _ramps(at, knots)
    bands = []
    for s, e in (first, second):
        v = psi(np.linspace(s, e, max(3, int((e - s) / fine))))
        bands.append((v.min(), v.max()))
    for (s0, e0), (s1, _) in ((first, second), (second, first)):
        gap = np.mod(s1 - e0, TWO_PI)
        v = psi(e0 + np.linspace(0, gap, max(3, int(gap / fine))))
        beyond = [max(v.max() - hi, lo - v.min(), 0.0) for lo, hi in bands]
        out.append((gap, min(beyond)))
    return out


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(0.15, 1.2), st.floats(-0.02, 0.02)), min_size=2, max_size=5), st.floats(0.05, 2.0))
@example([(0.5, 0.0), (0.01, 0.0026), (0.6, 0.0)], 0.5)  # the split rest
def test_two_reported_dwells_are_always_two_rests(steps, leave_deg):
    """Random rest-and-step outputs (levels within ±0.02 rad, steps of any crank length):
    whatever the finder reports as two dwells is separated by the rule on a brute-force
    0.01° walk of the exact ψ (to the refinement's margin)."""
    xs = np.cumsum([0.0] + [w for w, _ in steps])
    if xs[-1] >= TWO_PI - 0.2:
        return
    ys = np.cumsum([0.0] + [d for _, d in steps])
    knots = list(zip((0.1 + xs).tolist(), ys.tolist()))
    found = _found(knots, leave=leave_deg * DEG)
    if not found.found[1]:
        return
    spans = [(found.start[k], found.end[k]) for k in range(2)]
    for gap, leave in _brute_force_gaps(knots, *spans):
        assert gap >= REST_GAP - 1e-9
        assert leave >= leave_deg * DEG - 1e-6 * DEG


#: The demo atlas's answer to `--dwell 30 --dwell-tol 5 --dwells 2 --output rpr` before the
#: rule: rests [5.43°, 32.07°] and [32.21°, 65.77°], 0.14° of crank apart, the output turning
#: 0.088° between them in a 0.1° band — one 60° rest (issue #41).
SPLIT_ID = "138000012-dbl0.2@free~AT_Xd2dABzmBQCcZlEAk2VjACAjUQHKuJ8ESP6o"


def test_the_demo_atlas_split_rest_is_not_two_dwells():
    from synth.mechanism.figures import sixbar_figures
    from synth.query.candidate_ids import candidate_dimensions

    sb = candidate_dimensions(SPLIT_ID)
    f = sixbar_figures(sb, band=BAND, dwell_length=30 * DEG, dwells=2, leave=LEAVE)
    ends = [d.ends_deg() for d in f.dwells]
    # the longer half stays the first dwell; the second is the six-bar's real second rest
    assert ends[0] == pytest.approx((32.2099, 65.7656), abs=0.01)
    assert ends[1] == pytest.approx((195.847, 221.797), abs=0.01)
    assert f.rests_apart(LEAVE) and math.degrees(f.step) == pytest.approx(9.83, abs=0.01)
    assert [math.degrees(g) for g, _ in f.gaps] == pytest.approx([130.08, 170.41], abs=0.01)
    _check_two_rests(sb, f, LEAVE)


def _check_two_rests(sb, f, tol):
    """The rule on an independent 0.01° walk of the exact simulation of ``sb`` (crank-normalised
    six-bar with figures ``f``), each way round between its two dwells."""
    from synth.mechanism.sixbar import simulate

    a, b = f.dwells[:2]
    for (s, e), other in (((a.start, a.end), b), ((b.start, b.end), a)):
        gap = np.mod(other.start - e, TWO_PI)
        walk = e + np.linspace(0, gap, max(3, int(math.degrees(gap) / 0.01)))
        psi = np.unwrap(simulate(sb, np.mod(walk, TWO_PI), order=0).psi)
        psi += TWO_PI * np.round((a.rest - psi[0]) / TWO_PI)
        beyond = [max(psi.max() - (d.rest + BAND / 2), (d.rest - BAND / 2) - psi.min()) for d in (a, b)]
        assert math.degrees(gap) >= 5 and min(beyond) >= tol


def test_the_query_answers_two_rests(source):
    """Every double-dwell answer of a query on the test atlas has two rests by the rule, checked
    on an independent simulation at the request's swing tolerance."""
    from synth.query import answer
    from synth.query.candidates import Request

    request = Request(
        dwell=40 * DEG,
        dwell_tol=15 * DEG,
        swing=21.8 * DEG,
        swing_tol=2 * DEG,
        output="rpr",
        dwells=2,
        min_transmission=20 * DEG,
        max_link_ratio=30,
        refine=False,
    )
    found = answer(request, source).candidates
    assert len(found) >= 3
    for c in found:
        sb = c.sixbar.scaled(1.0 / request.crank)
        assert c.figures.rests_apart(request.swing_tol) and abs(c.figures.swing - request.swing) <= request.swing_tol
        _check_two_rests(sb, c.figures, request.swing_tol)
