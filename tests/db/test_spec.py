"""db.spec: the one reader of a stored sweep spec."""

from __future__ import annotations

import json

import pytest

from atlas.sweep import PRESETS
from db.spec import SpecError, spec_name, stored_spec, tolerances


def test_a_written_spec_reads_back():
    spec = PRESETS["demo"]
    doc = stored_spec(spec.to_json())
    assert doc == json.loads(spec.to_json())
    assert tolerances(doc) == list(spec.tolerances) == [1e-4, 1e-3, 1e-2]
    assert spec_name(spec.to_json()) == "demo"


@pytest.mark.parametrize("text", ["", "[]", "nope", '{"tolerances": ["x"]}', '{"tolerances": [1e999]}',
                                  '{"tolerances": [NaN]}', '{"tolerances": 3}', "1"])
def test_an_unreadable_spec_is_refused(text):
    with pytest.raises(SpecError):
        stored_spec(text)
    assert spec_name(text) == "?"
