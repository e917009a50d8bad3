"""A report of several candidates drawn on worker processes (``cli.report_pool``) is the report
drawn in the driver: the same files, the same bytes (plots, drawings, page, data)."""

from __future__ import annotations

import pytest

from atlas.build import build_atlas
from atlas.sweep import PRESETS
from cli.query import answer
from cli.report_pool import PARALLEL_FROM, report_pool, reports_pool
from db.engine import open_atlas
from report.export import write_report
from synth.query.candidates import Request

#: Files whose bytes a report fixes (the PNG's and DXF's carry the time they were made).
FIXED = {".json", ".csv", ".txt", ".html", ".toml", ".svg"}


@pytest.fixture(scope="module")
def candidates(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("atlas") / "small.sqlite")
    build_atlas(path, PRESETS["demo"].replace(samples=256), workers=1)
    engine = open_atlas(path, readonly=True)
    request = Request.from_degrees(dwell=45, swing=40, output="rpr", top=5)
    try:
        found = answer(engine, request).candidates
    finally:
        engine.dispose()
    assert len(found) >= PARALLEL_FROM
    return request, found


def test_a_report_drawn_on_worker_processes_is_the_one_drawn_in_the_driver(tmp_path, candidates):
    request, found = candidates
    pool = report_pool(len(found), workers=2)
    assert pool is not None
    here = write_report(found, request, tmp_path / "here")
    ticks = []
    there = write_report(
        found, request, tmp_path / "pool", map_candidates=pool, on_candidate=lambda done, n: ticks.append((done, n))
    )
    assert [p.name for p in there] == [p.name for p in here]
    fixed = [(a, b) for a, b in zip(here, there) if a.suffix in FIXED]
    assert len(fixed) >= 3 + 4 * len(found)  # the data files, and per candidate three plots' SVG and a drawing
    for a, b in fixed:
        assert a.read_bytes() == b.read_bytes(), a.name
    assert ticks == [(k, len(found)) for k in range(1, len(found) + 1)]


def test_a_few_candidates_or_one_core_are_drawn_in_the_driver():
    assert report_pool(PARALLEL_FROM - 1, workers=8) is None
    assert report_pool(10, workers=1) is None
    assert report_pool(PARALLEL_FROM, workers=2) is not None


def test_several_reports_drawn_on_one_pool_are_the_ones_drawn_in_the_driver(tmp_path, candidates):
    """``dwell demo``'s three reports share one pool (``reports_pool``): two reports of part of
    the candidates each, drawn on it, equal those drawn in the driver."""
    request, found = candidates
    halves = [[*found[:2]], [*found[2:4]]]
    with reports_pool(4, workers=2) as draw:
        assert draw is not None
        there = [
            write_report(part, request, tmp_path / f"pool{k}", map_candidates=draw) for k, part in enumerate(halves)
        ]
    for k, (part, files) in enumerate(zip(halves, there)):
        here = write_report(part, request, tmp_path / f"here{k}")
        assert [p.name for p in files] == [p.name for p in here]
        for a, b in zip(here, files):
            if a.suffix in FIXED:
                assert a.read_bytes() == b.read_bytes(), a.name
    with reports_pool(PARALLEL_FROM - 1, workers=8) as draw:
        assert draw is None
    with reports_pool(9, workers=1) as draw:
        assert draw is None
