"""The atlas's row format and row ids: what a shard's arrays become in the database.

``synth`` measures segments as arrays (:class:`synth.segments.FoundSegments`), ``atlas.shard``
computes a shard; this module alone decides how they are stored (the columns of
:mod:`db.schema`) and how rows are named. Ids are deterministic, so the content of an atlas does
not depend on the worker count, the order in which shards finish, or how often a build was
interrupted and resumed:

* linkage id = 2·sweep_index + (0 for branch +1, 1 for branch −1) + 1
* segment id = linkage id · :data:`SEGMENTS_PER_LINKAGE` + ordinal of the segment in its linkage
* dwell id   = segment id · :data:`DWELLS_PER_SEGMENT` + 2·level + part

Values are plain Python (no numpy scalars); units as :mod:`db.schema` says (crank lengths,
radians, fixed frame).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from synth.kinds import SEGMENT_KINDS, SegmentKind
from synth.segments import FoundSegments

__all__ = ["DWELLS_PER_SEGMENT", "SEGMENTS_PER_LINKAGE", "linkage_id", "linkage_rows", "segment_rows"]

#: Room for segment ordinals inside one linkage's id range (ids stay below 2^63 for 10^8 linkages).
SEGMENTS_PER_LINKAGE = 100_000
#: Room for (level, part) inside one segment's id range: up to 32 tolerance levels.
DWELLS_PER_SEGMENT = 64


def linkage_id(sweep_index: int, branch: int) -> int:
    """The deterministic primary key of a (proportion, branch) pair."""
    return 2 * int(sweep_index) + (0 if branch == 1 else 1) + 1


def linkage_rows(shard_index: int, sweep_index: NDArray, b: NDArray, c: NDArray, d: NDArray, branch: NDArray,
                 grashof: NDArray, transmission: NDArray) -> list[dict[str, Any]]:
    """Rows of the ``linkage`` table, one per four-bar; ``transmission`` (N, M) holds its folded
    transmission angle over the turn (rad; NaN where it does not assemble, not read)."""
    return [
        {
            "id": linkage_id(int(sweep_index[i]), int(branch[i])),
            "shard_index": int(shard_index),
            "sweep_index": int(sweep_index[i]),
            "b": float(b[i]),
            "c": float(c[i]),
            "d": float(d[i]),
            "branch": int(branch[i]),
            "grashof": int(grashof[i]),
            "transmission_min": float(np.nanmin(transmission[i])),
            "transmission_max": float(np.nanmax(transmission[i])),
        }
        for i in range(len(b))
    ]


def segment_rows(found: FoundSegments, linkages: list[dict[str, Any]]) -> tuple[list[dict], list[dict]]:
    """Rows of the ``segment`` and ``dwell`` tables for ``found``, whose ``linkage`` indexes
    ``linkages`` (the rows of :func:`linkage_rows`). Each dwell row carries copies of its
    linkage's constraint figures (smallest transmission angle, longest link), so that the
    query's covering index filters on them without a join."""
    segments: list[dict] = []
    dwells: list[dict] = []
    ordinal = _ordinals(found.linkage)
    for i in range(len(found)):
        kind = SEGMENT_KINDS[int(found.kind[i])]
        link = linkages[int(found.linkage[i])]
        sid = link["id"] * SEGMENTS_PER_LINKAGE + int(ordinal[i])
        segments.append({
            "id": sid,
            "linkage_id": link["id"],
            "kind": kind.value,
            "phi_gen": float(found.phi_gen[i]),
            "phi_gen2": float(found.phi_gen2[i]) if kind is SegmentKind.DOUBLE_LINE else None,
            "u": float(found.uv[i].real),
            "v": float(found.uv[i].imag),
        })
        copies = {"linkage_transmission_min": link["transmission_min"],
                  "longest_link": max(link["b"], link["c"], link["d"])}
        for level, tol in enumerate(found.tolerances):
            for part in range(2 if kind is SegmentKind.DOUBLE_LINE else 1):
                if not found.has_dwell[i, level, part]:
                    continue
                p = found.fit_point[i, level, part]
                start, end = float(found.phi_start[i, level, part]), float(found.phi_end[i, level, part])
                arc = kind is SegmentKind.ARC
                dwells.append({
                    "id": sid * DWELLS_PER_SEGMENT + 2 * level + part,
                    "segment_id": sid,
                    "kind": kind.value,
                    "level": level,
                    "tolerance": float(tol),
                    "part": part,
                    "phi_start": start,
                    "phi_end": end,
                    "dwell_angle": end - start,
                    "x": float(p.real),
                    "y": float(p.imag),
                    "direction": None if arc else float(np.angle(found.fit_direction[i, level, part])),
                    "radius": float(found.fit_radius[i, level, part]) if arc else None,
                    **copies,
                })
    return segments, dwells


def _ordinals(linkage: NDArray[np.int64]) -> NDArray[np.int64]:
    """Position of each segment within its linkage (segments arrive grouped in canonical order)."""
    out = np.zeros(linkage.size, dtype=np.int64)
    if linkage.size:
        start = np.r_[0, np.flatnonzero(np.diff(linkage)) + 1]
        counts = np.diff(np.r_[start, linkage.size])
        out = np.arange(linkage.size) - np.repeat(start, counts)
    return out
