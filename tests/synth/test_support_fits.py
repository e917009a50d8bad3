"""The near misses of a short rest at a small swing (synth.query.support_fits): which
requests ask for them, and that the fits are slotted rockers on the atlas's lines whose rests
sit at the support point and whose swing is the request's."""

from __future__ import annotations

import math

import numpy as np

from synth.query import Request
from synth.query.candidate_ids import candidate_dimensions
from synth.query.evaluate import candidate_of, figures_of
from synth.query.support_fits import GRID_POINTS, support_fits, wants_support_fits

DEG = math.pi / 180


def test_which_requests_want_them():
    # a harmonic output of a 10° swing rests 23.0° within 0.1°, of 20° 16.2°, of 60° 9.4°
    assert wants_support_fits(Request(dwell=10 * DEG, swing=10 * DEG, output="rpr"))
    assert wants_support_fits(Request(dwell=16 * DEG, swing=20 * DEG, output="rpr"))
    assert not wants_support_fits(Request(dwell=17 * DEG, swing=20 * DEG, output="rpr"))
    assert not wants_support_fits(Request(dwell=10 * DEG, swing=60 * DEG, output="rpr"))
    assert not wants_support_fits(Request(dwell=10 * DEG, swing=10 * DEG, output="rrr"))
    assert not wants_support_fits(Request(dwell=10 * DEG, swing=10 * DEG, output="rpr", dwells=2))
    assert support_fits(Request(dwell=60 * DEG, swing=10 * DEG, output="rpr"), source=None) == []


def test_fits_swing_as_asked_and_rest_short(source):
    request = Request(dwell=10 * DEG, swing=10 * DEG, output="rpr")
    fits = support_fits(request, source)
    assert fits, "the test atlas's lines give support-point fits"
    assert {f.row.kind for f in fits} == {"line"} and all(f.moved for f in fits)
    assert all(np.isclose(GRID_POINTS, complex(f.row.fourbar.u, f.row.fourbar.v)).any() for f in fits)
    figures = figures_of(request, [f.sixbar() for f in fits], footprint=False)
    ok = [f for f in figures if f.acceptable and f.dwells]
    assert len(ok) >= 0.9 * len(fits)
    swing = np.array([f.swing for f in ok])
    assert np.abs(swing - request.swing).max() < 1.01 * DEG  # the reach found on the samples: within 10 %
    rest = np.array([f.dwells[0].angle for f in ok])
    # the far-field test is first order: the exact rests are short, not the ~23° a harmonic
    # output of that swing has, for most
    assert np.median(rest) < 23 * DEG


def test_a_grid_fit_is_its_id(source):
    """A fit at a grid point sits on a line's row of its four-bar with the grid's coupler point:
    the candidate's id carries that point, so the six-bar rebuilt from the id is the fit's."""
    request = Request(dwell=10 * DEG, swing=10 * DEG, output="rpr")
    fit_ = support_fits(request, source)[0]
    (figures,) = figures_of(request, [fit_.sixbar()], footprint=False)
    rebuilt = candidate_dimensions(candidate_of(request, fit_, figures).id)
    sixbar = fit_.sixbar()
    assert rebuilt is not None
    assert np.allclose(
        [rebuilt.u, rebuilt.v, rebuilt.b, rebuilt.c, rebuilt.d],
        [sixbar.u, sixbar.v, sixbar.b, sixbar.c, sixbar.d],
        rtol=1e-6,
    )
    assert abs(rebuilt.dyad.pivot - sixbar.dyad.pivot) < 1e-5 * abs(sixbar.dyad.pivot)
