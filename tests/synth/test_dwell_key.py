"""The arc's dwell key (``synth.segment_search.dwell_key``): its closed forms, what the atlas stores, and that
it orders arcs by the RRR dwell they give far better than the stored dwell does."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.stats import spearmanr
from sqlalchemy import select as sql_select

from db.schema import Dwell
from kinematics.fourbar import fourbar_motion
from synth import query as Q
from synth.kinds import SegmentKind
from synth.query.candidates import Request
from synth.segment_search.dwell_key import arc_dwell_key, arc_key_target, predicted_rrr_dwell

DEG = math.pi / 180


@given(
    dwell=st.floats(1 * DEG, 350 * DEG),
    swing=st.floats(0.5 * DEG, 179 * DEG),
    band=st.floats(1e-4, 0.2),
    tolerance=st.floats(1e-6, 0.1),
)
def test_the_target_key_predicts_the_requested_dwell(dwell, swing, band, tolerance):
    key = arc_key_target(dwell, swing, band, tolerance)
    assert key > 0
    assert predicted_rrr_dwell(key, swing, band, tolerance) == pytest.approx(dwell, rel=1e-12)


def test_the_key_is_the_dwell_times_the_excursions_fourth_root():
    assert arc_dwell_key(2.0, 16.0, 1e-3) == pytest.approx(4.0, rel=1e-15)
    # an excursion under the tolerance is the fine grid's sampling: the tolerance stands for it
    assert arc_dwell_key(1.0, 0.0, 1e-4) == pytest.approx(0.1, rel=1e-12)
    # a four-times wider swing at a sixteen-times looser level asks for the same key
    assert arc_key_target(1.0, 2 * math.asin(0.4), 1e-3, 1e-4) == pytest.approx(
        arc_key_target(1.0, 2 * math.asin(0.1), 1e-3, 4e-4), rel=1e-12
    )


def _arc_rows(source, level: int):
    rows = [
        r
        for b in source.scan_segments(
            "arc", level, min_transmission=30 * DEG, max_length=10.0, min_radius_ratio=0.1, batch=100_000
        )
        for r in b
    ]
    with source.engine.connect() as conn:
        keys = dict(
            conn.execute(
                sql_select(Dwell.segment_id, Dwell.dwell_key).where(
                    Dwell.kind == SegmentKind.ARC.code, Dwell.level == level
                )
            ).all()
        )
    return rows, keys


def test_stored_keys_are_the_rows_dwell_and_excursion(source):
    """Every arc row's stored key, against its excursion recomputed independently: the coupler
    path on a 0.1° grid, its farthest distance from the row's circle (the build samples the
    search's fine grid, so the two differ by that sampling only)."""
    phi = np.arange(3600) * (2 * np.pi / 3600)
    for level, tolerance in source.tolerance_levels():
        rows, keys = _arc_rows(source, level)
        assert len(rows) > 100
        b, c, d = (np.array([getattr(r.fourbar, n) for r in rows])[:, None] for n in "bcd")
        m = fourbar_motion(1.0, b, c, d, phi, np.array([r.fourbar.branch for r in rows])[:, None], order=0)
        z = m.A + m.e_theta * np.array([complex(r.fourbar.u, r.fourbar.v) for r in rows])[:, None]
        centre = np.array([complex(r.parts[0][2], r.parts[0][3]) for r in rows])[:, None]
        radius = np.array([r.parts[0][5] for r in rows])[:, None]
        excursion = np.abs(np.abs(z - centre) - radius).max(axis=1)
        dwell = np.array([r.parts[0][1] - r.parts[0][0] for r in rows])
        stored = np.array([keys[r.segment_id] for r in rows])
        # the build's grid (1.5° here) is a subset of this one: its key is never larger, and
        # short of it by the sampling of a sharp turn at most (measured ≤ 0.3 %)
        exact = arc_dwell_key(dwell, excursion, tolerance)
        assert np.all(stored <= exact * (1 + 1e-12)) and np.all(stored >= exact * 0.99)


@pytest.mark.parametrize("swing_deg", [20, 45])
def test_the_key_predicts_the_rrr_dwell_the_stored_dwell_does_not(source, swing_deg):
    """Every other arc row of the small atlas fitted with an RRR output for the swing and simulated:
    ranked by the predicted dwell, the six-bars' dwells follow it (Spearman ρ ≥ 0.8 at the
    finest level, where the ¼-power law is measured from, and above the stored dwell's by ≥ 0.1
    there and ≥ 0.5 at the coarser levels, where the stored dwell alone is anti-correlated:
    measured ρ 0.87 against 0.63–0.73 at level 0, 0.48–0.60 against −0.26…−0.43 at 1,
    0.13–0.14 against −0.40 at 2). The prediction is a little long (median actual/predicted
    0.83–0.88 at level 0): the rocker the fit finds is near the shortest the
    swing allows."""
    request = Request(dwell=60 * DEG, swing=swing_deg * DEG, output="rrr")
    for level, tolerance in source.tolerance_levels():
        rows, keys = _arc_rows(source, level)
        fits = Q.fit(request, rows[::2], "arc")  # every other row: ~750 six-bars are plenty
        figures = Q.figures_of(request, [f.sixbar() for f in fits], footprint=False)
        dwell = np.array([fig.dwells[0].angle if fig.dwells else 0.0 for fig in figures])
        rocks = dwell > 0
        assert np.count_nonzero(rocks) > 400
        key = np.array([keys[f.row.segment_id] for f in fits])[rocks]
        stored = np.array([f.row.parts[0][1] - f.row.parts[0][0] for f in fits])[rocks]
        predicted = predicted_rrr_dwell(key, request.swing, request.band, tolerance)
        by_key, by_stored = spearmanr(predicted, dwell[rocks])[0], spearmanr(stored, dwell[rocks])[0]
        if level == 0:
            assert by_key >= max(0.8, by_stored + 0.1)
            assert 0.7 <= np.median(dwell[rocks] / predicted) <= 1.0
        else:
            assert by_key >= by_stored + 0.5
