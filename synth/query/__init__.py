"""The synthesis query as a library stage: a :class:`~synth.query.candidates.Request` in, ranked
six-bars out (pure: no click, no ORM, no I/O — segments are read through a
:class:`SegmentSource`, which ``db.queries.AtlasSource`` implements over an engine).

Pipeline (:func:`answer`): the segments whose stored dwell (an arc's dwell key) lies near the
request (:meth:`SegmentSource.select_segments`) → output dyads fitted to every segment in one
batch per kind (``synth.mechanism.dyad``: RPR on straight segments, RPR at the lines' intersection for
double Ball points, RRR on arcs) → a necessary screen on the crank grid
(:func:`~synth.query.candidates.screen`) → the full figures of the survivors from the exact
simulation (:func:`~synth.mechanism.figures.sixbar_figures`) → the six-bars that meet the request →
ranked (:func:`~synth.query.candidates.rank`), one per segment and output type and one of a mirror
pair → with ``request.refine``, the top ones refined by a local optimisation with exact
simulation in the loop (:func:`synth.query.refine.refine`) and ranked again. Lengths are
crank-normalised until the end, then scaled to ``request.crank``. ``--output any`` (one dwell)
runs the pipeline once as RPR and once as RRR and ranks the union of the two answers.

That pipeline runs on a sample of the atlas (:func:`select`: per level, the stored rows
nearest a target — a line's dwell, an arc's dwell key, :mod:`synth.segment_search.dwell_key` — a budget;
a sparse answer samples wider, moves the fits' pivots, then reads deeper along the arcs).
With ``request.complete`` it runs instead on every stored segment at every level
(:func:`search`), pruned only by conditions no meeting six-bar can fail, the prescreen (:func:`prescreen`) among them: the complete answer.

When fewer than ``FILL`` six-bars meet the request (and refinement is on), the nearest misses
(of the sample's fits and of the fits to rests twice as long the moved pivots were taken from;
``MISSES`` at a time, by the sum of their excesses over the limits, for at most
``MISS_ROUNDS`` rounds while fewer than ``FILL`` meet) are refined toward it
(the refinement's reach: a CMA-ES in a wider trust region), and those that then meet it join
the answer; if nothing meets it even so, the result carries a
:class:`NoMatch`: how many fitted six-bars each constraint
rejected, the nearest six-bar and the request that it would meet. Without refinement the same
:class:`NoMatch` comes cheaper (:func:`diagnose_by_bounds`): only the six-bars whose dwell
decides a count or the nearest get their dwell ends refined.

Modules, one step each (each imports only those above it):

* :mod:`~synth.query.contract` — what the query reads (:class:`DwellWindow`,
  :class:`SegmentSource`): the one module ``db/`` imports;
* :mod:`~synth.query.candidates` — the request, the candidate, the screen and the ranking;
* :mod:`~synth.query.candidate_ids` — a candidate's id and the dimensions a refined id carries;
* :mod:`~synth.query.result` — what it answers (:class:`QueryResult`, :class:`NoMatch`);
* :mod:`~synth.query.windows` — the sample's dwell windows (:func:`select`);
* :mod:`~synth.query.fitting` — output dyads fitted, prescreened and reseated (:func:`fit`,
  :func:`prescreen`, :func:`reseat`);
* :mod:`~synth.query.evaluate` — the exact figures and the request's test (:func:`simulate`,
  :func:`meets`, :func:`violations`);
* :mod:`~synth.query.diagnosis` — why nothing met a request (:func:`diagnose`,
  :func:`diagnose_by_bounds`);
* :mod:`~synth.query.refine_objective`, :mod:`~synth.query.refine` — the refinement's objective
  and acceptance, and its searches (the polish, the reach);
* :mod:`~synth.query.refinement` — the hand-off to :mod:`synth.query.refine` (the top, the near misses);
* :mod:`~synth.query.complete` — the complete search (:func:`search`, :func:`search_many`);
* :mod:`~synth.query.both_outputs` — ``--output any``: the union of the two output types' answers;
* :mod:`~synth.query.pipeline` — :func:`answer`: the steps above over one answer's state
  (:class:`~synth.query.pipeline.Answering`);
* :mod:`~synth.query.rebuilding` — candidates rebuilt from their ids (:func:`rebuild`).
"""

# The names the product and its tests use, from the modules that define them (``__all__``:
# what ``synth`` re-exports).
from synth.query.candidate_ids import REFINED_MARK
from synth.query.candidates import Candidate, Request, rank
from synth.query.complete import BATCH, SearchCount, fit_key, search, search_batch, search_many
from synth.query.contract import ALL_ROWS, BatchMap, DwellWindow, SegmentSource
from synth.query.diagnosis import diagnose, diagnose_by_bounds, misses_of
from synth.query.evaluate import (
    SAMPLES,
    candidate_of,
    distinct,
    figures_of,
    meets,
    scaled_figures,
    simulate,
    total_excess,
    violations,
)
from synth.query.fitting import FIT_SAMPLES, Fitted, coupler_paths, fit, prescreen, reseat
from synth.query.pipeline import DEEPER, DEEPER_KINDS, FILL, RESEAT_BATCH, RESEAT_LONGER, WIDER, answer
from synth.query.rebuilding import rebuild
from synth.query.refinement import MISS_ROUNDS, MISSES, miss_pool, no_worse_than_fits, refined_misses
from synth.query.result import CONSTRAINTS, NoMatch, QueryResult, RebuildError
from synth.query.segment_rows import SegmentRow
from synth.query.windows import PER_LEVEL, REACHES, kinds_for, select

__all__ = [
    "CONSTRAINTS",
    "DwellWindow",
    "NoMatch",
    "QueryResult",
    "RebuildError",
    "SearchCount",
    "SegmentRow",
    "SegmentSource",
    "answer",
    "fit_key",
    "rebuild",
    "search",
    "search_batch",
    "search_many",
]
