"""``--output any`` with one dwell is the best of both output types (``synth.query.answer``):
its answer is the best ``--top`` of the union of the RPR and RRR answers to the same request,
ranked once by :func:`synth.query.candidates.rank` (Pareto layer over the union, score, id)."""

from __future__ import annotations

import dataclasses
import math

import pytest

from synth.query import CONSTRAINTS, answer, scaled_figures, total_excess, violations
from synth.query.candidates import Request, rank

DEG = math.pi / 180


def _both(request: Request, source):
    """The request answered as RPR and as RRR."""
    return tuple(answer(dataclasses.replace(request, output=o), source) for o in ("rpr", "rrr"))


def _best_of_union(request: Request, rpr, rrr):
    """The best ``request.top`` of the union of two answers, ranked from 1."""
    return rank(request, [*rpr.candidates, *rrr.candidates])[: request.top]


def _key(c):
    """What a candidate is and shows: id, rank and figures."""
    f = c.figures
    return (
        c.id,
        c.rank,
        tuple(tuple(d) for d in f.dwells),
        f.swing,
        f.deviations,
        f.transmission_fourbar,
        f.transmission_output,
        f.link_ratio,
        f.footprint,
    )


#: Sampled requests on the test atlas, without refinement (cheap): dwells 30–150°, swings
#: 10–90°, tight and loose limits, --top 3 to 10. With the next four refined: ≥ 20 in all.
PLAIN = [
    Request(dwell=d * DEG, swing=s * DEG, dwell_tol=t * DEG, min_transmission=m * DEG, top=k, refine=False)
    for d, s, t, m, k in (
        (30, 10, 2, 30, 10),
        (45, 20, 2, 30, 10),
        (45, 40, 2, 45, 5),
        (60, 30, 2, 30, 10),
        (60, 30, 0.5, 30, 3),
        (60, 60, 2, 30, 10),
        (75, 45, 2, 40, 10),
        (75, 50, 1, 30, 6),
        (90, 30, 2, 30, 10),
        (90, 45, 2, 45, 10),
        (90, 90, 2, 30, 10),
        (105, 45, 2, 30, 8),
        (105, 20, 2, 30, 10),
        (120, 30, 2, 30, 10),
        (120, 60, 3, 35, 10),
        (150, 20, 2, 30, 10),
        (30, 60, 2, 30, 4),
        (60, 10, 2, 30, 10),
    )
]
#: Refined requests: a full answer, a sparse one (the moved pivots and the refined near misses
#: of each output type fill it), the regression of issue #41 and a small --top.
REFINED = [
    Request(dwell=60 * DEG, swing=30 * DEG, top=10),
    Request(dwell=30 * DEG, swing=10 * DEG, top=10),
    Request(dwell=90 * DEG, swing=45 * DEG, min_transmission=45 * DEG, top=10),
    Request(dwell=75 * DEG, swing=45 * DEG, top=3),
]


@pytest.fixture(scope="module")
def answered(source):
    """Per request: the ``any`` answer and the RPR and RRR answers."""
    return [(r, answer(r, source), *_both(r, source)) for r in PLAIN + REFINED]


def test_any_is_the_best_top_of_the_union_of_rpr_and_rrr(answered):
    """On 22 requests, ``any``'s candidates (ids, ranks, figures) are exactly the best
    ``--top`` of the union of the RPR and RRR answers; its counts are theirs added."""
    assert len(answered) >= 20
    mixed = cut = 0
    for request, either, rpr, rrr in answered:
        best = _best_of_union(request, rpr, rrr)
        assert [_key(c) for c in either.candidates] == [_key(c) for c in best], request
        assert [c.rank for c in either.candidates] == list(range(1, len(best) + 1))
        assert (either.considered, either.simulated) == (rpr.considered + rrr.considered, rpr.simulated + rrr.simulated)
        assert either.refined == (rpr.refined[0] + rrr.refined[0], rpr.refined[1] + rrr.refined[1])
        kinds = {c.sixbar.dyad.kind for c in either.candidates}
        mixed += kinds == {"RPR", "RRR"}
        cut += len(rpr.candidates) + len(rrr.candidates) > request.top
    # the union is taken for real: answers of both kinds, and unions cut to --top
    assert mixed >= 4 and cut >= 4  # 4 mixed with the plate counted in the link ratio


def test_the_best_of_both_keeps_what_each_answer_counted(answered):
    """Of the candidates ``any`` keeps, as many are refined near misses and six-bars with a
    moved pivot as their own answers said (recounted on the kept ones: a sparse RRR answer
    of moved pivots and refined misses mixed with a full RPR one)."""
    for request, either, rpr, rrr in answered:
        ids = {c.id for c in either.candidates}
        for part in (rpr, rrr):
            assert part.misses_met <= len(part.candidates) and part.reseated <= len(part.candidates)
        if ids == {c.id for c in rpr.candidates} | {c.id for c in rrr.candidates}:
            assert either.misses_met == rpr.misses_met + rrr.misses_met
            assert either.reseated == rpr.reseated + rrr.reseated
    sparse = [(r, e) for r, e, _, _ in answered if r.refine and (e.reseated or e.misses_met)]
    assert sparse  # the refined requests do go through the sparse steps


def test_the_regression_of_issue_41_any_finds_what_rrr_finds(source):
    """Issue #41: ``--dwell 90 --swing 45 --min-transmission 45`` answered 4 six-bars as
    ``any`` and 10 as ``rrr`` on ``standard``, 8 of them not in ``any``'s list: both output
    types shared one sample and one sparse answer, so neither was filled toward ``--top`` on
    its own. On the test atlas ``--dwell 75 --swing 45 --min-transmission 45`` showed it: 4
    six-bars as ``any``, 4 as ``rpr``, 10 as ``rrr``, 7 of the best 10 of the union not in
    ``any``'s list. Now ``any`` answers that best 10, RRR six-bars among them."""
    request = Request(dwell=75 * DEG, swing=45 * DEG, min_transmission=45 * DEG, top=10)
    either = answer(request, source)
    rpr, rrr = _both(request, source)
    best = _best_of_union(request, rpr, rrr)
    assert len(rrr.candidates) == 10 and len(either.candidates) == 10
    assert [c.id for c in either.candidates] == [c.id for c in best]
    assert sum(c.sixbar.dyad.kind == "RRR" for c in either.candidates) >= 6


def test_a_no_match_of_any_is_both_diagnoses_in_one(source):
    """Nothing meets a 60°/30° request held to an exact dwell and 45° transmission as either
    output type: ``any``'s no-match counts the six-bars both fitted and both rejections, and
    its nearest six-bar is the nearer of the two (the smaller sum of excesses)."""
    request = Request(dwell=60 * DEG, dwell_tol=0.0, swing=30 * DEG, min_transmission=45 * DEG, refine=False)
    either = answer(request, source)
    rpr, rrr = _both(request, source)
    assert either.candidates == rpr.candidates == rrr.candidates == []
    a, b, c = either.no_match, rpr.no_match, rrr.no_match
    assert b.fitted > 0 and c.fitted > 0
    assert a.fitted == b.fitted + c.fitted
    assert a.rejected == {k: b.rejected[k] + c.rejected[k] for k in CONSTRAINTS}

    def total(nm):
        return total_excess(violations(request, scaled_figures(nm.nearest.figures, 1 / request.crank)))

    nearer = min((b, c), key=total)
    assert a.nearest.id == nearer.nearest.id
    assert a.would_meet == dataclasses.replace(nearer.would_meet, output="any")


@pytest.mark.parametrize("dwell, swing, output", [(150, 90, "rrr"), (10, 10, "rpr"), (60, 30, "rrr")])
def test_the_constraint_in_the_way_is_the_best_figure_of_the_six_bars_missing_it_alone(source, dwell, swing, output):
    """A no-match's ``reach``: the constraint that the nearest six-bar missing a single one
    misses, and the best figure on it of every fitted six-bar missing it alone (recomputed
    here from every fit's own figures)."""
    from synth.mechanism.figures import sixbar_figures
    from synth.mechanism.sixbar import SixBars
    from synth.query import SAMPLES, diagnose, fit, select

    request = Request(
        dwell=dwell * DEG,
        swing=swing * DEG,
        output=output,
        dwell_tol=(0.0 if dwell == 60 else 2) * DEG,
        min_transmission=45 * DEG,
    )
    kind = "line" if output == "rpr" else "arc"
    fits = fit(request, select(source, request, (kind,), 30), kind)
    assert fits
    figures = sixbar_figures(
        SixBars.from_sixbars([f.sixbar() for f in fits]),
        band=request.band,
        dwell_length=request.dwell,
        dwells=1,
        samples=SAMPLES,
        footprint=False,
    )
    excess = [violations(request, f) for f in figures]
    alone = [
        (next(k for k, x in e.items() if x > 0), f, total_excess(e))
        for e, f in zip(excess, figures)
        if not e["assembly"] and sum(x > 0 for x in e.values()) == 1
    ]
    reach = diagnose(request, fits).reach
    if not alone:
        assert reach is None
        return
    key = min(alone, key=lambda a: a[2])[0]
    mine = [f for k, f, _ in alone if k == key]
    assert reach[0] == key
    if key == "dwell":
        best = min((d.angle for f in mine for d in f.dwells[:1]), key=lambda a: abs(a - request.dwell))
        assert (reach[1], reach[2]) == pytest.approx((math.degrees(best), dwell), abs=1e-9)
        assert abs(reach[1] - dwell) > 2 * (dwell != 60)
    elif key == "transmission":
        best = max(min(f.transmission_fourbar, f.transmission_output) for f in mine)
        assert (reach[1], reach[2]) == pytest.approx((math.degrees(best), 45.0), abs=1e-9)
        assert reach[1] < 45
    else:
        assert reach[2] in (request.max_link_ratio, request.min_arm, request.min_clearance, swing)


def test_a_complete_any_is_the_best_of_both_complete_answers(source):
    """With ``--complete`` too: ``any`` (each output type searched whole) is the best --top of
    the union of the complete RPR and RRR answers; handed one search of both kinds
    (:func:`synth.query.search`, as ``dwell bench coverage --complete`` does), it splits it by
    output type and answers the same, with the search's counts."""
    from synth.query import search

    request = Request(dwell=60 * DEG, swing=30 * DEG, top=8, complete=True, refine=False)
    either = answer(request, source)
    rpr, rrr = _both(request, source)
    best = _best_of_union(request, rpr, rrr)
    assert [_key(c) for c in either.candidates] == [_key(c) for c in best]
    assert rpr.candidates and rrr.candidates and len(either.candidates) == request.top
    found, count = search(request, source)
    again = answer(request, source, searched=(found, count))
    assert [_key(c) for c in again.candidates] == [_key(c) for c in best]
    assert (again.considered, again.simulated) == (count.rows, count.simulated)
