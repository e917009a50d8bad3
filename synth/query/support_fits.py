"""Slotted rockers resting at a coupler curve's support point: the near misses of a sparse
answer for a rest shorter than a harmonic output of the requested swing would give
(:func:`support_fits`).

A short rest at a small swing (RPR 10° at a 10° or 20° swing) lies at no stored straight
stretch: the output must turn sharply at its extremes and move evenly between them
(:mod:`synth.mechanism.support_rest`). Every line of the atlas's first level lends its
coupler point (its four-bar within the request's transmission and link limits); the paths
whose support point in some slot direction passes the far-field test get a slot pivot on the
support tangent each way (its longest reach within the link ratio, its swing within 10 %
of the request's), and an even spread of
them (:data:`SUPPORT_FITS` at most) are returned as fits whose ids carry their dimensions, for the near-miss refinement to move onto the request.
"""

from __future__ import annotations

import numpy as np

from synth.kinds import OutputTag, SegmentKind
from synth.mechanism.sixbar import OutputDyad, crank_grid
from synth.mechanism.support_rest import harmonic_rest, slot_pivots, support_points
from synth.query.candidates import Request
from synth.query.contract import SegmentSource
from synth.query.fitting import Fitted, coupler_paths
from synth.query.segment_rows import SegmentBatch, SegmentRow

__all__ = ["SUPPORT_FITS", "support_fits", "wants_support_fits"]

#: Fits returned at most (the near-miss refinement takes the nearest of them).
SUPPORT_FITS = 2048
#: How far (a fraction of the request's) a fit's swing may stay from it: the refinement moves
#: a near miss a little, and near the curve the reach may find no pivot that swings as asked.
SWING_SLACK = 0.1
#: Crank samples of the far-field test (1°: a 10° rest is ten of them).
SAMPLES = 360
#: Rows of the atlas read per batch.
BATCH = 8000


def wants_support_fits(request: Request) -> bool:
    """A single RPR rest no longer than a harmonic output of the requested swing rests
    (:func:`~synth.mechanism.support_rest.harmonic_rest`, 23.0° at a 10° swing and 0.1° band):
    what the stored stretches do not predict."""
    return (
        request.output == OutputTag.RPR
        and request.dwells == 1
        and request.swing is not None
        and request.dwell <= harmonic_rest(request.band, request.swing)
    )


def support_fits(request: Request, source: SegmentSource) -> list[Fitted]:
    """Up to :data:`SUPPORT_FITS` RPR fits with the slot pivot on a support tangent of the
    coupler curve of an atlas line (module docstring), in the atlas's scan order; [] unless
    :func:`wants_support_fits`."""
    if not wants_support_fits(request):
        return []
    level = source.tolerance_levels()[0][0]  # every line has a row at every level
    phi = crank_grid(SAMPLES)
    found: list[tuple[SegmentBatch, np.ndarray, np.ndarray, np.ndarray]] = []  # (batch, rows, k, sample)
    for batch in source.scan_segments(
        SegmentKind.LINE,
        level,
        min_transmission=request.min_transmission,
        max_length=request.max_link_ratio,
        min_radius_ratio=1.0 / request.max_link_ratio,
        batch=BATCH,
    ):
        support = support_points(
            coupler_paths(batch, phi),
            dwell=request.dwell,
            dwell_tol=request.dwell_tol,
            swing=request.swing,
            band=request.band,
        )
        rows, k = np.nonzero(support >= 0)
        found.append((batch, rows, k, support[rows, k]))
    total = sum(len(rows) for _, rows, _, _ in found)
    # a small swing passes up to ~10⁵ (path, direction) pairs: an even spread of them, in scan order
    chosen = np.unique(np.linspace(0, total - 1, min(total, SUPPORT_FITS // 2)).round().astype(np.int64))
    picked: list[SegmentRow] = []
    direction, sample = [], []
    start = 0
    for batch, rows, k, at in found:
        mine = chosen[(chosen >= start) & (chosen < start + len(rows))] - start
        picked += [batch[int(r)] for r in rows[mine]]
        direction.append(k[mine])
        sample.append(at[mine])
        start += len(rows)
    if not picked:
        return []
    paths = coupler_paths(picked, phi)
    hits, pivots, swung = slot_pivots(paths, np.concatenate(direction), np.concatenate(sample), swing=request.swing)
    reach = np.abs(paths[hits] - pivots[:, None]).max(axis=1)
    keep = (
        np.isfinite(pivots)
        & (reach <= request.max_link_ratio)  # the slot is a link (crank = 1)
        & (np.abs(swung - request.swing) <= SWING_SLACK * request.swing)
    )
    return [
        Fitted(picked[h], OutputTag.RPR, 0, OutputDyad.rpr(complex(p)), moved=True)
        for h, p in zip(hits[keep], pivots[keep])
    ]
