"""The ids file of ``cli.shown_ids``: a short id resolves to its full id with the settings of
the last table that showed it; a line without settings (as older tables wrote) or with
damaged ones resolves with none, so ``dwell report`` falls back to its own options."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from cli.shown_ids import REPORT_SETTINGS, ids_file, remember, report_settings, resolve
from report.short_id import short_id
from synth.query.candidates import Request

FULL = "1234500007-rrr0.1@30"
SHORT = short_id(FULL)


@pytest.fixture(autouse=True)
def _own_ids_file(tmp_path_factory, monkeypatch):
    """This module rewrites the ids file: a folder of its own, not the session's."""
    monkeypatch.setenv("DWELL_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "shown-ids-tests"))


def test_the_last_table_s_settings_are_the_ones_resolved():
    request = Request.from_degrees(dwell=60, swing=30, band=0.002, crank=25.0, tolerance=0.1)
    first = report_settings(request, "mm")
    assert first["dwell"] == pytest.approx(60) and first["band"] == pytest.approx(0.002) and first["tolerance"] == 0.1
    assert remember([FULL], first) is None
    later = {**first, "band": 0.1, "units": "in"}
    assert remember([FULL], later) is None
    shown = resolve(SHORT)
    assert shown.full == FULL and shown.settings == later and set(shown.settings) == set(REPORT_SETTINGS)


def test_no_tolerance_is_kept_as_none():
    assert report_settings(Request.from_degrees(dwell=60, swing=30), "mm")["tolerance"] is None


@given(
    st.one_of(
        st.just(""),
        st.text(max_size=40),
        st.dictionaries(st.sampled_from(REPORT_SETTINGS), st.one_of(st.none(), st.floats(), st.text(max_size=5))),
    )
)
def test_damaged_settings_resolve_as_none_and_never_raise(damaged):
    path = ids_file()
    path.parent.mkdir(parents=True, exist_ok=True)
    field = damaged if isinstance(damaged, str) else json.dumps(damaged)
    path.write_text(f"{SHORT}\t{FULL}\t{field}\n")
    shown = resolve(SHORT)
    assert shown.full == FULL
    if shown.settings is not None:  # only a whole, finite set of the report's options is taken
        assert set(shown.settings) == set(REPORT_SETTINGS) and isinstance(shown.settings["units"], str)
        assert all(math.isfinite(v) for k, v in shown.settings.items() if k != "units" and v is not None)


def test_a_line_without_settings_resolves_with_none():
    path = ids_file()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"{SHORT}\t{FULL}\n")
    assert resolve(SHORT).settings is None
