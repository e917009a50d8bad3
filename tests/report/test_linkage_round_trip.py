"""The linkage file is the candidate (docs/linkage-files.md): for every candidate of the
coverage bench's grid (``cli/bench/coverage.py``: RPR and RRR single dwells, RPR double
dwells), its linkage file read back and analysed as ``dwell analyze linkage FILE --limits``
does with no other option gives the candidate's swing (1e-4°), dwell ends (0.01°) and smallest
transmission angles (1e-3°).

The grid is answered by the complete search (``--complete``: the best ``--top`` of every
six-bar the atlas yields) on a small atlas of the demo sweep, so that its few hundred
linkages give several hundred six-bars; the same check over the ``standard`` atlas is
``tests/report/measure_linkage_round_trip.py``.
"""

from __future__ import annotations

from collections import Counter

import pytest
from linkage_checks import Agreement, round_trip

#: The small atlas: the demo sweep on fewer samples (fewer linkages), and the six-bars kept per cell.
SAMPLES = 384
TOP = 7
#: Double dwells (dwell °, swing °) at the demo's swing tolerance (±2°), beside the grid's ±5°-dwell
#: row: the grid's swings of 20° and 45° are out of this small atlas's reach for two rests.
DEMO_DOUBLES = ((50, 12), (60, 12), (60, 6))


@pytest.fixture(scope="module")
def grid_answers(tmp_path_factory):
    """(cell, request, candidates) for every cell of the coverage grid."""
    from atlas.build import build_atlas
    from atlas.sweep import PRESETS
    from cli.bench.coverage import cells
    from db.engine import open_atlas
    from db.queries import AtlasSource
    from synth.query import Request, answer, fit_key, search_many

    path = str(tmp_path_factory.mktemp("grid") / "small.sqlite")
    build_atlas(path, PRESETS["demo"].replace(samples=SAMPLES), workers=1)
    engine = open_atlas(path, readonly=True)
    try:
        source = AtlasSource(engine)
        from cli.bench.coverage import DOUBLE_TOL, Cell

        grid = cells()
        requests = [cell.request(TOP, refine=False, complete=True) for cell in grid]
        for dwell, swing in DEMO_DOUBLES:
            grid.append(Cell("double", dwell, swing))
            requests.append(
                Request.from_degrees(
                    dwell=dwell,
                    dwell_tol=DOUBLE_TOL,
                    swing=swing,
                    swing_tol=2,
                    output="rpr",
                    dwells=2,
                    top=TOP,
                    refine=False,
                    complete=True,
                )
            )
        groups: dict[tuple, list[int]] = {}
        for k, request in enumerate(requests):
            groups.setdefault(fit_key(request), []).append(k)  # the cells of one walk of the atlas
        found = {}
        for members in groups.values():
            for k, searched in zip(members, search_many([requests[k] for k in members], source)):
                found[k] = answer(requests[k], source, searched=searched).candidates
    finally:
        engine.dispose()
    return [(grid[k], requests[k], found[k]) for k in range(len(grid))]


def test_every_candidate_of_the_coverage_grid_is_its_linkage_file(grid_answers):
    agreement = Agreement()
    families: Counter = Counter()
    for cell, request, candidates in grid_answers:
        round_trip(candidates, request, agreement=agreement)
        families[cell.family] += len(candidates)
    assert not agreement.failures, agreement.failures[:5]
    assert agreement.checked == sum(families.values()) >= 500, families
    assert families["rpr"] >= 200 and families["rrr"] >= 150 and families["double"] >= 10, families
    assert agreement.swing <= 1e-4 and agreement.dwell_end <= 0.01 and agreement.transmission <= 1e-3
    # the file's configuration key matters: without it, these would be analysed as another mechanism
    assert sum(n for number, n in agreement.configurations.items() if number != 1) >= 100, agreement.configurations
