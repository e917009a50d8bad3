"""The band search of ``--band auto`` (``synth.query.band_search``): the narrowest band a run of
samples stands in (``least_bands``) against a brute force, the bands the sweep checks against a
brute-force count of intervals, then the search on the small demo atlas: at the band reached
enough six-bars meet the request by an independent simulation, and no band of a fine ladder
well below it holds as many six-bars of the search's pool."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from synth.mechanism.figures import sixbar_figures
from synth.mechanism.output_range import least_bands
from synth.mechanism.sixbar import SixBars
from synth.query import answer, rebuild
from synth.query.band_search import (
    DETUNE_PER_DECADE,
    FLOOR,
    MEET,
    REFERENCE_BAND,
    answer_tightest,
    covered_bands,
    detune_bands,
    detuned,
    dwell_bands,
    ladder,
    needed,
    pool,
    probe,
    still_six_bars,
    sweep,
)
from synth.query.candidate_ids import dimension_vector
from synth.query.candidates import Request
from synth.query.evaluate import distinct, figures_of, meets
from synth.query.refine import stiller

RPR_60 = Request(dwell=math.radians(60.0), swing=math.radians(30.0), output="rpr", refine=False)


def _brute_least_band(row: np.ndarray, width: int) -> float:
    M = len(row)
    turns = np.concatenate([row, row])
    return min(float(np.ptp(turns[j : j + width])) for j in range(M))


@settings(max_examples=150, deadline=None)
@given(
    rows=hnp.arrays(float, st.tuples(st.integers(1, 4), st.integers(2, 40)), elements=st.floats(-3.0, 3.0)),
    data=st.data(),
)
@example(rows=np.array([[0.0, 1.0, 0.0, 1.0]]), data=None)
def test_least_bands_is_the_smallest_range_of_any_cyclic_run(rows, data):
    """Per row and width, the smallest max − min over every run of that many consecutive samples,
    cyclic over the turn (a brute force over every start)."""
    M = rows.shape[1]
    widths = [1, M, 2] if data is None else data.draw(st.lists(st.integers(1, M), min_size=1, max_size=3))
    widths = [w for w in widths if w <= M]
    got = least_bands(rows, widths)
    assert got.shape == (rows.shape[0], len(widths))
    for r, row in enumerate(rows):
        closed = abs(row[-1] - row[0]) < math.pi
        for k, w in enumerate(widths):
            assert got[r, k] == (_brute_least_band(row, w) if closed else math.inf)


def test_leastdwell_bands_an_output_that_revolves_is_infinite():
    psi = np.stack([np.linspace(0.0, 2 * math.pi, 720, endpoint=False), np.sin(np.linspace(0, 2 * math.pi, 720))])
    got = least_bands(psi, [1, 100])
    assert np.all(np.isinf(got[0])) and got[1, 0] == 0.0 and 0 < got[1, 1] < 2
    with pytest.raises(ValueError, match="does not fit"):
        least_bands(psi, [721])


@settings(max_examples=200, deadline=None)
@given(
    intervals=st.lists(st.tuples(st.floats(-6.5, -1.0), st.floats(0.0, 3.0)), max_size=12),
    need=st.integers(1, 4),
    extra=st.lists(st.floats(-7.0, -0.5), max_size=4),
)
def test_covered_bands_are_every_band_enough_intervals_cover(intervals, need, extra):
    """The bands yielded, tightest first, are exactly the candidate bands (the six-bars' own,
    widened by the margin, the ladder and the extra bands, clipped to [floor, ceiling]) at
    which ≥ need of the intervals [lo, hi) are live, each with those intervals."""
    ceiling = math.radians(0.1)
    lo = np.array([10.0**x for x, _ in intervals])
    hi = np.array([10.0 ** (x + w) for x, w in intervals])
    more = [10.0**x for x in extra]
    got = list(covered_bands(lo, hi, need, ceiling, extra=more))
    bands = [b for b, _ in got]
    assert bands == sorted(set(bands))
    candidates = sorted(
        {
            *np.clip(lo * 1.01, FLOOR, ceiling).tolist(),
            *ladder(ceiling, FLOOR).tolist(),
            *np.clip(more, FLOOR, ceiling).tolist(),
        }
    )
    expected = [b for b in candidates if np.count_nonzero((lo <= b) & (b < hi)) >= need]
    assert bands == pytest.approx(expected, rel=1e-12)
    for b, live in got:
        assert set(live.tolist()) == set(np.flatnonzero((lo <= b) & (b < hi)).tolist())


def test_the_ladder_runs_from_ceiling_to_floor():
    rungs = ladder(math.radians(0.1), FLOOR)
    assert (
        len(rungs) == 3 * 6 + 1 and rungs[0] == pytest.approx(math.radians(0.1)) and rungs[-1] == pytest.approx(FLOOR)
    )
    assert len(ladder(math.radians(0.1), FLOOR, 2)) == 7
    assert needed(RPR_60) == MEET == 3 and needed(dataclasses.replace(RPR_60, top=2)) == 2


@pytest.mark.parametrize("refine", [False, True], ids=["pool", "stiller"])
def test_the_band_reached_holds_enough_six_bars(source, refine):
    """At the band reached, ≥ 3 of the answer's six-bars meet the request by a simulation of
    their own (the figures worked out afresh at that band); each one's dwell there is within
    60° ± 2° and at the 0.1° reference band longer; the band is far below 0.1°. With refinement
    on, the stiller rests make the band no looser than the pool's alone."""
    request = dataclasses.replace(RPR_60, refine=refine)
    found = answer_tightest(request, source)
    assert found.settled and found.band < math.radians(0.02)
    result = found.result
    assert result.request.band == found.band and len(result.candidates) >= 3
    at = dataclasses.replace(request, band=found.band)
    figures = sixbar_figures(
        SixBars.from_sixbars([c.sixbar.scaled(1.0 / request.crank) for c in result.candidates]),
        band=found.band,
        dwell_length=request.dwell,
        samples=720,
        footprint=False,
        leave=request.swing_tol,
    )
    assert sum(meets(at, f) for f in figures) >= 3
    for c, ref in zip(result.candidates, found.reference_dwells):
        here = c.figures.dwells[0].angle
        assert abs(math.degrees(here) - 60.0) <= 2.0 + 1e-9
        assert ref and ref[0] > here + math.radians(5.0)
    assert REFERENCE_BAND == math.radians(0.1)
    if refine:
        assert found.band <= answer_tightest(RPR_60, source).band * (1 + 1e-12)


def test_no_band_well_below_the_one_reached_holds_enough_of_the_pool(source):
    """A scan of the pool: at every band of a 12-per-decade ladder below the band reached by
    more than a factor 1.2 (the grid's own band and the exact dwell differ by a sample or
    two), fewer than 3 distinct six-bars of the pool meet the request (exact figures)."""
    still, _ = still_six_bars(RPR_60, pool(RPR_60, source))
    band, met, probes = sweep(RPR_60, still)
    assert band is not None and len(distinct(met)) >= 3 and probes[-1].band == band and probes[-1].met >= 3
    sixbars = [s.sixbar for s in still]
    for b in ladder(RPR_60.band, FLOOR, 12):
        if b < band / 1.2:
            at = dataclasses.replace(RPR_60, band=float(b))
            meeting = [s for s, f in zip(still, figures_of(at, sixbars, footprint=False)) if meets(at, f)]
            assert len({s.fitted.row.segment_id for s in meeting}) < 3


@pytest.mark.parametrize("band_deg", [0.1, 0.01, 0.0001])
def test_a_probe_counts_what_the_query_answers(source, band_deg):
    """A probe (which skips the no-match's stored-dwell look-up) counts the six-bars the
    unrefined query itself returns at that band, cut to min(top, 3)."""
    request = dataclasses.replace(RPR_60, output="any", band=math.radians(band_deg))
    full = answer(request, source)
    assert probe(request, source, request.band).met == min(len(full.candidates), needed(request))
    assert band_deg != 0.0001 or (not full.candidates and full.nearest != (None, None))


@pytest.fixture(scope="module")
def stiller_rests(source):
    """The request, its pool's still six-bars, and the four stillest with their stiller
    versions (``refine.stiller``): (request, still, [(six-bar, its stiller SixBar)])."""
    request = dataclasses.replace(RPR_60, refine=True)
    still, figures = still_six_bars(request, pool(request, source))
    order = sorted(range(len(still)), key=lambda i: still[i].lowest)[:4]
    at = dataclasses.replace(request, band=still[order[0]].lowest)
    moved = stiller(at, [still[i].sixbar for i in order], [figures[i] for i in order])
    return request, still, [(still[i], sb) for i, sb in zip(order, moved) if sb is not still[i].sixbar]


def test_stiller_rests_are_stiller_and_keep_every_other_constraint(source, stiller_rests):
    """The search's stillest-rest step (``refine.stiller``) on the pool's four stillest
    six-bars: every six-bar it moves still meets every band-free constraint and its rest needs
    a band no wider than before (a run of dwell − tol on the grid); most get markedly stiller."""
    request, _, changed = stiller_rests
    assert len(changed) >= 3
    kept, _ = still_six_bars(request, [s.fitted for s, _ in changed], [sb for _, sb in changed], moved=True)
    assert len(kept) == len(changed)
    before = np.array([s.lowest for s, _ in changed])
    after, _ = dwell_bands(request, [sb for _, sb in changed])
    assert np.all(after <= before * 1.001) and np.count_nonzero(after < 0.8 * before) >= 2
    # a moved six-bar's id carries its dimensions: a report rebuilds that six-bar from the id
    at = dataclasses.replace(request, band=kept[0].lowest * 1.01)
    c = kept[0].candidate(at, figures_of(at, [kept[0].sixbar], footprint=False)[0])
    (back,) = rebuild([c.id], source, at)
    assert back.id == c.id and c.sixbar.scaled(1.0) == kept[0].sixbar
    assert np.allclose(dimension_vector(back.sixbar), dimension_vector(kept[0].sixbar), rtol=0, atol=1e-12)


def test_detuned_rests_lie_between_a_fit_and_its_stiller_version_and_meet_at_their_bands(stiller_rests):
    """Each six-bar the detuning returns lies on the straight line of dimensions from a fit to
    its stiller version (to the float32 of an id), strictly between them, and its own bands
    (a fresh run of the grid's measure) hold one of the bands it was detuned to; the bands run
    from the one the third stillest rest needs (with the margin), twelve per decade, below the
    request's band."""
    request, still, changed = stiller_rests
    moved, _ = still_six_bars(request, [s.fitted for s, _ in changed], [sb for _, sb in changed], moved=True)
    pairs = [(s, m) for s, _ in changed for m in moved if m.fitted.key == s.fitted.key]
    bands = detune_bands(request, [*still, *moved])
    third = sorted(s.lowest for s in distinct(sorted([*still, *moved], key=lambda s: s.lowest)))[2]
    assert bands[0] == pytest.approx(third * 1.01, rel=1e-12) and np.all(bands < request.band)
    assert np.allclose(np.diff(np.log10(bands)), 1 / DETUNE_PER_DECADE)
    found = detuned(request, pairs, bands)
    assert len(found) >= len(pairs)
    lowest, highest = dwell_bands(request, [f.sixbar for f in found])
    for f, lo, hi in zip(found, lowest, highest):
        start, end = next((s, m) for s, m in pairs if m.fitted.key == f.fitted.key)
        p0, p1, p = (np.array(dimension_vector(x.sixbar)) for x in (start, end, f))
        t = np.dot(p - p0, p1 - p0) / np.dot(p1 - p0, p1 - p0)
        assert 0 < t < 1 and np.allclose(p, p0 + t * (p1 - p0), rtol=1e-6, atol=1e-6)
        assert f.moved and (f.lowest, f.highest) == (lo, hi)
        assert np.any((lo <= bands) & (bands < hi))
