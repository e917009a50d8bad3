"""An answer of fewer six-bars than the query fills up to (``synth.query.FILL``) names the one
constraint in the way of more, with a figure (``QueryResult.short_of``,
``synth.query.diagnosis.reach_beyond``): RPR 180° at a 90° swing on the test atlas answers one
six-bar, refined from a near miss; the other fitted six-bars that meet every other limit rest
129.7° at most."""

from __future__ import annotations

import dataclasses
import math

import pytest

from synth.query import FILL, answer
from synth.query.candidates import Request

DEG = math.pi / 180
REQUEST = Request(dwell=180 * DEG, swing=90 * DEG, output="rpr")


@pytest.fixture(scope="module")
def short(source):
    return answer(REQUEST, source)


def test_a_short_answer_names_the_dwell_in_the_way_with_a_figure_within_reach(short, source):
    assert 0 < len(short.candidates) < FILL and short.no_match is None
    ((output, constraint, best, limit),) = short.short_of
    assert (output, constraint, limit) == ("rpr", "dwell", pytest.approx(180))
    assert 90 < best < 178  # a rest, short of the 180° ± 2° asked
    # the figure is a fitted six-bar's: asked for that rest, the sample answers it unrefined
    at_best = answer(dataclasses.replace(REQUEST, dwell=best * DEG, refine=False), source)
    assert at_best.candidates
    assert any(abs(math.degrees(c.figures.dwells[0].angle) - best) < 0.01 for c in at_best.candidates)


def test_an_answer_that_is_not_short_names_nothing(source):
    assert answer(dataclasses.replace(REQUEST, top=1), source).short_of == ()


def test_any_names_each_output_type_s_constraint(short, source):
    both = answer(dataclasses.replace(REQUEST, output="any"), source)
    assert 0 < len(both.candidates) < FILL
    by_output = {s[0]: s[1:] for s in both.short_of}
    assert set(by_output) == {"rpr", "rrr"}
    assert by_output["rpr"] == short.short_of[0][1:]
    constraint, best, limit = by_output["rrr"]
    assert constraint == "dwell" and best < limit
