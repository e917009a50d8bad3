"""``Request.from_degrees``: the one way to build a request from the command's units, and
Request's errors naming its fields."""

from __future__ import annotations

import dataclasses
import math

import pytest

from synth.query.candidates import DEGREE_FIELDS, Request


def test_from_degrees_converts_the_angles_and_leaves_the_rest():
    r = Request.from_degrees(
        dwell=60.0, dwell_tol=5.0, swing=12.0, swing_tol=2.0, band=0.05, min_transmission=40.0, step=10.0, dwells=2,
        output="rpr", top=3, crank=2.5, max_link_ratio=20.0, rpm=120.0, max_accel=500.0, tolerance=0.01,
    )  # fmt: skip
    assert r == Request(
        dwell=math.radians(60.0),
        dwell_tol=math.radians(5.0),
        swing=math.radians(12.0),
        swing_tol=math.radians(2.0),
        band=math.radians(0.05),
        min_transmission=math.radians(40.0),
        step=math.radians(10.0),
        dwells=2,
        output="rpr",
        top=3,
        crank=2.5,
        max_link_ratio=20.0,
        rpm=120.0,
        max_accel=500.0,
        tolerance=0.01,
    )
    assert math.degrees(r.dwell) == pytest.approx(60.0, abs=1e-12) and r.crank == 2.5


def test_none_takes_the_field_default():
    names = [f.name for f in dataclasses.fields(Request) if f.name not in ("dwell", "swing")]
    r = Request.from_degrees(dwell=45.0, swing=30.0, **dict.fromkeys(names))
    assert r == Request(dwell=math.radians(45.0), swing=math.radians(30.0))
    assert r.dwell_tol == math.radians(2.0) and r.band == math.radians(0.1) and r.top == 10 and r.refine


def test_the_degree_fields_are_fields():
    assert DEGREE_FIELDS <= {f.name for f in dataclasses.fields(Request)}


@pytest.mark.parametrize(
    ("given", "message"),
    [
        (
            {"dwell": 0.5, "swing": 30.0},
            "`dwell` must be at least 1° (the simulation samples the turn every 0.5°), got 0.5",
        ),
        ({"dwell": 60.0}, "`swing` is required"),
        ({"dwell": 60.0, "swing": 30.0, "swing_tol": 200.0}, "`swing_tol` must be between 0 and 180 degrees, got 200"),
        (
            {"dwell": 60.0, "swing": 30.0, "dwells": 2, "step": 50.0},
            "`step` 50 is more than `swing` 30 (± `swing_tol`)",
        ),
        ({"dwell": 60.0, "swing": 30.0, "min_arm": -1.0}, "`min_arm` must be a length in cranks >= 0, got -1"),
    ],
)
def test_errors_name_the_fields(given, message):
    with pytest.raises(ValueError) as raised:
        Request.from_degrees(**given)
    assert message in str(raised.value) and "--" not in str(raised.value)


def test_the_shortest_dwell_is_one_degree():
    assert Request.from_degrees(dwell=1.0, swing=30.0).dwell == math.radians(1.0)
    with pytest.raises(ValueError, match="`dwell` must be at least"):
        Request(dwell=math.radians(0.999), swing=math.radians(30.0))


def test_an_unknown_name_is_a_type_error():
    with pytest.raises(TypeError):
        Request.from_degrees(dwell=60.0, swing=30.0, swing_tolerance=1.0)
