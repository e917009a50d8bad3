"""The complete search (``request.complete``): every stored segment at every tolerance level,
read in batches, fitted once per :func:`fit_key` for several requests (:func:`search_many`),
pruned only by conditions no meeting six-bar can fail.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from synth.query.candidates import Candidate, Request
from synth.query.contract import BatchMap, SegmentSource
from synth.query.evaluate import simulate
from synth.query.fitting import fit_arrays, fits_of, prescreen
from synth.query.segment_rows import SegmentRow
from synth.query.windows import kinds_for

#: (segment, level) rows the complete search reads, fits and simulates at a time.
BATCH = 4000


@dataclass(frozen=True, slots=True)
class SearchCount:
    """What the complete search went through: (segment, level) rows read and fitted, dyads
    fitted, six-bars past the prescreen (:func:`prescreen`) and simulated, six-bars that met
    the request."""

    rows: int = 0
    fitted: int = 0
    simulated: int = 0
    met: int = 0


def fit_key(request: Request) -> tuple:
    """What the rows a complete search reads and the dyads it fits depend on: requests with
    the same key share both (:func:`search_many`); the dwell, band and the other limits only
    decide which of the fitted six-bars meet a request."""
    return (kinds_for(request), request.swing, request.min_transmission, request.max_link_ratio)


def search_batch(
    job: tuple[Sequence[Request], str, Sequence[SegmentRow]],
) -> tuple[list[list[Candidate]], int, int, list[int]]:
    """One batch of :func:`search_many`: ``job = (requests, kind, rows)`` → per request the
    six-bars that meet it, then the rows, the fitted dyads and per request the simulated
    six-bars. The dyads are fitted once for all the requests (they share :func:`fit_key`).
    Module-level, so that it runs on worker processes."""
    requests, kind, rows = job
    fits, paths = fit_arrays(requests[0], rows, kind)
    met, simulated = [], []
    for request in requests:
        found, n = simulate(request, fits_of(rows, fits, prescreen(request, fits, paths)))
        met.append(found)
        simulated.append(n)
    return met, len(rows), fits.index.size, simulated


def search(
    request: Request,
    source: SegmentSource,
    *,
    on_progress: Callable[[int, int], None] | None = None,
    map_batches: BatchMap | None = None,
) -> tuple[list[Candidate], SearchCount]:
    """Every six-bar the atlas yields for ``request`` that meets it, unranked (in the
    crank-normalised fit's terms, scaled to ``request.crank``).

    The six-bars the atlas yields: for every stored segment of the request's kinds
    (:func:`kinds_for`) at every tolerance level, the output dyads :func:`fit` finds for it
    (RPR: a slot pivot on each side of a straight stretch; RRR: up to two rocker directions on
    an arc; double: the pivot at the two lines' intersection). Nothing is left out by a
    budget: the rows are only pruned by conditions no six-bar meeting the request can fail —
    the four-bar's transmission angle and link lengths (stored per linkage), the arc's radius
    as the rod, then :func:`prescreen` and :func:`synth.query.candidates.screen` on exact samples.
    The atlas is read in batches of ``BATCH`` rows per kind and level, each evaluated by
    :func:`search_batch` through ``map_batches`` (default: in this process, in order; the
    answer does not depend on the order); ``on_progress(rows done, rows in all)`` after each."""
    return search_many([request], source, on_progress=on_progress, map_batches=map_batches)[0]


def search_many(
    requests: Sequence[Request],
    source: SegmentSource,
    *,
    on_progress: Callable[[int, int], None] | None = None,
    map_batches: BatchMap | None = None,
) -> list[tuple[list[Candidate], SearchCount]]:
    """:func:`search` for several requests with one :func:`fit_key` (say, every dwell of one
    swing): one walk of the atlas, each row fitted once; per request the same answer as its
    own :func:`search`."""
    requests = list(requests)
    if not requests or any(fit_key(r) != fit_key(requests[0]) for r in requests):
        raise ValueError(
            "search_many needs one or more requests with the same kinds, swing, transmission and link ratio"
        )
    first = requests[0]
    limits = {
        "min_transmission": first.min_transmission,
        "max_length": first.max_link_ratio,
        "min_radius_ratio": 1.0 / first.max_link_ratio,
    }
    jobs = [(kind, lv) for kind in kinds_for(first) for lv, _ in source.tolerance_levels()]
    total = sum(source.count_segments(kind, lv, **limits) for kind, lv in jobs)
    batches = (
        (tuple(requests), kind, rows)
        for kind, lv in jobs
        for rows in source.scan_segments(kind, lv, batch=BATCH, **limits)
    )
    out: list[list[Candidate]] = [[] for _ in requests]
    simulated = [0] * len(requests)
    rows_n = fitted_n = 0
    for met, n_rows, n_fitted, n_simulated in (map_batches or map)(search_batch, batches):
        for k, (found, n) in enumerate(zip(met, n_simulated)):
            out[k] += found
            simulated[k] += n
        rows_n, fitted_n = rows_n + n_rows, fitted_n + n_fitted
        if on_progress is not None:
            on_progress(rows_n, total)
    if on_progress is not None:
        on_progress(total, total)  # a double line without both stretches at a level is read, not fitted
    return [(found, SearchCount(rows_n, fitted_n, n, len(found))) for found, n in zip(out, simulated)]
