"""A sparse answer's near misses include the lines a far slot pivot predicts
(``synth.query.pipeline._far_slot_fits``, ``synth.query.windows.LONG_REACHES``): the long
rests' six-bars (RPR 180° at a 20° or 30° swing on ``standard``) are refined from them."""

from __future__ import annotations

import math

import pytest

from synth.kinds import SegmentKind
from synth.query import Request, answer
from synth.query.fitting import fit
from synth.query.windows import LONG_REACHES, PER_LEVEL, REACHES, select

DEG = math.pi / 180


class _Recording:
    """``source`` that records the windows :func:`select` asks it for."""

    def __init__(self, source):
        self.source, self.windows = source, []

    def tolerance_levels(self):
        return self.source.tolerance_levels()

    def select_segments(self, kinds, windows, **limits):
        self.windows += list(windows)
        return self.source.select_segments(kinds, windows, **limits)


def test_a_longer_slot_targets_a_shorter_stored_dwell(source):
    """At every level the line window for a slot of reach R targets the stored dwell
    dwell·(ε/(R·band/2))^¼ (the output's band is a path band R·band/2 wide at the stretch):
    the longer slots of LONG_REACHES target shorter stored dwells than REACHES' longest."""
    request = Request(dwell=180 * DEG, swing=30 * DEG, output="rpr")
    recording = _Recording(source)
    select(recording, request, (SegmentKind.LINE,), PER_LEVEL, LONG_REACHES)
    windows = recording.windows[1:]  # the first: the request's own
    levels = source.tolerance_levels()
    assert len(windows) == len(levels) * len(LONG_REACHES)
    for w, ((level, eps), reach) in zip(windows, [(lv, r) for lv in levels for r in LONG_REACHES]):
        assert w.level == level
        assert w.target == pytest.approx(request.dwell * (eps / (reach * request.band / 2)) ** 0.25, rel=1e-12)
    for level, eps in levels:
        mine = {w.target for w in windows if w.level == level}
        assert min(mine) < request.dwell * (eps / (max(REACHES) * request.band / 2)) ** 0.25


def test_a_sparse_answer_refines_the_far_slot_lines_as_near_misses(source, monkeypatch):
    """RPR 150°/30° on the test atlas is sparse: the misses refined toward it hold every fit
    of the lines the far slots' windows select that the sample (narrow and wider) did not
    read."""
    from synth.query import pipeline

    request = Request(dwell=150 * DEG, swing=30 * DEG, output="rpr")
    offered: list[set] = []
    real = pipeline.refined_misses

    def spy(request, misses, taken, wanted):
        offered.append({m[1].key for m in misses})
        return real(request, misses, taken, wanted)

    monkeypatch.setattr(pipeline, "refined_misses", spy)
    answer(request, source)
    assert offered, "the answer was not sparse: no near misses were refined"
    near = {
        (r.segment_id, r.level)
        for per_level in (PER_LEVEL, pipeline.WIDER * PER_LEVEL)
        for r in select(source, request, (SegmentKind.LINE,), per_level)
    }
    far = [
        r
        for r in select(source, request, (SegmentKind.LINE,), pipeline.WIDER * PER_LEVEL, LONG_REACHES)
        if (r.segment_id, r.level) not in near
    ]
    far_fits = {f.key for f in fit(request, far, SegmentKind.LINE)}
    assert far_fits, "no line of the far slots' windows fits here: the test says nothing"
    assert far_fits <= offered[0]
