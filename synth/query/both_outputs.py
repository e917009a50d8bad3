"""``--output any`` with one dwell: the union of the RPR answer and the RRR answer, ranked once
(:func:`union_of`). :func:`synth.query.pipeline.answer` answers each output type through the
whole pipeline and hands both answers here.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass

from synth.query.candidates import Request, rank
from synth.query.diagnosis import either_no_match
from synth.query.result import NoMatch, QueryResult

__all__ = ["Answered", "union_of"]


@dataclass(frozen=True, slots=True)
class Answered:
    """One output type's answer and which of its candidates are refined near misses (FILL)
    and six-bars with a moved output pivot (by id): what :func:`union_of` recounts for
    the candidates that stay in the union's top."""

    result: QueryResult
    misses: frozenset[str]
    reseated: frozenset[str]
    #: an empty answer made without its diagnosis: the step that works out its no-match and
    #: the stored dwells nearest the request (:meth:`diagnosed`); None otherwise
    diagnosis: Callable[[], tuple[NoMatch, tuple[float | None, float | None]]] | None = None

    def diagnosed(self) -> Answered:
        """This answer with its no-match worked out, if it was left for later. The diagnosis
        simulates every fit (most of an unrefined answer's time), so ``--output any`` asks for
        it only when both output types came back empty."""
        if self.diagnosis is None:
            return self
        no_match, nearest = self.diagnosis()  # its time goes to the answer's own clock
        return dataclasses.replace(
            self, result=dataclasses.replace(self.result, no_match=no_match, nearest=nearest), diagnosis=None
        )


def union_of(request: Request, parts: list[Answered]) -> QueryResult:
    """The best ``request.top`` of the union of ``parts`` (one answer per output type) by
    :func:`~synth.query.candidates.rank` (Pareto layer, score, id, over the union: a six-bar's
    layer depends on what it is ranked with). The answers share no six-bar (their dyads
    differ), so the union needs no de-duplication. Times, counts and refinements add up; with
    nothing in either, the no-match is the diagnoses in one (:func:`either_no_match`)."""
    t = time.perf_counter()
    top = rank(request, [c for p in parts for c in p.result.candidates])[: request.top]
    clock: dict[str, float] = {}
    for p in parts:
        for k, v in p.result.seconds.items():
            clock[k] = clock.get(k, 0.0) + v
    clock["rank"] = clock.get("rank", 0.0) + time.perf_counter() - t
    results = [p.result for p in parts]
    no_match = None if top else either_no_match(request, [r.no_match for r in results])
    below = [r.nearest[0] for r in results if r.nearest[0] is not None]
    above = [r.nearest[1] for r in results if r.nearest[1] is not None]
    nearest = (None, None) if top else (max(below, default=None), min(above, default=None))
    ids = {c.id for c in top}
    return QueryResult(
        request,
        top,
        sum(r.considered for r in results),
        sum(r.simulated for r in results),
        nearest,
        clock,
        no_match,
        (sum(r.refined[0] for r in results), sum(r.refined[1] for r in results)),
        from_misses=bool(top) and all(r.from_misses or not r.candidates for r in results),
        misses_met=sum(len(p.misses & ids) for p in parts),
        reseated=sum(len(p.reseated & ids) for p in parts),
    )
