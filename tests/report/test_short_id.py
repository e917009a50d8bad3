"""Short candidate ids (report/short_id.py): at most 24 characters, a pure function of the full
id, different for different ids."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from report.short_id import MAX_LENGTH, SHORT_ID, short_id
from synth.query.candidate_ids import candidate_id

#: A refined RRR id as the query prints it (standard atlas, RRR 60°/30°).
REFINED = "991900016-rrr1.2@30~BkCQh0U__OzUQJiDoECCWatAU0AkwA64VUEPfUs_pehpQNDG0A"


def test_known_values():
    """Fixed values: a short id shown once stays valid in every later version."""
    assert short_id("2947500003-rrr0.2@30") == "2947500003-rrr-k3lap"
    assert short_id(REFINED) == "991900016-rrr-e2f2y"
    assert short_id("33600000-rpr0.1@40~AUCClSpAEJO6QIyoqEAjGUA93nxwQGTCfL_ASUk") == "33600000-rpr-b3ae7"


@given(
    segment=st.integers(1, 2**63 - 1),
    output=st.sampled_from(["rpr", "rrr", "dbl"]),
    slot=st.integers(0, 99),
    level=st.integers(0, 99),
    swing=st.one_of(st.none(), st.floats(0.01, 179.99).map(lambda d: d * 3.141592653589793 / 180)),
    refined=st.one_of(
        st.just(""),
        st.text("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_", min_size=39, max_size=50).map(
            lambda t: "~" + t
        ),
    ),
)
def test_every_id_gets_a_short_one_of_at_most_24_characters(segment, output, slot, level, swing, refined):
    full = candidate_id(segment, output, slot, level, swing) + refined
    sid = short_id(full)
    assert len(sid) <= MAX_LENGTH and SHORT_ID.fullmatch(sid)
    assert sid.split("-")[0] == str(segment)[-14:] and sid.split("-")[1] == output
    assert short_id(full) == sid  # a pure function


def test_different_ids_get_different_short_ids():
    """179 swings of one segment, and one character of a refined id changed."""
    assert len({short_id(f"2947500003-rrr0.2@{s}") for s in range(1, 180)}) == 179
    assert short_id(REFINED) != short_id(REFINED[:-1] + "B")


@pytest.mark.parametrize("text", ["rrr-12", "", "-rpr0.1@40", "12-xyz0.1@40"])
def test_not_an_id(text):
    with pytest.raises(ValueError):
        short_id(text)
