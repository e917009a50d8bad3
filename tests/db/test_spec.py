"""db.spec: the one reader of a stored sweep spec."""

from __future__ import annotations

import json
import re

import pytest

from atlas.sweep import PRESETS
from db.spec import SPEC_RANGES, SpecError, spec_name, stored_spec, tolerances


def test_a_written_spec_reads_back():
    spec = PRESETS["demo"]
    doc = stored_spec(spec.to_json())
    assert doc == json.loads(spec.to_json())
    assert tolerances(doc) == list(spec.tolerances) == [1e-4, 1e-3, 1e-2]
    assert spec_name(spec.to_json()) == "demo"


@pytest.mark.parametrize(
    "text",
    [
        "",
        "[]",
        "nope",
        '{"tolerances": ["x"]}',
        '{"tolerances": [1e999]}',
        '{"tolerances": [NaN]}',
        '{"tolerances": 3}',
        "1",
    ],
)
def test_an_unreadable_spec_is_refused(text):
    with pytest.raises(SpecError):
        stored_spec(text)
    assert spec_name(text) == "?"


def test_the_ranges_are_the_sweeps():
    """db does not import atlas: its copy of the sweep's bounds must stay equal to them."""
    from atlas import sweep

    assert SPEC_RANGES["samples"] == sweep.SAMPLES_RANGE and SPEC_RANGES["rays"] == sweep.RAYS_RANGE
    assert SPEC_RANGES["shard_size"] == sweep.SHARD_SIZE_RANGE
    assert SPEC_RANGES["crank_step_deg"] == sweep.CRANK_STEP_RANGE_DEG
    assert SPEC_RANGES["proportion"] == sweep.PROPORTION_RANGE and SPEC_RANGES["tolerance"] == sweep.TOLERANCE_RANGE


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_every_preset_reads_back(preset):
    assert stored_spec(PRESETS[preset].to_json())["name"] == preset


@pytest.mark.parametrize(
    ("field", "value", "words"),
    [
        ("samples", "many", "samples is 'many'"),
        ("samples", 1e308, "samples is 1e+308"),
        ("samples", 0, "samples is 0"),
        ("samples", True, "samples is True"),
        ("samples", 2**31 + 1, "not a whole number"),
        ("seed", -1, "seed is -1"),
        ("shard_size", 0.5, "shard_size is 0.5"),
        ("rays", None, "rays is None"),
        ("crank_step_deg", "2", "crank_step_deg"),
        ("b", [4.0, 1.0], "low above high"),
        ("c", [1.0], "not a range"),
        ("d", [1.0, 1e999], "d is inf"),
        ("tolerances", [0.01, 0.001], "do not increase"),
        ("tolerances", [0.0], "tolerances is 0.0"),
        ("branches", [2], "branches"),
        ("crank_rockers_only", 1, "crank_rockers_only"),
        ("name", 5, "name is 5"),
        ("min_dwell_deg", -1, "min_dwell_deg"),
    ],
)
def test_a_spec_field_of_the_wrong_type_or_out_of_range_is_named(field, value, words):
    doc = json.loads(PRESETS["demo"].to_json())
    doc[field] = value
    with pytest.raises(SpecError, match=re.escape(words)):
        stored_spec(json.dumps(doc))
