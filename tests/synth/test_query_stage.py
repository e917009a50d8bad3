"""The query as a library stage (``synth.query``): answers through any :class:`SegmentSource`,
a necessary screen, rebuilds from ids, and a no-match that explains itself."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from synth.kinds import OutputKind
from synth.mechanism.figures import sixbar_figures
from synth.mechanism.sixbar import SixBar, SixBars
from synth.mechanism.sixbar import simulate as simulate_motion
from synth.query import (
    CONSTRAINTS,
    DEEPER,
    PER_LEVEL,
    WIDER,
    QueryResult,
    RebuildError,
    SegmentSource,
    answer,
    fit,
    kinds_for,
    meets,
    rebuild,
    select,
    violations,
)
from synth.query.candidates import Request, screen

DEG = math.pi / 180


class Recorded:
    """A SegmentSource that replays what another one returned (no database): the stage needs
    nothing but the protocol."""

    def __init__(self, inner: SegmentSource) -> None:
        self.levels = inner.tolerance_levels()
        self.inner = inner
        self.rows: dict = {}

    def tolerance_levels(self):
        return self.levels

    def select_segments(self, kinds, windows, *, min_transmission, max_length, min_radius_ratio):
        key = (kinds, tuple(windows), min_transmission, max_length, min_radius_ratio)
        if key not in self.rows:
            self.rows[key] = self.inner.select_segments(
                kinds,
                windows,
                min_transmission=min_transmission,
                max_length=max_length,
                min_radius_ratio=min_radius_ratio,
            )
        return list(self.rows[key])

    def segment(self, segment_id, level):
        return self.inner.segment(segment_id, level)

    def nearest_dwell_angles(self, kinds, target):
        return (None, None)


def test_request_is_keyword_only_with_one_set_of_defaults():
    with pytest.raises(TypeError):
        Request(1.0, 2.0)  # the point of the test: positional arguments are refused
    r = Request(dwell=60 * DEG, swing=30 * DEG)
    assert (math.degrees(r.dwell_tol), math.degrees(r.swing_tol), r.output, r.top) == pytest.approx(
        (2.0, 0.5, "any", 10)
    )


def test_answer_through_any_source_is_the_same(source):
    request = Request(dwell=45 * DEG, swing=40 * DEG, output="rpr", top=5)
    direct = answer(request, source)
    replay = Recorded(source)
    again = answer(request, replay)
    assert isinstance(direct, QueryResult) and direct.candidates
    assert [c.id for c in again.candidates] == [c.id for c in direct.candidates]
    assert [c.figures.dwells for c in again.candidates] == [c.figures.dwells for c in direct.candidates]
    for c in direct.candidates:
        assert meets(request, c.figures)
        assert all(v == 0 for v in violations(request, c.figures).values())


def test_rebuild_gives_the_queried_six_bars(source):
    request = Request(dwell=60 * DEG, swing=30 * DEG, output="any", top=4)
    found = answer(request, source).candidates
    assert found
    again = rebuild([c.id for c in found], source, request)
    for a, b in zip(found, again, strict=True):
        assert a.id == b.id and a.sixbar == b.sixbar
        assert a.figures.dwells == b.figures.dwells and a.figures.swing == b.figures.swing
    with pytest.raises(RebuildError, match="no segment 999999999"):
        rebuild(["999999999-rpr0.0@30"], source, request)
    with pytest.raises(RebuildError, match="not a candidate id"):
        rebuild(["12-xyz0.0@30"], source, request)


@pytest.mark.parametrize(
    "output, dwell, tol, swing, dwells", [("rpr", 45, 8, 40, 1), ("rrr", 60, 8, 30, 1), ("rpr", 40, 15, 21.8, 2)]
)
def test_grid_screen_never_rejects_a_six_bar_that_meets_the_request(source, output, dwell, tol, swing, dwells):
    """``screen`` is a necessary test: every fitted six-bar whose full figures meet the request
    passes it (checked on all fits of real queries, with a wide dwell tolerance so that many
    meet), and it does reject a share of those that do not."""
    request = Request(
        dwell=dwell * DEG,
        dwell_tol=tol * DEG,
        swing=swing * DEG,
        swing_tol=2 * DEG,
        output=output,
        dwells=dwells,
        min_transmission=20 * DEG,
        max_link_ratio=30,
    )
    fitted = [f for kind in kinds_for(request) for f in fit(request, select(source, request, (kind,)), kind)]
    batch = SixBars.from_sixbars([f.sixbar() for f in fitted])
    passed = screen(request, batch)
    figures = sixbar_figures(batch, band=request.band, dwell_length=request.dwell, dwells=request.dwells)
    met = [meets(request, f) for f in figures]
    assert sum(met) >= 3, "the request should be answerable on the test atlas"
    assert all(passed[k] for k, m in enumerate(met) if m)
    assert sum(not p for p in passed) >= 0.2 * sum(not m for m in met)


@pytest.mark.parametrize(
    "output, ratio, clearance, arm", [("rpr", 4.0, 0.3, 0.5), ("rrr", 5.0, 0.4, 0.0), ("any", 6.0, 0.2, 0.3)]
)
def test_grid_screen_holds_the_figures_link_ratio_clearance_and_arm(source, output, ratio, clearance, arm):
    """On the figures' own grid the screen tests the link ratio, the clearance and the torque
    arm as the figures have them: every fitted six-bar whose figures miss one of them is
    rejected, none that meets the request is (tight limits, so that many miss them)."""
    request = Request(
        dwell=50 * DEG,
        dwell_tol=20 * DEG,
        swing=35 * DEG,
        swing_tol=10 * DEG,
        output=output,
        min_transmission=20 * DEG,
        max_link_ratio=ratio,
        min_clearance=clearance,
        min_arm=arm,
    )
    fitted = [f for kind in kinds_for(request) for f in fit(request, select(source, request, (kind,)), kind)]
    batch = SixBars.from_sixbars([f.sixbar() for f in fitted])
    passed = screen(request, batch)
    figures = sixbar_figures(batch, band=request.band, dwell_length=request.dwell)
    misses = [
        f.link_ratio > ratio or f.build.clearance < clearance or (f.build.arm is not None and f.build.arm < arm)
        for f in figures
    ]
    assert sum(misses) >= 10
    assert not any(p and m for p, m in zip(passed, misses))
    assert all(passed[k] for k, f in enumerate(figures) if meets(request, f))


def test_no_match_counts_rejections_and_loosens_to_the_nearest(source):
    """Nothing meets a 60°/30° RRR request held to a 0.01° dwell: every fitted six-bar is
    counted against the constraints it misses (checked one by one), and the request the
    no-match offers is met by the nearest six-bar's own figures."""
    request = Request(dwell=60 * DEG, dwell_tol=0.0, swing=30 * DEG, output="rrr", min_transmission=45 * DEG)
    result = answer(request, source)
    assert result.candidates == []
    nm = result.no_match
    assert nm is not None and nm.fitted > 0
    # the sample, then (refinement on, nothing met) the wider one's further rows, then the
    # deeper one's along the arcs' keys (the moved pivots' six-bars are not fits of the sample)
    fitted = []
    for kind in kinds_for(request):
        rows = select(source, request, (kind,))
        for per_level in (WIDER * PER_LEVEL, DEEPER * PER_LEVEL):
            seen = {(r.segment_id, r.level) for r in rows}
            rows += [r for r in select(source, request, (kind,), per_level) if (r.segment_id, r.level) not in seen]
        fitted += fit(request, rows, kind)
    assert nm.fitted == len(fitted)
    figures = sixbar_figures(
        SixBars.from_sixbars([f.sixbar() for f in fitted]),
        band=request.band,
        dwell_length=request.dwell,
        footprint=False,
    )
    expected = {k: sum(violations(request, f)[k] > 0 for f in figures) for k in CONSTRAINTS}
    assert nm.rejected == expected
    assert nm.failed == max(CONSTRAINTS, key=lambda k: (expected[k], -CONSTRAINTS.index(k)))
    assert nm.nearest is not None and not meets(request, nm.nearest.figures)
    assert meets(nm.would_meet, nm.nearest.figures)
    # the nearest six-bar's footprint as the full figures give it (the misses are simulated without)
    full = sixbar_figures(nm.nearest.sixbar, band=request.band, dwell_length=request.dwell)
    assert nm.nearest.figures.footprint == pytest.approx(full.footprint, rel=1e-12) and full.footprint > 0
    # only what the nearest six-bar missed is loosened
    missed = {k for k, x in violations(request, nm.nearest.figures).items() if x > 0}
    changed = {
        f.name for f in dataclasses.fields(Request) if getattr(request, f.name) != getattr(nm.would_meet, f.name)
    }
    field_of = {
        "dwell": {"dwell", "dwell_tol"},
        "swing": {"swing", "swing_tol"},
        "transmission": {"min_transmission"},
        "link_ratio": {"max_link_ratio"},
        "arm": {"min_arm"},
        "clearance": {"min_clearance"},
        "acceleration": {"max_accel"},
    }
    assert changed <= set().union(*(field_of[k] for k in missed))


def _no_match_requests():
    """Requests the test atlas's sample cannot meet, single and double dwells: a spread of
    dwells (within, at the edge of and outside the stored range) and tight tolerances."""
    out = [
        Request(dwell=d * DEG, dwell_tol=t * DEG, swing=s * DEG, output=o, refine=False)
        for o in ("rpr", "rrr", "any")
        for d, s, t in (
            (10, 10, 0.5),
            (30, 60, 2),
            (60, 30, 0.2),
            (75, 45, 0.5),
            (90, 90, 2),
            (120, 30, 2),
            (150, 20, 1),
            (180, 10, 2),
            (45, 90, 0.2),
            (105, 60, 0.5),
        )
    ]
    out += [
        Request(dwell=d * DEG, dwell_tol=5 * DEG, swing=20 * DEG, output="rpr", dwells=2, refine=False)
        for d in (10, 90)
    ]
    out.append(
        Request(dwell=60 * DEG, dwell_tol=0.0, swing=30 * DEG, output="rrr", min_transmission=45 * DEG, refine=False)
    )
    return out


def test_no_match_diagnosis_by_bounds_is_the_full_diagnosis(source, monkeypatch):
    """Without refinement a no-match is diagnosed from bounds on the dwell (``diagnose_by_bounds``):
    the same counts per constraint, the same nearest six-bar and the same request it would meet
    as the full diagnosis (every fitted six-bar's exact figures) — on ≥ 20 requests nothing in
    the sample meets — while most six-bars are never refined."""
    import synth.query as q
    from synth.query import diagnosis, evaluate, pipeline, refinement

    refined_rows, fitted_rows, refined_rows_single, cases, reaches = 0, 0, 0, 0, 0
    real_figures = evaluate.figures_of
    users = (evaluate, diagnosis, refinement)  # the modules that compute figures

    def counting(request, sixbars, footprint=True):
        nonlocal refined_rows
        refined_rows += len(sixbars)
        return real_figures(request, sixbars, footprint=footprint)

    for request in _no_match_requests():
        for module in users:
            monkeypatch.setattr(module, "figures_of", counting)
        refined_rows = 0
        fast = q.answer(request, source)
        refined_fast = refined_rows
        for module in users:
            monkeypatch.setattr(module, "figures_of", real_figures)
        if fast.no_match is None:
            continue
        monkeypatch.setattr(
            pipeline, "diagnose_by_bounds", lambda r, f, k=None: diagnosis.diagnose(r, f, diagnosis.misses_of(r, f, k))
        )
        full = q.answer(request, source)
        monkeypatch.undo()
        a, b = fast.no_match, full.no_match
        assert (a.fitted, a.rejected, a.would_meet) == (b.fitted, b.rejected, b.would_meet), request
        assert (a.nearest is None) == (b.nearest is None)
        # the constraint in the way and its figure (computed in another batch: to rounding)
        assert (a.reach is None) == (b.reach is None), request
        if a.reach is not None:
            reaches += 1
            assert a.reach[0] == b.reach[0] and a.reach[1:] == pytest.approx(b.reach[1:], rel=1e-12), request
        if a.nearest is not None:
            assert a.nearest.id == b.nearest.id
            # figures computed in another batch: equal to the last bits but for float rounding
            x, y = a.nearest.figures, b.nearest.figures
            assert [tuple(d) for d in x.dwells] == [pytest.approx(tuple(d), rel=1e-12, abs=1e-12) for d in y.dwells]
            assert (x.swing, x.transmission_fourbar, x.link_ratio) == pytest.approx(
                (y.swing, y.transmission_fourbar, y.link_ratio), rel=1e-12
            )
        cases += 1
        if request.dwells == 1:
            fitted_rows += a.fitted
            refined_rows_single += refined_fast
    assert cases >= 20 and reaches >= 10
    print(
        f"{cases} no-matches ({reaches} with a constraint in the way); single dwells: {refined_rows_single} of {fitted_rows} six-bars refined"
    )
    assert refined_rows_single < 0.5 * fitted_rows


def test_bounded_excess_is_violations_row_by_row(source):
    """The diagnosis's excesses from bounds, for a whole batch at once (``bounded_excess`` of
    ``figures_with_dwell_bounds``), are the very floats ``violations`` and ``total_excess`` give
    row by row on the full figures with the dwell at its bounds (the least excess: at the
    bound nearest the request) — every limit binding somewhere (arm, clearance, acceleration,
    link ratio, transmission, swing), six-bars that do not assemble or revolve among them."""
    from synth.mechanism.figures import figures_with_dwell_bounds
    from synth.mechanism.output_range import Dwell
    from synth.query.diagnosis import bounded_excess
    from synth.query.evaluate import dwell_excess, total_excess

    sixbars = []
    for output, dwell, swing in (("rpr", 45, 40), ("rrr", 60, 30), ("rpr", 90, 20), ("rrr", 30, 15)):
        req = Request(dwell=dwell * DEG, dwell_tol=10 * DEG, swing=swing * DEG, output=output, max_link_ratio=30)
        sixbars += [f.sixbar() for kind in kinds_for(req) for f in fit(req, select(source, req, (kind,)), kind)]
    # broken on purpose: RRR rockers too short to close the loop, slots pivoted inside the
    # coupler curve (the output revolves)
    rrr = [sb for sb in sixbars if sb.dyad.kind == OutputKind.RRR][:20]
    rpr = [sb for sb in sixbars if sb.dyad.kind == OutputKind.RPR][:20]
    sixbars += [SixBar.of(sb.fourbar, dataclasses.replace(sb.dyad, rocker=0.2 * sb.dyad.rocker)) for sb in rrr]
    centres = simulate_motion(SixBars.from_sixbars(rpr), np.linspace(0, 2 * math.pi, 72), order=0).z[0].mean(axis=1)
    sixbars += [SixBar.of(sb.fourbar, dataclasses.replace(sb.dyad, pivot=complex(c))) for sb, c in zip(rpr, centres)]
    batch = SixBars.from_sixbars(sixbars)
    full = sixbar_figures(batch, band=0.1 * DEG, samples=720, footprint=False)
    assert len(full) >= 100 and 0 < sum(f.acceptable for f in full) < len(full)
    for request in (
        Request(dwell=60 * DEG, swing=30 * DEG, min_transmission=40 * DEG, max_link_ratio=6, refine=False),
        Request(
            dwell=45 * DEG,
            swing=40 * DEG,
            min_transmission=40 * DEG,
            max_link_ratio=6,
            min_arm=1.0,
            min_clearance=0.5,
            max_accel=20.0,
            refine=False,
        ),
    ):
        rough = figures_with_dwell_bounds(batch, band=0.1 * DEG, samples=720, accel=request.max_accel is not None)
        least, most, low, high = bounded_excess(request, rough)
        nearest = np.minimum(np.maximum(request.dwell, rough.dwell_low), rough.dwell_high).tolist()
        binding = dict.fromkeys(CONSTRAINTS, 0)
        for k, f in enumerate(full):
            want = violations(request, dataclasses.replace(f, dwells=(Dwell(0.0, nearest[k], nearest[k]),)))
            assert {c: least[c][k] for c in CONSTRAINTS} == want, k
            worst = max(dwell_excess(request, rough.dwell_low[k]), dwell_excess(request, rough.dwell_high[k]))
            assert (most[k], low[k], high[k]) == (worst, total_excess(want), total_excess(dict(want, dwell=worst)))
            for c in CONSTRAINTS:
                binding[c] += want[c] > 0
        limits = ("assembly", "dwell", "swing", "transmission", "link_ratio")
        extra = ("arm", "clearance", "acceleration") if request.max_accel is not None else ()
        assert all(binding[c] > 0 for c in limits + extra), binding


def test_dwell_angle_bounds_hold_the_refined_dwell(source):
    """``dwell_angle_bounds`` (what the no-match diagnosis decides by) brackets the dwell that
    ``sixbar_figures`` refines on the exact path, for every acceptable six-bar the query fits
    to a spread of requests, and is narrow: 3.5 grid steps wide on average, at most 4 for 95 % of
    them (wider where ψ bends sharply between samples)."""
    from synth.mechanism.output_range import dwell_angle_bounds
    from synth.mechanism.sixbar import crank_grid, simulate

    sixbars = _fitted_sixbars(source, 10**6)
    assert len(sixbars) >= 300
    batch = SixBars.from_sixbars(sixbars)
    phi = crank_grid(720)
    motion = simulate(batch, phi, order=2)
    figs = sixbar_figures(batch, band=0.1 * DEG, samples=720, motion=motion, footprint=False)
    low, high = dwell_angle_bounds(phi, motion.psi, 0.1 * DEG, dpsi1=motion.dpsi[0])
    angle = np.array([f.dwells[0].angle for f in figs])
    h = 2 * math.pi / 720
    assert np.all(low <= angle) and np.all(angle <= high)
    assert np.percentile(high - low, 95) <= 4 * h + 1e-12 and np.mean(high - low) <= 3.5 * h


# ---------------------------------------------------------------------------------------------
# Exact dwell figures: the reported ends against a brute-force 0.001° crank grid
# ---------------------------------------------------------------------------------------------

FINE = 0.001  # degrees
END_TOL = 0.005  # degrees: how close each end must be to where the band breaks


def _fitted_sixbars(source, count):
    """Acceptable six-bars fitted by the query to its segments for a spread of requests."""
    out = []
    for output in ("rpr", "rrr"):
        for dwell, swing in ((30, 15), (45, 40), (60, 30), (75, 50), (90, 20), (120, 45)):
            req = Request(
                dwell=dwell * DEG,
                dwell_tol=10 * DEG,
                swing=swing * DEG,
                output=output,
                min_transmission=20 * DEG,
                max_link_ratio=30,
            )
            out += [f.sixbar() for kind in kinds_for(req) for f in fit(req, select(source, req, (kind,)), kind)]
    batch = SixBars.from_sixbars(out)
    figs = sixbar_figures(batch, band=0.1 * DEG, footprint=False)
    keep = [k for k, f in enumerate(figs) if f.acceptable and f.dwells and f.dwells[0].angle < 300 * DEG]
    rng = np.random.default_rng(13)
    return [out[k] for k in sorted(rng.choice(keep, size=min(count, len(keep)), replace=False))]


def test_dwell_ends_and_deviation_window_agree_with_a_brute_force_grid(source):
    """≥ 200 six-bars from the fit: on a 0.001° grid of the exact ψ (simulated there, nothing
    refined), each reported dwell interval holds the band, no window longer by 0.005° holds it
    anywhere on the turn, and neither end can be pushed out by 0.005°; the output deviation
    over a window around the dwell is the brute-force minimum over its placements."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    from synth.mechanism.sixbar import simulate

    sixbars = _fitted_sixbars(source, 220)
    assert len(sixbars) >= 200
    band = 0.1 * DEG
    batch = SixBars.from_sixbars(sixbars)
    figs = sixbar_figures(batch, band=band, footprint=False)
    lengths = np.array([0.8 * f.dwells[0].angle for f in figs])
    m = round(360 / FINE)
    phi = np.arange(m) * (FINE * DEG)
    worst = {"shorter": 0.0, "excess": 0.0, "deviation": 0.0}
    for k, sb in enumerate(sixbars):
        f = sixbar_figures(sb, band=band, dwell_length=lengths[k])
        psi = simulate(sb, phi, order=0).psi
        d = f.dwells[0]

        def spread(a, b):
            i = np.arange(math.ceil(a / (FINE * DEG) - 1e-9), math.floor(b / (FINE * DEG) + 1e-9) + 1)
            v = psi[i % m]
            return v.max() - v.min()

        worst["excess"] = max(worst["excess"], spread(d.start, d.end) - band)
        step = END_TOL * DEG
        for a, b in ((d.start - step, d.end), (d.start, d.end + step)):
            assert spread(a, b) > band, f"six-bar {k}: an end of {np.degrees([d.start, d.end])} can move {END_TOL}°"
        # the longest band on the grid: no cyclic window of angle + END_TOL within it
        n = math.floor((d.angle / DEG + END_TOL) / FINE) + 1
        longer = maximum_filter1d(psi, n, mode="wrap") - minimum_filter1d(psi, n, mode="wrap")
        assert longer.min() > band, f"six-bar {k}: a band longer than {math.degrees(d.angle):.4f}° exists"
        # how much shorter than the grid's longest (found by bisection on the window size)
        lo_n, hi_n = round(d.angle / DEG / FINE) - 10, n
        while lo_n < hi_n:
            mid = (lo_n + hi_n + 1) // 2
            ok = (maximum_filter1d(psi, mid, mode="wrap") - minimum_filter1d(psi, mid, mode="wrap")).min() <= band
            lo_n, hi_n = (mid, hi_n) if ok else (lo_n, mid - 1)
        worst["shorter"] = max(worst["shorter"], (lo_n - 1) * FINE * DEG - d.angle)
        # deviation: every placement [s, s + L] on the grid that contains the dwell's middle
        centre, L = 0.5 * (d.start + d.end), lengths[k]
        nL = round(L / (FINE * DEG)) + 1
        wide = maximum_filter1d(psi, nL, mode="wrap") - minimum_filter1d(psi, nL, mode="wrap")  # centred windows
        starts = np.arange(math.ceil((centre - L) / (FINE * DEG)), math.floor(centre / (FINE * DEG)) + 1)
        brute_dev = wide[(starts + nL // 2) % m].min()
        worst["deviation"] = max(worst["deviation"], abs(f.deviations[0] - brute_dev))
    print("worst vs the 0.001° grid (deg):", {k: math.degrees(v) for k, v in worst.items()})
    assert worst["excess"] <= 1e-6 * DEG
    assert worst["shorter"] <= END_TOL * DEG
    # a placement within ~0.004° of the best: the deviation within a thousandth of a degree
    assert worst["deviation"] <= 1e-3 * DEG


def test_pivots_around_a_fitted_pivot_are_at_the_stated_distances_nearest_first():
    """``pivots_around``: ``AROUND_STEPS`` × the reach (at least ``AROUND_MIN_REACH``),
    ``AROUND_DIRECTIONS`` evenly turned each."""
    from synth.mechanism.dyad import AROUND_DIRECTIONS, AROUND_MIN_REACH, AROUND_STEPS, pivots_around

    X = np.array([1 + 2j, 0.1 + 0j])
    got = pivots_around(X, np.array([4.0, 0.1]))
    assert got.shape == (2, len(AROUND_STEPS) * AROUND_DIRECTIONS)
    reach = np.array([4.0, AROUND_MIN_REACH])
    dist = np.abs(got - X[:, None])
    assert dist == pytest.approx(
        np.repeat(np.array(AROUND_STEPS)[None, :], AROUND_DIRECTIONS, axis=1) * reach[:, None], rel=1e-12
    )
    assert np.all(np.diff(dist, axis=1) >= -1e-12)  # nearest first
    turn = np.angle((got[:, 1:AROUND_DIRECTIONS] - X[:, None]) / (got[:, : AROUND_DIRECTIONS - 1] - X[:, None]))
    assert turn == pytest.approx(np.full(turn.shape, 2 * math.pi / AROUND_DIRECTIONS), rel=1e-12)


def _check_moved(request, source, result):
    """Every candidate of a reseated answer meets ``request`` — on a brute-force 0.01° grid
    too — its output pivot is off the fitted one, and a rebuild from its id gives the same
    six-bar and figures."""
    from synth.query import FILL

    assert len(result.candidates) >= FILL and result.reseated >= FILL and not result.from_misses
    for c in result.candidates:
        assert meets(request, c.figures) and "~" in c.id
        fitted = rebuild([c.id.split("~")[0]], source, request)[0].sixbar.dyad
        assert abs(c.sixbar.dyad.pivot - fitted.pivot) > 1e-3
        if fitted.kind == "RRR":  # the rocker and the rod kept (up to the id's float32 and refinement)
            assert c.sixbar.dyad.rocker == pytest.approx(fitted.rocker, rel=0.06)
            assert c.sixbar.dyad.rod == pytest.approx(fitted.rod, rel=0.06)
            # where Q rests: on the rocker's circle, at the rod's length from P mid-dwell
            d = c.figures.dwells[0]
            motion = simulate_motion(c.sixbar, np.array([0.5 * (d.start + d.end)]), order=0)
            assert abs(c.dwell_position - c.sixbar.dyad.pivot) == pytest.approx(c.sixbar.dyad.rocker, rel=1e-9)
            assert c.dwell_position == pytest.approx(complex(motion.moving_pivot[0]), abs=1e-9)
        again = rebuild([c.id], source, request)[0]
        assert again.sixbar == c.sixbar and again.figures.dwells == c.figures.dwells
        # each rest on a fine grid: the band holds over each reported interval
        for d in c.figures.dwells:
            phi = np.linspace(d.start, d.end, max(3, round(math.degrees(d.end - d.start) / 0.01)))
            psi = np.unwrap(simulate_motion(c.sixbar, np.mod(phi, 2 * math.pi), order=0).psi)
            assert psi.max() - psi.min() <= request.band + 1e-6 * DEG  # the ends' refinement, as above
            assert abs(d.angle - request.dwell) <= request.dwell_tol
        if request.swing is not None:
            assert abs(c.figures.swing - request.swing) <= request.swing_tol


@pytest.mark.parametrize("output, dwell, swing", [("rpr", 30, 10), ("rrr", 30, 10), ("any", 30, 10)])
def test_a_sparse_single_dwell_moves_the_output_pivot_off_the_fitted_one(source, output, dwell, swing):
    """Single dwells shorter than the sample's fits give (the test atlas's sample answers
    nothing): with the output pivot moved off the fitted one, they are met."""
    request = Request(dwell=dwell * DEG, swing=swing * DEG, output=output)
    assert not answer(dataclasses.replace(request, refine=False), source).candidates
    _check_moved(request, source, answer(request, source))


def test_a_sparse_double_dwell_moves_the_slot_pivot_off_the_crossing(source):
    """Two rests of 20° ± 5°: no crossing of the test atlas's sample gives them (its rests are
    longer). Refined, the slot pivots moved off the crossings do."""
    request = Request(dwell=20 * DEG, dwell_tol=5 * DEG, swing=8.5 * DEG, swing_tol=2 * DEG, dwells=2, output="rpr")
    assert not answer(dataclasses.replace(request, refine=False), source).candidates
    _check_moved(request, source, answer(request, source))


def test_a_sparse_answer_is_the_same_every_time(source):
    """RRR 105° ± 2° / 45° on the test atlas goes through every stage of a sparse answer (the
    wider sample, moved pivots, the deeper sample, refined near misses), which create and drop
    many fits. Asked four times in one process, it gives the same six-bars and figures: the
    figures kept for the diagnosis are keyed by the fit's id(), and a moved fit's figures kept
    once its id was reused made a later fit read them (4 different answers in 6 runs)."""
    request = Request(dwell=105 * DEG, dwell_tol=2 * DEG, swing=45 * DEG, output="rrr")
    answers = set()
    for _ in range(4):
        result = answer(request, source)
        assert result.reseated > 0 and result.misses_met > 0
        answers.add(
            tuple(
                (
                    c.id,
                    c.figures.dwells[0].angle,
                    c.figures.swing,
                    None if c.refined_from is None else c.refined_from.dwells[0].angle,
                )
                for c in result.candidates
            )
        )
    assert len(answers) == 1


@pytest.mark.parametrize(
    "met_per_round, wanted, rounds, output",
    [((2, 1), 3, 2, "any"), ((3, 0), 3, 1, "any"), ((0,), 1, "all", "rpr"), ((0,), 1, "all", "rrr")],
)
def test_nearest_misses_are_refined_a_round_at_a_time_until_enough_meet(
    monkeypatch, met_per_round, wanted, rounds, output
):
    """The nearest misses go to refinement MISSES at a time, nearest first, and another
    round runs only while fewer than ``wanted`` distinct six-bars meet the request, for at
    most MISS_ROUNDS rounds, ARC_MISS_ROUNDS for an RRR output (``rounds`` "all")."""
    import synth.query.refinement as Q

    if rounds == "all":
        rounds = Q.ARC_MISS_ROUNDS if output == "rrr" else Q.MISS_ROUNDS
        assert Q.ARC_MISS_ROUNDS < Q.MISS_ROUNDS
    met_per_round = (*met_per_round, *(0,) * Q.MISS_ROUNDS)
    pool = [_fake_candidate(i) for i in range(Q.MISS_ROUNDS * Q.MISSES + 5)]
    monkeypatch.setattr(Q, "miss_pool", lambda request, misses, taken, n: (pool[:n], [None] * min(n, len(pool))))
    calls = []

    def refined(request, part, figures, *, reach):
        calls.append([c.id for c in part])
        k = met_per_round[len(calls) - 1]
        return [dataclasses.replace(c, refined_from=() if j < k else None) for j, c in enumerate(part)], k

    monkeypatch.setattr(Q, "refined_candidates", refined)
    met, tried, better = Q.refined_misses(Request(dwell=60 * DEG, swing=30 * DEG, output=output), [], set(), wanted)
    assert len(calls) == rounds and tried == rounds * Q.MISSES and better == sum(met_per_round[:rounds])
    assert calls == [[c.id for c in pool[r * Q.MISSES : (r + 1) * Q.MISSES]] for r in range(rounds)]  # nearest first
    assert [c.id for c in met] == [
        c.id for r in range(rounds) for c in pool[r * Q.MISSES : r * Q.MISSES + met_per_round[r]]
    ]


def _fake_candidate(i: int):
    """A candidate of its own segment and four-bar (no two are mirror twins)."""
    from synth.mechanism.sixbar import OutputDyad, SixBar
    from synth.query import Candidate

    sixbar = SixBar(1.0, 2.0 + 0.01 * i, 3.0, 3.5, 1, 0.8, -0.6, OutputDyad.rpr(2 - 3j))
    return Candidate(id=f"{i}-rpr0.0@10", segment_id=i, sixbar=sixbar, figures=None, rank=0)
