"""A batch of segment rows as columns (synth.query.segment_rows.SegmentBatch) spells out the rows it
was made of: every value, bit for bit, None where a part has no direction or radius."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from synth.linkage import CouplerFourBar
from synth.query.segment_rows import SegmentBatch, SegmentRow

finite = st.floats(-1e6, 1e6, allow_nan=False)


def _linkage(u: float = 0.0) -> CouplerFourBar:
    return CouplerFourBar(b=1.0, c=2.0, d=2.0, branch=1, u=u, v=0.5)


def _part(kind: str):
    """A stretch: an arc has a radius and no direction, a line the other way round."""
    if kind == "arc":
        return st.tuples(finite, finite, finite, finite, st.none(), st.floats(1e-3, 1e3))
    return st.tuples(finite, finite, finite, finite, st.floats(-math.pi, math.pi), st.none())


@st.composite
def rows_of_a_kind(draw):
    kind = draw(st.sampled_from(["line", "arc", "double_line"]))
    parts = st.lists(_part(kind), min_size=1, max_size=2 if kind == "double_line" else 1).map(tuple)
    row = st.builds(
        SegmentRow,
        segment_id=st.integers(1, 2**62),
        kind=st.just(kind),
        level=st.integers(0, 8),
        tolerance=st.floats(1e-6, 1.0),
        fourbar=st.builds(
            CouplerFourBar, b=finite, c=finite, d=finite, branch=st.sampled_from([1, -1]), u=finite, v=finite
        ),
        phi_gen=finite,
        parts=parts,
        fourbar_transmission_min=finite,
    )
    return kind, draw(st.lists(row, max_size=6))


@given(rows_of_a_kind())
@example(
    (
        "double_line",
        [SegmentRow(1, "double_line", 0, 1e-3, _linkage(u=-0.0), 0.1, ((0.0, 1.0, -0.0, 0.0, 0.3, None),), 0.5)],
    )
)  # one stretch, −0.0 kept
def test_a_batch_spells_out_its_rows(case):
    kind, rows = case
    batch = SegmentBatch.of_rows(rows, kind)
    assert len(batch) == len(rows) and list(batch) == rows and batch[:] == rows
    bits = lambda r: [
        x.hex() if isinstance(x, float) else x
        for x in (
            *(getattr(r.fourbar, f) for f in "bcduv"),
            r.fourbar.branch,
            r.phi_gen,
            *(y for p in r.parts for y in p),
        )
    ]
    assert [bits(r) for r in batch] == [bits(r) for r in rows]
    if rows:
        assert batch[-1] == rows[-1]
        assert batch.point(0).tolist() == [complex(r.parts[0][2], r.parts[0][3]) for r in rows]
        assert [(z.real.hex(), z.imag.hex()) for z in batch.coupler_point().tolist()] == [
            (r.fourbar.u.hex(), r.fourbar.v.hex()) for r in rows
        ]


def test_a_batch_holds_one_kind_and_says_which_rows_it_has():
    line = SegmentRow(1, "line", 0, 1e-3, _linkage(), 0.1, ((0.0, 1.0, 0.0, 0.0, 0.3, None),), 0.5)
    with pytest.raises(ValueError, match="one kind"):
        SegmentBatch.of_rows(
            [
                line,
                SegmentRow(2, "arc", 0, 1e-3, _linkage(), 0.1, ((0.0, 1.0, 0.0, 0.0, None, 2.0),), 0.5),
            ],
            "line",
        )
    batch = SegmentBatch.of_rows([line], "line")
    with pytest.raises(IndexError, match="row 1 of a batch of 1"):
        batch[1]
    assert np.isnan(batch.part(0, "radius")).all()
