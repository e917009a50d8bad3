"""Minimum-zone lines and circles through sampled coupler paths (docs/curvature.md §3).

:func:`path_deviation` is the one definition of a path's signed distance from a line or a
circle (:func:`synth.segment_search.minimum_zone_kernel.deviation_at` is its compiled scalar twin, the same
expressions); :func:`minimum_zone_fit` moves a line or circle towards the minimum-zone
(Chebyshev, minimax) one through path samples — Lawson's iteratively reweighted least squares
on the fit linearised about the current geometry, compiled per row in
:mod:`synth.segment_search.minimum_zone_kernel`. Units: crank lengths, radians. Used by the segment search
(``synth.segment_search.segments``, ``synth.segment_search.dwell_measure``) and the dwell bounds (``synth.segment_search.dwell_bounds``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from synth.kinds import SegmentKind
from synth.types import C128, F64

__all__ = ["minimum_zone_fit", "path_deviation"]

_LINE = SegmentKind.LINE.code


def path_deviation(z: C128, kind: NDArray[np.integer] | int, point: C128, direction: C128, radius: F64) -> F64:
    """Signed distance of path points ``z`` from a line (``kind`` ``SegmentKind.LINE.code``:
    through ``point`` along unit ``direction``, positive to its left) or a circle
    (``SegmentKind.ARC.code``: centre ``point``, ``radius``, positive outside). Arguments
    broadcast."""
    kind = np.asarray(kind)
    if kind.size and np.all(kind == kind.flat[0]):  # one kind: compute only its distance
        if kind.flat[0] == _LINE:
            return np.broadcast_to(
                np.imag(np.conj(direction) * (z - point)),
                np.broadcast_shapes(np.shape(z), kind.shape, np.shape(point), np.shape(direction)),
            )
        return np.broadcast_to(
            np.abs(z - point) - radius, np.broadcast_shapes(np.shape(z), kind.shape, np.shape(point), np.shape(radius))
        )
    line = np.imag(np.conj(direction) * (z - point))
    circle = np.abs(z - point) - radius
    return np.where(kind == _LINE, line, circle)


def minimum_zone_fit(
    z: C128, kind: int, point: C128, direction: C128, radius: F64, iterations: int
) -> tuple[C128, C128, F64]:
    """Minimum-zone line (``kind`` ``SegmentKind.LINE.code``) or circle (``ARC.code``) through
    each row of path samples ``z`` (n, samples), started from the given one (each (n,)):
    :func:`synth.segment_search.minimum_zone_kernel.fit_row` per row."""
    from synth.segment_search.minimum_zone_kernel import fit_rows  # numba: imported on first use

    z = np.ascontiguousarray(z, dtype=complex)
    n = z.shape[0]
    point, direction, radius = (
        np.ascontiguousarray(np.broadcast_to(x, (n,)), dtype=t)
        for x, t in ((point, complex), (direction, complex), (radius, float))
    )
    return fit_rows(z, int(kind), point, direction, radius, int(iterations))
