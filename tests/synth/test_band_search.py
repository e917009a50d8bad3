"""The band search of ``--band auto`` (``synth.query.band_search``): the search rule on made-up
counts, then on the small demo atlas against a brute-force scan of the ladder's bands."""

from __future__ import annotations

import dataclasses
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from synth.query import answer
from synth.query.band_search import (
    FLOOR,
    LADDER,
    MEET,
    REFERENCE_BAND,
    RESOLUTION,
    BandProbe,
    answer_tightest,
    ladder,
    needed,
    probe,
    tightest_band,
)
from synth.query.candidates import Request

RPR_60 = Request(dwell=math.radians(60.0), swing=math.radians(30.0), output="rpr", refine=False)


def _counts(rule):
    """A probe function from ``rule(band in degrees) -> six-bars met``, and the probes it made."""
    made = []

    def count(band: float) -> BandProbe:
        made.append(band)
        return BandProbe(band, rule(math.degrees(band)))

    return count, made


@pytest.mark.parametrize("edge", [0.00321, 0.0123, 0.0999])
def test_monotone_counts_give_the_edge_within_the_resolution(edge):
    """Three six-bars meet at every band ≥ edge: the band found lies in [edge, edge·RESOLUTION]."""
    count, made = _counts(lambda b: 3 if b >= edge else 2)
    band, probes = tightest_band(RPR_60, count)
    assert edge <= math.degrees(band) <= edge * RESOLUTION
    # the ladder (19 rungs from 0.1° to 1e-4°) stops at the first rung that meets; the
    # bisection between two rungs (a factor 10^(1/6) = 1.47) takes one or two probes
    assert len(ladder(RPR_60.band, FLOOR)) == 3 * LADDER + 1
    assert len(probes) == len(made) <= 3 * LADDER + 1 + 2
    assert all(p.met == (3 if math.degrees(p.band) >= edge else 2) for p in probes)


def test_an_island_below_a_gap_is_found():
    """Counts that are not monotonic in the band: the tighter island (0.002°–0.003°) wins over
    the loose bands, although the bands between them (0.003°–0.05°) fail."""
    count, _ = _counts(lambda b: 3 if 0.002 <= b <= 0.003 or b >= 0.05 else 0)
    band, _ = tightest_band(RPR_60, count)
    assert 0.002 <= math.degrees(band) <= 0.003


def test_nothing_meets_and_top_lowers_the_count():
    count, made = _counts(lambda b: 2)
    band, probes = tightest_band(RPR_60, count)
    assert band is None and len(probes) == 3 * LADDER + 1  # every rung tried, none met
    assert needed(RPR_60) == MEET == 3
    two = dataclasses.replace(RPR_60, top=2)
    assert needed(two) == 2
    band, probes = tightest_band(two, count)
    assert band == pytest.approx(FLOOR) and len(probes) == 1  # the floor meets at once


@pytest.mark.parametrize(
    "request_",
    [
        RPR_60,
        Request(dwell=math.radians(40.0), swing=math.radians(20.0), output="rpr", top=2, refine=False),
    ],
    ids=["rpr-60-30", "rpr-40-20-top-2"],
)
def test_search_matches_a_scan_of_the_atlas(source, request_):
    """On the demo atlas: at the band found ≥ min(top, 3) six-bars meet; a scan of every
    ladder rung tighter than the band found finds none where as many meet; and a probe within
    a factor RESOLUTION below the band found failed."""
    need = needed(request_)
    band, probes = tightest_band(request_, lambda b: probe(request_, source, b))
    assert band is not None and band < request_.band
    assert probe(request_, source, band).met >= need
    tighter = [float(b) for b in ladder(request_.band, FLOOR) if b < band * (1 - 1e-9)]
    assert len(tighter) >= 6 and all(probe(request_, source, b).met < need for b in tighter)
    failed_below = [p.band for p in probes if p.band < band]
    assert failed_below and band / max(failed_below) <= RESOLUTION
    assert all(p.met < need for p in probes if p.band < band)


@pytest.mark.parametrize("band_deg", [0.1, 0.01, 0.0001])
def test_a_probe_counts_what_the_query_answers(source, band_deg):
    """A probe (which skips the no-match's stored-dwell look-up) counts the six-bars the
    unrefined query itself returns at that band, cut to min(top, 3)."""
    request = dataclasses.replace(RPR_60, output="any", band=math.radians(band_deg))
    full = answer(request, source)
    assert probe(request, source, request.band).met == min(len(full.candidates), needed(request))
    assert band_deg != 0.0001 or (not full.candidates and full.nearest != (None, None))


def test_answer_at_the_band_reached(source):
    """The answer is the request at the band reached: each candidate's dwell there within
    60° ± 2°, and at the reference band 0.1° (wider) a longer dwell of the same six-bar."""
    found = answer_tightest(RPR_60, source)
    assert found.settled and found.band < math.radians(0.02)
    result = found.result
    assert result.request.band == found.band and len(result.candidates) >= 3
    assert len(found.reference_dwells) == len(result.candidates)
    for c, ref in zip(result.candidates, found.reference_dwells):
        here = c.figures.dwells[0].angle
        assert abs(math.degrees(here) - 60.0) <= 2.0 + 1e-9
        assert ref and ref[0] > here + math.radians(5.0)  # a 0.1° band holds far more than 0.01°
    assert REFERENCE_BAND == math.radians(0.1)


@settings(max_examples=200, deadline=None)
@given(islands=st.lists(st.tuples(st.floats(-4.0, -1.0), st.floats(0.0, 1.5)), max_size=4), top=st.integers(1, 5))
def test_the_rule_on_any_counts(islands, top):
    """Counts made of islands [10^x, 10^(x+w)] (degrees) where enough six-bars meet: the band
    found meets; no ladder rung tighter than it does; a failing probe lies within a factor
    RESOLUTION below it; with no island the search says none."""
    request = dataclasses.replace(RPR_60, top=top)
    need = needed(request)

    def met(b: float) -> int:
        return need if any(10**x <= b <= 10 ** (x + w) for x, w in islands) else need - 1

    count, _ = _counts(met)
    band, probes = tightest_band(request, count)
    rungs = [float(r) for r in ladder(request.band, FLOOR)]
    if band is None:
        assert all(met(math.degrees(r)) < need for r in rungs)
        return
    assert met(math.degrees(band)) >= need
    assert all(met(math.degrees(r)) < need for r in rungs if r < band * (1 - 1e-9))
    below = [p.band for p in probes if p.band < band]
    assert not below or band / max(below) <= RESOLUTION * (1 + 1e-9)
    assert below or band == pytest.approx(FLOOR)
