"""synth.mechanism.tolerance: the toleranced output deviation, held to a plain loop over the same draws."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import synth.mechanism.tolerance as tolerance_module
from synth.mechanism import dwell_ends_kernel, tolerance_kernel
from synth.mechanism.figures import sixbar_figures
from synth.mechanism.output_range import output_deviation
from synth.mechanism.sixbar import (
    PIN_ON_PIVOT_EPS,
    ExactOutput,
    OutputDyad,
    SixBar,
    crank_grid,
    kernel_inputs,
    simulate,
)
from synth.mechanism.sixbar_kernel import output_angles
from synth.mechanism.tolerance import (
    DRAWS,
    PERCENTILE,
    SEED,
    clear_of_limits,
    crank_turns,
    deciding_draws,
    deviation_draws,
    perturbed,
    toleranced_deviation,
    unit_draws,
)
from synth.query.candidates import Candidate, Request, rank

# the demo's best RRR 60°/30° six-bar (crank 1) and an RPR 45°/40° one
RRR = SixBar(1.0, 3.542, 2.49, 3.938, 1, 3.645, -0.321, OutputDyad.rrr(complex(4.219, -0.5853), 0.4984, 2.807, 1))
RPR = SixBar(1.0, 4.072, 1.546, 4.173, 1, 3.794, -0.2963, OutputDyad.rpr(complex(1.982, 2.447)))
# the best answers on `standard` to RPR 135°/15° and RRR 120°/20° (crank 1): long dwells, the
# most samples a draw
RPR_LONG = SixBar(
    1.0,
    3.204494922919432,
    3.7866919384592808,
    4.407561973601058,
    1,
    3.326214283766126,
    0.9664907337493401,
    OutputDyad.rpr(complex(2.331377209893427, 5.018076951827258)),
)
RRR_LONG = SixBar(
    1.0,
    4.171713352203369,
    4.838138103485107,
    3.724871873855591,
    -1,
    7.432656288146973,
    1.4767475128173828,
    OutputDyad.rrr(complex(6.593959808349609, -11.989498138427734), 3.4670629501342773, 5.514910697937012, -1),
)
BAND = math.radians(0.1)


def _centres(sb: SixBar, length: float) -> list[float]:
    f = sixbar_figures(sb, band=BAND, dwell_length=length)
    return [0.5 * (d.start + d.end) for d in f.dwells]


def _brute_force(sb: SixBar, tol: float, centres: list[float], length: float, draws: int) -> np.ndarray:
    """One draw at a time, written out: the drawn dimensions, the draw's own frame (A0′ at the
    origin, B0′ on +x), one six-bar simulated alone, its deviation per dwell."""
    out = []
    phi = crank_grid(720)
    for row in unit_draws(draws):
        e = tol * row
        a0 = complex(e[7], e[8])
        b0 = complex(sb.d + e[9], e[10])
        beta = math.atan2((b0 - a0).imag, (b0 - a0).real)
        rot = complex(math.cos(-beta), math.sin(-beta))
        dy = sb.dyad
        pivot = (dy.pivot + complex(e[11], e[12]) - a0) * rot
        if dy.kind == "RRR":
            dyad = OutputDyad.rrr(pivot, dy.rocker + e[5], dy.rod + e[6], dy.branch)
        else:
            dyad = OutputDyad.rpr(pivot)
        one = SixBar(sb.a + e[0], sb.b + e[1], sb.c + e[2], abs(b0 - a0), sb.branch, sb.u + e[3], sb.v + e[4], dyad)
        m = simulate(one, phi, order=1)
        if np.any(m.status != 0) or abs(m.psi[-1] - m.psi[0]) >= math.pi:
            out.append(math.inf)
            continue
        worst = 0.0
        for c in centres:
            c_draw = (c - beta - phi[0]) % (2 * math.pi) + phi[0]
            from synth.mechanism.sixbar import SixBars

            dev, _ = output_deviation(
                phi, m.psi, c_draw, length, psi_at=ExactOutput(SixBars.from_sixbars([one])), dpsi1=m.dpsi[0]
            )
            worst = max(worst, float(dev))
        out.append(worst)
    return np.array(out)


@pytest.mark.parametrize("sb, dwell_deg", [(RRR, 60.0), (RPR, 45.0), (RPR_LONG, 135.0), (RRR_LONG, 120.0)])
def test_draws_match_a_plain_loop_over_the_same_draws(sb, dwell_deg):
    length = math.radians(dwell_deg)
    centres = _centres(sb, length)
    tol = 0.05 / 40  # 0.05 mm on a 40 mm crank
    assert clear_of_limits(sb, tol)  # far from every limit: the dwell windows are enough
    loop = _brute_force(sb, tol, centres, length, 48)
    turn = deviation_draws(sb, tol, centres, length, draws=48, whole_turn=True)
    batch = deviation_draws(sb, tol, centres, length, draws=48)  # the dwell windows only
    assert np.all(np.isfinite(batch)) and np.all(np.isfinite(loop))
    np.testing.assert_allclose(turn, loop, rtol=0, atol=1e-12)
    # the windows' coarser grid and shorter refinement: within 0.002° of every draw's figure
    # (measured: 0.001° at most), against deviations of ~0.1°
    np.testing.assert_allclose(batch, loop, rtol=0, atol=math.radians(0.002))
    assert np.max(np.abs(batch - loop)) > 0  # the two paths are not the same code
    # the tolerance moves the rest: the draws spread, and some rest worse than the drawing
    nominal = max(sixbar_figures(sb, band=BAND, dwell_length=length).deviations)
    assert batch.max() > nominal * 1.05 and batch.std() > 0


@pytest.mark.parametrize(
    "sb, dwell_deg, zone, redone",
    [(RPR_LONG, 135.0, 1, (63, 63)), (RRR_LONG, 120.0, 2, (2, 62)), (RRR_LONG, 120.0, 0, (63, 63))],
)
def test_windows_sampled_near_the_first_draws_best_are_those_sampled_whole(monkeypatch, sb, dwell_deg, zone, redone):
    # a long dwell's draws are sampled every step only near the first draw's best window
    # start (ZONE steps either side); a zone too narrow for some draws (measured: 19 of 64 at
    # 2 steps for this RRR) or for all of them sends those back to every sample: the same
    # figures either way
    length = math.radians(dwell_deg)
    centres = _centres(sb, length)
    whole_grid, rows_sampled_whole = {}, {}
    real = tolerance_kernel.window_samples

    def spy(*args):
        slab, jbest, dev, whole = real(*args)
        rows_sampled_whole[name] += int(whole.sum())
        return slab, jbest, dev, whole

    monkeypatch.setattr(tolerance_kernel, "window_samples", spy)
    for name, steps in [("zone", tolerance_module.ZONE), ("narrow", zone), ("whole", 10_000)]:
        monkeypatch.setattr(tolerance_module, "ZONE", steps)
        rows_sampled_whole[name] = 0
        whole_grid[name] = deviation_draws(sb, 0.05 / 40, centres, length, draws=64)
    # the first draw sampled whole, then none, some or all of the 63 others; or every draw at once
    assert rows_sampled_whole["zone"] == 1
    assert redone[0] <= rows_sampled_whole["narrow"] - 1 <= redone[1]
    assert rows_sampled_whole["whole"] == 64
    # a sample's ψ does not depend on which other samples are taken: the very same figures
    np.testing.assert_array_equal(whole_grid["zone"], whole_grid["whole"])
    np.testing.assert_array_equal(whole_grid["narrow"], whole_grid["whole"])


@pytest.mark.parametrize("sb, dwell_deg", [(RRR, 60.0), (RPR_LONG, 135.0)])
def test_a_candidates_draws_stay_on_one_thread_until_a_split_pays(monkeypatch, sb, dwell_deg):
    # with two threads to hand: a candidate's 256 draws (every column for the RRR, the zone
    # for the long RPR) are sampled in the caller's thread, where they cost the least CPU;
    # 2 048 draws (estimated over the split threshold) are split, with bitwise the figures of
    # the same draws on one thread
    import threading

    from synth import parallel_rows

    length = math.radians(dwell_deg)
    centres = _centres(sb, length)
    threads_used, real = set(), tolerance_kernel._sample_rows

    def spy(*args):
        threads_used.add(threading.get_ident())
        return real(*args)

    monkeypatch.setattr(tolerance_kernel, "_sample_rows", spy)
    monkeypatch.setattr(parallel_rows, "threads", lambda: 2)
    deviation_draws(sb, 0.05 / 40, centres, length, draws=DRAWS)
    assert threads_used == {threading.get_ident()}
    split = deviation_draws(sb, 0.05 / 40, centres, length, draws=2048)
    assert len(threads_used) == 2
    monkeypatch.setattr(tolerance_kernel, "_SPLIT_NS", math.inf)
    threads_used.clear()
    one = deviation_draws(sb, 0.05 / 40, centres, length, draws=2048)
    assert threads_used == {threading.get_ident()}
    np.testing.assert_array_equal(split, one)
    assert np.all(np.isfinite(one)) and one.std() > 0


def test_six_bars_split_over_threads_give_each_ones_figure(monkeypatch):
    # a query's candidates in one call: split over two threads (each six-bar's draws on one),
    # bitwise the figures of one call per six-bar; a bad tolerance or centres: one clear error
    import threading

    from synth import parallel_rows

    sixbars = [RRR, RPR, RPR_LONG, RRR_LONG]
    lengths = {id(RRR): 60.0, id(RPR): 45.0, id(RPR_LONG): 135.0, id(RRR_LONG): 120.0}
    length = math.radians(50.0)  # one request: every six-bar's window that long
    centres = [_centres(sb, math.radians(lengths[id(sb)])) for sb in sixbars]
    threads_used, real = set(), tolerance_module.toleranced_deviation

    def spy(*args, **kwargs):
        threads_used.add(threading.get_ident())
        return real(*args, **kwargs)

    monkeypatch.setattr(parallel_rows, "threads", lambda: 2)
    monkeypatch.setattr(tolerance_module, "toleranced_deviation", spy)
    split = tolerance_module.toleranced_deviations(sixbars, 0.05 / 40, centres, length, draws=64)
    assert len(threads_used) == 2
    one = [real(sb, 0.05 / 40, c, length, draws=64) for sb, c in zip(sixbars, centres)]
    assert split == one and all(x is not None and x > 0 for x in one) and len(set(one)) == 4
    with pytest.raises(ValueError, match="tolerance"):
        tolerance_module.toleranced_deviations(sixbars, -1.0, centres, length)
    with pytest.raises(ValueError, match="centres"):
        tolerance_module.toleranced_deviations(sixbars, 0.01, centres[:2], length)


def test_zero_tolerance_is_the_nominal_deviation():
    length = math.radians(60.0)
    nominal = max(sixbar_figures(RRR, band=BAND, dwell_length=length).deviations)
    dev = deviation_draws(RRR, 0.0, _centres(RRR, length), length, draws=8, whole_turn=True)
    np.testing.assert_allclose(dev, nominal, rtol=0, atol=1e-12)
    dev = deviation_draws(RRR, 0.0, _centres(RRR, length), length, draws=8)
    np.testing.assert_allclose(dev, nominal, rtol=0, atol=math.radians(0.001))


def test_percentile_of_256_seeded_draws_is_deterministic_and_grows_with_the_tolerance():
    length = math.radians(60.0)
    centres = _centres(RRR, length)
    small = toleranced_deviation(RRR, 0.02 / 40, centres, length)
    large = toleranced_deviation(RRR, 0.05 / 40, centres, length)
    assert large == toleranced_deviation(RRR, 0.05 / 40, centres, length)
    draws = deviation_draws(RRR, 0.05 / 40, centres, length)
    assert len(draws) == DRAWS
    # refining only the draws that decide the percentile gives the very number
    assert large == pytest.approx(float(np.percentile(draws, PERCENTILE)), abs=0)
    nominal = max(sixbar_figures(RRR, band=BAND, dwell_length=length).deviations)
    assert nominal < small < large


def _spied(monkeypatch):
    """Spies on the bounds of one call: each window_bounds call's four bounds, the bounds
    deciding_draws is given, and the number of draws refined."""
    seen = {"kernel": [], "refined": []}

    def spy_bounds(*args):
        bounds = real_bounds(*args)
        seen["kernel"].append([b.copy() for b in bounds])
        return bounds

    def spy_decide(lower, upper, q):
        seen["lower"], seen["upper"] = lower.copy(), upper.copy()
        return deciding_draws(lower, upper, q)

    def spy_refine(params, rpr, six, *rest):
        seen["refined"].append(len(six))
        return real_refine(params, rpr, six, *rest)

    real_bounds, real_refine = tolerance_kernel.window_bounds, dwell_ends_kernel.refine_deviation_windows
    monkeypatch.setattr(tolerance_kernel, "window_bounds", spy_bounds)
    monkeypatch.setattr(tolerance_module, "deciding_draws", spy_decide)
    monkeypatch.setattr(dwell_ends_kernel, "refine_deviation_windows", spy_refine)
    return seen


@pytest.mark.parametrize(
    "sb, dwell_deg, most",
    [(RRR, 60.0, 8), (RPR, 45.0, 8), (RPR_LONG, 135.0, 8), (RRR_LONG, 120.0, 8)],
)
@pytest.mark.parametrize("tol_mm, seed", [(0.05, SEED), (0.02, 1), (0.2, 2)])
def test_bounds_hold_every_draw_and_leave_few_to_refine(monkeypatch, sb, dwell_deg, most, tol_mm, seed):
    length = math.radians(dwell_deg)
    centres = _centres(sb, length)
    assert len(centres) == 1
    tol = tol_mm / 40
    seen = _spied(monkeypatch)
    value = toleranced_deviation(sb, tol, centres, length, seed=seed)
    ((samples_lo, samples_hi, cubic_lo, cubic_hi),) = seen["kernel"]
    refined = sum(seen["refined"])
    every = deviation_draws(sb, tol, centres, length, seed=seed)  # every draw refined
    # both kinds of bound hold every draw on their own
    assert np.all(samples_lo <= every) and np.all(every <= samples_hi)
    assert np.all(cubic_lo <= every) and np.all(every <= cubic_hi)
    assert np.all(seen["lower"] <= every) and np.all(every <= seen["upper"])
    # the interpolated ones are the tight ones wherever they are taken (measured: on 98.8-100 %
    # of the draws, 2e-5-6e-5° wide, against 0.014-0.06° for the samples')
    taken = np.isfinite(cubic_hi)
    assert taken.mean() > 0.9
    assert np.max(cubic_hi[taken] - cubic_lo[taken]) < math.radians(1e-4)
    assert refined <= most  # measured: 2-5 draws
    assert value == float(np.percentile(every, PERCENTILE))


@pytest.mark.parametrize("seed", [SEED, 1])
def test_samples_bounds_hold_where_the_dwell_is_not_whole_grid_steps(monkeypatch, seed):
    # 45° is 22.5 steps of 2°: every refined window reaches half a step past the grid window,
    # whose range alone is no upper bound (about half these draws refine above it, by up to
    # 0.009°): the samples' upper bound allows for it
    length = math.radians(45.0)
    centres = _centres(RPR, length)
    tol = 0.2 / 40
    seen = _spied(monkeypatch)
    value = toleranced_deviation(RPR, tol, centres, length, draws=64, seed=seed)
    ((samples_lo, samples_hi, _, _),) = seen["kernel"]
    every = deviation_draws(RPR, tol, centres, length, draws=64, seed=seed)
    assert np.all(samples_lo <= every) and np.all(every <= samples_hi)
    assert value == float(np.percentile(every, PERCENTILE))


@pytest.mark.parametrize("sb, dwell_deg", [(RRR, 60.0), (RPR_LONG, 135.0)])
def test_window_samples_are_the_position_kernels_psi(sb, dwell_deg):
    # ψ alone (two closing triangles, the angle from the dwell middle's direction, an odd
    # series near it) against the position kernel's ψ (every joint, atan2 steps summed), over
    # a whole turn of 2° samples of 32 draws: the rest and the swing both
    batch, _ = perturbed(sb, 0.05 / 40, unit_draws(32))
    params, rpr = kernel_inputs(batch)
    phi = crank_grid(180)
    n, mid = len(params), round(_centres(sb, math.radians(dwell_deg))[0] / (2 * math.pi / 180))
    slab, start, width, whole = tolerance_kernel.window_samples(
        params, rpr, phi, np.full(n, mid), np.full(n, mid - 30), np.full(n, mid), 30, 10_000, 4
    )
    psi = output_angles(params, rpr, phi[None, :], PIN_ON_PIVOT_EPS)
    assert whole.all() and np.isfinite(slab).all()
    # the two differ by a whole number of turns at most (each starts on its own branch)
    offset = np.round((psi[:, mid] - slab[:, mid]) / (2 * math.pi)) * 2 * math.pi
    np.testing.assert_allclose(slab + offset[:, None], psi, rtol=0, atol=1e-13)
    # both ways of taking the angle are held: the rest within 1/32 rad of the middle's
    # direction (the series), the swing beyond it (atan2)
    near = np.abs(slab - slab[:, mid : mid + 1]) < 1 / 32
    assert np.all(near.sum(axis=1) > 20) and np.all((~near).sum(axis=1) > 20)
    # the best start: the window of 31 samples with the least range, the first of equals
    ranges = np.array([[np.ptp(row[s : s + 31]) for s in range(mid - 30, mid + 1)] for row in slab])
    np.testing.assert_array_equal(start + 1, mid - 30 + np.argmin(ranges, axis=1))
    np.testing.assert_array_equal(width, ranges.min(axis=1))


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=40),
    st.integers(0, 39),
    st.integers(0, 39),
    st.integers(1, 12),
)
def test_best_start_is_the_window_of_least_range(values, first, count, nL):
    # every window of nL + 1 samples from a start in [first, first + count]: one pass of
    # suffix and prefix extremes where the starts lie within a window, each window read whole
    # where they do not
    row = np.array([values])
    last = min(first + count, len(values) - 1 - nL)
    top, bottom = np.empty(len(values)), np.empty(len(values))
    start, width = tolerance_kernel._best_start(row, 0, first, last, nL, top, bottom)
    if last < first:
        assert (start, width) == (-1, math.inf)
        return
    ranges = [np.ptp(row[0, s : s + nL + 1]) for s in range(first, last + 1)]
    assert start == first + int(np.argmin(ranges))
    assert width == min(ranges)


def test_moved_ground_pivots_turn_the_frame():
    unit = np.zeros((1, 13))
    unit[0, 8] = 1.0  # A0 moved up by the tolerance: the ground line turns clockwise
    batch, beta = perturbed(RRR, 0.1, unit)
    assert beta[0] == pytest.approx(math.atan2(-0.1, RRR.d), rel=1e-15)
    assert batch.d[0] == pytest.approx(math.hypot(RRR.d, 0.1), rel=1e-15)
    # D keeps its distance to A0′
    assert abs(batch.pivot[0]) == pytest.approx(abs(RRR.dyad.pivot - 0.1j), rel=1e-14)


def test_a_tolerance_no_draw_survives_is_none_and_ranks_last():
    length = math.radians(60.0)
    centres = _centres(RRR, length)
    assert toleranced_deviation(RRR, 2.0, centres, length, draws=32) is None  # links of ±2 cranks
    f = sixbar_figures(RRR, band=BAND, dwell_length=length)
    req = Request(dwell=length, swing=math.radians(30.0), tolerance=0.001)
    worse = Candidate("b", 1, RRR, f, toleranced_deviation=None)
    better = Candidate("a", 2, RRR, f, toleranced_deviation=math.radians(0.5))
    assert [c.id for c in rank(req, [worse, better])] == ["a", "b"]
    with pytest.raises(ValueError, match="`tolerance`"):
        Request(dwell=length, swing=math.radians(30.0), tolerance=-1.0)


def test_near_a_limit_every_draw_is_simulated_over_the_whole_turn():
    length = math.radians(60.0)
    centres = _centres(RRR, length)
    assert clear_of_limits(RRR, 0.05 / 40)
    # the RRR's rod and rocker reach r = |D − P| ∈ [|L − ρ|, L + ρ]; a tolerance of a tenth of
    # the smallest margin over the turn leaves no room for the linear bound's factor of two
    phi = crank_grid(720)
    r = np.abs(RRR.dyad.pivot - simulate(RRR, phi, order=0).z[0])
    margin = float(np.min(np.minimum(RRR.dyad.rocker + RRR.dyad.rod - r, r - abs(RRR.dyad.rocker - RRR.dyad.rod))))
    tol = 0.1 * margin
    assert not clear_of_limits(RRR, tol)
    np.testing.assert_array_equal(
        deviation_draws(RRR, tol, centres, length, draws=16),
        deviation_draws(RRR, tol, centres, length, draws=16, whole_turn=True),
    )


def testcrank_turns_is_the_grashof_crank_condition():
    unit = np.zeros((3, 13))
    unit[1, 0] = 1.0  # a longer crank
    unit[2, 2] = -1.0  # a shorter rocker
    batch, _ = perturbed(RRR, 1.0, unit)
    a, b, c, d = RRR.a, RRR.b, RRR.c, RRR.d
    assert d + a < b + c and abs(b - c) < d - a  # the drawing: the crank turns
    # a = 2: |b − c| = 1.052 < d − a = 1.938 and d + a = 5.938 < b + c = 6.032; c = 1.49:
    # d + a = 4.938 < b + c = 5.032: both still turn
    np.testing.assert_array_equal(crank_turns(batch), [True, True, True])
    unit[2, 2] = -1.5  # c = 0.99: d + a = 4.938 > b + c = 4.532, the coupler cannot reach
    batch, _ = perturbed(RRR, 1.0, unit)
    np.testing.assert_array_equal(crank_turns(batch), [True, True, False])


@pytest.mark.parametrize("q", [50.0, 95.0, 99.0])
def test_deciding_draws_hold_every_order_statistic_the_percentile_reads(q):
    rng = np.random.default_rng(7)
    exact = rng.uniform(0.0, 1.0, 256)
    lower, upper = exact - rng.uniform(0, 0.05, 256), exact + rng.uniform(0, 0.05, 256)
    need, stand_in = deciding_draws(lower, upper, q)
    assert 0 < need.sum() < 128  # most draws are decided by their bounds alone
    assert np.all((stand_in == lower) | (stand_in == upper))
    # the others replaced by their stand-ins: the same percentile
    assert np.percentile(np.where(need, exact, stand_in), q) == np.percentile(exact, q)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(0.0, 1.0),
            st.floats(0.0, 0.5),
            st.floats(0.0, 0.5),
        ),
        min_size=2,
        max_size=300,
    ),
    st.floats(0.0, 100.0),
)
def test_deciding_draws_give_the_exact_percentile_for_any_bounds(draws, q):
    exact = np.array([x for x, _, _ in draws])
    lower = exact - np.array([a for _, a, _ in draws])
    upper = exact + np.array([b for _, _, b in draws])
    need, stand_in = deciding_draws(lower, upper, q)
    assert np.percentile(np.where(need, exact, stand_in), q) == np.percentile(exact, q)
