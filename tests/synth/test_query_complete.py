"""The complete search (``synth.query.search``) against a brute-force reference, and its
monotonicity.

The reference fits every stored segment of a small atlas at every tolerance level with no
filter at all (not the linkage's transmission angle or link lengths, not the arc's radius),
computes the full figures of every fitted six-bar (no screen) and keeps those that meet the
request: the search, which prunes by those filters and by two screens on exact samples, must
give the same set of six-bar ids — for 42 requests over RPR, RRR and double dwells. Then:
loosening any limit of a request never removes a six-bar from the set that meets it, and a
sweep with more linkages never answers fewer requests.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import pytest

from synth import query as Q
from synth.query.candidates import Request

#: The small atlas of these tests: the demo sweep on 64 Sobol samples.
SAMPLES = 64
#: Dwell angles (°) asked of each family of requests below.
DWELLS = (20, 30, 40, 50, 60, 70, 80, 90, 100, 110, 120, 130, 140, 150)
#: Request families: the fit depends only on these fields (swing, output, dwells, the RRR's
#: minimum transmission), the figures on the band; the dwell is varied over DWELLS.
FAMILIES = {
    "rpr": Request(dwell=1.0, swing=math.radians(40.0), output="rpr", refine=False),
    "rrr": Request(dwell=1.0, swing=math.radians(30.0), output="rrr", max_link_ratio=20.0, refine=False),
    # two dwells name their swing (issue #41): the test atlas's double dwells that meet the
    # default limits swing 135°–155° (rests of 24°–56°, 3 000–6 000 rad/s² at 60 rpm)
    "double": Request(
        dwell=1.0,
        dwell_tol=math.radians(10.0),
        swing=math.radians(145.0),
        swing_tol=math.radians(10.0),
        dwells=2,
        output="rpr",
        refine=False,
    ),
}


def _build(tmp_path_factory, samples: int):
    from atlas.build import build_atlas
    from atlas.sweep import PRESETS
    from db.engine import open_atlas
    from db.queries import AtlasSource

    path = str(tmp_path_factory.mktemp("complete") / f"demo{samples}.sqlite")
    build_atlas(path, PRESETS["demo"].replace(samples=samples), workers=1)
    return AtlasSource(open_atlas(path, readonly=True))


@pytest.fixture(scope="module")
def atlas(tmp_path_factory):
    source = _build(tmp_path_factory, SAMPLES)
    yield source
    source.engine.dispose()


def _every_fit(source, request: Request) -> list:
    """(fitted dyad, figures) of every segment of the request's kinds at every level, unfiltered."""
    out = []
    for kind in Q.kinds_for(request):
        for level, _ in source.tolerance_levels():
            rows = source.select_segments(
                (kind,),
                [Q.DwellWindow(level, 0.0, 1e300, 0.0, Q.ALL_ROWS)],
                min_transmission=0.0,
                max_length=1e300,
                min_radius_ratio=0.0,
            )
            fitted = Q.fit(request, rows, kind)
            out += zip(fitted, Q.figures_of(request, [f.sixbar() for f in fitted], footprint=False))
    return out


def _meeting(request: Request, every: list) -> set[str]:
    return {Q.candidate_of(request, f, fig).id for f, fig in every if Q.meets(request, fig)}


@pytest.fixture(scope="module")
def reference(atlas):
    """Per family, every fitted six-bar of the atlas with its figures."""
    return {name: _every_fit(atlas, req) for name, req in FAMILIES.items()}


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_the_search_finds_every_six_bar_the_brute_force_finds(atlas, reference, family):
    answered = 0
    for dwell in DWELLS:
        request = dataclasses.replace(FAMILIES[family], dwell=math.radians(dwell))
        expected = _meeting(request, reference[family])
        found, count = Q.search(request, atlas)
        assert {c.id for c in found} == expected, (family, dwell)
        assert count.met == len(found) and count.rows >= len({c.segment_id for c in found})
        answered += bool(expected)
    assert answered >= 3, (
        f"{family}: only {answered} of {len(DWELLS)} requests have an answer: the test checks too little"
    )


def test_the_query_ranks_the_complete_set(atlas, reference):
    """``answer`` with ``complete``: the ranked best of the search's six-bars, one per segment
    and output type and one of a mirror pair, as from the reference."""
    request = dataclasses.replace(FAMILIES["rpr"], dwell=math.radians(50.0), top=1000, complete=True)
    met = [f for f, fig in reference["rpr"] if Q.meets(request, fig)]
    # the ranking reads the footprint, which the reference's figures leave out
    figures = Q.figures_of(request, [f.sixbar() for f in met])
    expected = [
        c.id for c in Q.distinct(Q.rank(request, [Q.candidate_of(request, f, fig) for f, fig in zip(met, figures)]))
    ]
    result = Q.answer(request, atlas)
    assert expected and [c.id for c in result.candidates] == expected
    assert [c.rank for c in result.candidates] == list(range(1, len(expected) + 1))


def test_the_search_on_worker_processes_answers_as_in_one(atlas):
    """Batches evaluated on a pool of two processes (in completion order) give the same
    ranked candidates, figures and counts as in this process, in order."""
    from atlas.pool import pool_map

    pool = functools.partial(pool_map, workers=2, preload=("synth.query",))
    for family, dwell in (("rpr", 50.0), ("rrr", 60.0)):
        request = dataclasses.replace(FAMILIES[family], dwell=math.radians(dwell), top=1000, complete=True)
        here, there = Q.answer(request, atlas), Q.answer(request, atlas, map_batches=pool)
        assert here.candidates, f"{family}: nothing to compare"
        assert there.candidates == here.candidates
        assert (there.considered, there.simulated) == (here.considered, here.simulated)


def test_requests_that_share_their_fits_are_answered_as_one_by_one(atlas):
    """:func:`search_many` (one walk, each row fitted once) gives every request of one swing
    the same six-bars and counts as its own :func:`search`; requests that fit differently
    are refused."""
    for family in ("rpr", "rrr", "double"):
        requests = [dataclasses.replace(FAMILIES[family], dwell=math.radians(d)) for d in (40.0, 60.0, 90.0)]
        together = Q.search_many(requests, atlas)
        alone = [Q.search(r, atlas) for r in requests]
        assert sum(len(found) for found, _ in alone) > 0, f"{family}: nothing to compare"
        for (found, count), (found1, count1) in zip(together, alone):
            assert sorted(c.id for c in found) == sorted(c.id for c in found1)
            assert count == count1
    with pytest.raises(ValueError, match="same kinds, swing"):
        Q.search_many([FAMILIES["rpr"], dataclasses.replace(FAMILIES["rpr"], swing=math.radians(30.0))], atlas)


#: Each limit loosened: a looser request must keep every six-bar.
LOOSER = {
    "dwell_tol": lambda r: r.dwell_tol + math.radians(2.0),
    "swing_tol": lambda r: r.swing_tol + math.radians(1.5),
    "min_transmission": lambda r: r.min_transmission - math.radians(10.0),
    "max_link_ratio": lambda r: 1.5 * r.max_link_ratio,
    "min_arm": lambda r: 0.25 * r.min_arm,
    "min_clearance": lambda r: 0.2 * r.min_clearance,
    "max_accel": lambda r: 1e9,
}


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_loosening_a_limit_never_removes_a_six_bar(atlas, reference, family):
    base = dataclasses.replace(FAMILIES[family], max_accel=100.0 if family != "double" else 10_000.0)
    # the RRR fit depends on the minimum transmission: with a looser one it is fitted afresh
    refitted = (
        _every_fit(atlas, dataclasses.replace(base, min_transmission=LOOSER["min_transmission"](base)))
        if family == "rrr"
        else reference[family]
    )
    checked = 0
    for dwell in DWELLS:
        request = dataclasses.replace(base, dwell=math.radians(dwell))
        strict = _meeting(request, reference[family])
        for field, looser in LOOSER.items():
            if field == "swing_tol" and family == "double":
                continue  # two dwells: --swing-tol is also the least motion between the rests (issue #41)
            loose = dataclasses.replace(request, **{field: looser(request)})
            every = refitted if field == "min_transmission" else reference[family]
            missing = strict - _meeting(loose, every)
            assert not missing, (family, dwell, field, sorted(missing)[:5])
            checked += len(strict)
    assert checked > 0


def test_a_superset_sweep_never_answers_fewer_requests(atlas, tmp_path_factory):
    """The 32-sample sweep's linkages are the first ones of the 64-sample sweep (Sobol
    points): every request the smaller atlas answers, the larger one answers too."""
    small = _build(tmp_path_factory, SAMPLES // 2)
    try:
        answered = {"small": 0, "large": 0}
        for name in ("rpr", "double"):
            for dwell in (30, 50, 70, 90):
                request = dataclasses.replace(FAMILIES[name], dwell=math.radians(dwell))
                got_small = bool(Q.search(request, small)[0])
                got_large = bool(Q.search(request, atlas)[0])
                assert got_large or not got_small, (name, dwell)
                answered["small"] += got_small
                answered["large"] += got_large
        assert answered["small"] >= 2
    finally:
        small.engine.dispose()
