"""A no-match that fitted no six-bar names the transmission angle as in its way only with a
figure below the limit (``synth.query.diagnosis.unfitted_reach``): the best the sample's
segments reach with their output dyads fitted without the limit, or, when the sample held no
segment, the best stored four-bar's. Before, a request whose segments exist but whose swing no
rocker transmits (RRR 60° at a 179° swing) was told the four-bars' 65° stood in the way of 30°."""

from __future__ import annotations

import dataclasses
import math

import pytest

from synth.query import answer
from synth.query.candidates import Request

DEG = math.pi / 180


@pytest.mark.parametrize("swing", [170, 179])
def test_a_swing_no_rocker_transmits_names_the_dyads_best_transmission(source, swing):
    request = Request(dwell=60 * DEG, swing=swing * DEG, output="rrr", refine=False)
    result = answer(request, source)
    nm = result.no_match
    assert not result.candidates and result.considered > 0 and nm.fitted == 0
    constraint, best, limit = nm.reach
    assert (constraint, nm.reach_among, limit) == ("transmission", "fitted without the limit", pytest.approx(30))
    assert 0 < best < limit
    # the figure is within reach: asked a limit a degree below it, the sample fits six-bars
    # (its rows may differ: the sample takes the four-bars the limit allows)
    looser = answer(dataclasses.replace(request, min_transmission=(best - 1) * DEG), source)
    assert looser.candidates or looser.no_match.fitted > 0


def test_a_sample_without_segments_names_the_best_four_bar(source):
    request = Request(dwell=10 * DEG, swing=30 * DEG, output="rrr", refine=False)
    result = answer(request, source)
    nm = result.no_match
    assert result.considered == 0 and nm.fitted == 0
    constraint, best, limit = nm.reach
    assert (constraint, nm.reach_among) == ("transmission", "four-bars")
    assert 0 < best < limit


def test_a_slot_that_cannot_swing_so_far_blames_no_transmission(source):
    # an RPR fit has no transmission limit: when its segments fit no slot, the swing is in the
    # way, and no figure of the transmission (the old code named the four-bars' 56.8°, above 30°)
    result = answer(Request(dwell=60 * DEG, swing=179 * DEG, output="rpr", refine=False), source)
    nm = result.no_match
    assert not result.candidates and result.considered > 0 and nm.fitted == 0
    assert nm.reach is None
