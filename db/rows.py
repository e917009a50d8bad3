"""The atlas's row format and row ids: what a shard's arrays become in the database.

``synth`` measures segments as arrays (:class:`synth.segments.FoundSegments`), ``atlas.shard``
computes a shard; this module alone decides how they are stored (the columns of
:mod:`db.schema`) and how rows are named. Ids are deterministic, so the content of an atlas does
not depend on the worker count, the order in which shards finish, or how often a build was
interrupted and resumed:

* linkage id = 2·sweep_index + (0 for branch +1, 1 for branch −1) + 1
* segment id = linkage id · :data:`SEGMENTS_PER_LINKAGE` + ordinal of the segment in its linkage
* a dwell row is named by (segment id, level); its key in the table is (kind code, level,
  dwell key, segment id), the query's walk order (:class:`db.schema.Dwell`): a line's dwell
  key is its dwell angle, an arc's its dwell angle × excursion^¼ (:mod:`synth.dwell_key`)

Values are plain Python (no numpy scalars); units as :mod:`db.schema` says (crank lengths,
radians, fixed frame).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from synth.dwell_key import arc_dwell_key
from synth.kinds import SEGMENT_KINDS, SegmentKind
from synth.segments import FoundSegments

__all__ = ["SEGMENTS_PER_LINKAGE", "length_ceil_milli", "line_offset", "line_point", "linkage_id", "linkage_rows", "segment_rows",
           "transmission_floor_cdeg"]

#: Room for segment ordinals inside one linkage's id range (ids stay below 2^63 for 10^8 linkages).
SEGMENTS_PER_LINKAGE = 100_000


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


def transmission_floor_cdeg(angle: float) -> int:
    """A transmission angle (rad) as the atlas's filters store and compare it: floor(° · 100).
    Monotone (each float step is correctly rounded), so ``angle ≥ limit`` implies
    ``transmission_floor_cdeg(angle) ≥ transmission_floor_cdeg(limit)``."""
    return math.floor(math.degrees(angle) * 100)


def length_ceil_milli(length: float) -> int:
    """A length (cranks) as the atlas's filters store and compare it: ceil(length · 1000).
    Monotone, so ``length ≤ limit`` implies ``length_ceil_milli(length) ≤ length_ceil_milli(limit)``;
    and ``(length_ceil_milli(length) − 2) / 1000 < length`` whatever the rounding."""
    return math.ceil(length * 1000)


def line_offset(point: complex, direction: float) -> float:
    """The signed distance of the line through ``point`` at angle ``direction`` (rad) from the
    origin A0, as the atlas stores a line: the line is {offset·i·e^{iδ} + t·e^{iδ}}."""
    return float((point * np.exp(-1j * direction)).imag)


def line_point(offset: float, direction: float) -> complex:
    """The foot from A0 of the stored line (``offset``, ``direction``): the inverse of
    :func:`line_offset` up to the line's own points."""
    return offset * 1j * complex(math.cos(direction), math.sin(direction))


def segment_rows(found: FoundSegments, linkages: list[dict[str, Any]]) -> tuple[list[dict], list[dict]]:
    """Rows of the ``segment`` and ``dwell`` tables for ``found``, whose ``linkage`` indexes
    ``linkages`` (the rows of :func:`linkage_rows`). Each dwell row carries conservative
    integer copies of its linkage's constraint figures (smallest transmission angle floored
    to 0.01°, longest link ceiled to 0.001 crank), so that the query's walk filters on them
    without a join. A double line gets a dwell row only at the levels where both its
    stretches have one."""
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
        copies = {"transmission_min_cdeg": transmission_floor_cdeg(link["transmission_min"]),
                  "longest_link_milli": length_ceil_milli(max(link["b"], link["c"], link["d"]))}
        double = kind is SegmentKind.DOUBLE_LINE
        for level in range(len(found.tolerances)):
            if not found.has_dwell[i, level, 0] or (double and not found.has_dwell[i, level, 1]):
                continue
            row = {"kind": kind.code, "level": level, "segment_id": sid, **copies,
                   **_stretch(found, i, level, 0, arc=kind is SegmentKind.ARC)}
            if double:
                second = _stretch(found, i, level, 1, arc=False)
                row.update(dwell_angle2=second["dwell_key"], phi_start2=second["phi_start"], x2=second["x"],
                           direction2=second["direction"])
            else:
                row.update(dwell_angle2=None, phi_start2=None, x2=None, direction2=None)
            dwells.append(row)
    return segments, dwells


def _stretch(found: FoundSegments, i: int, level: int, part: int, *, arc: bool) -> dict[str, Any]:
    """The dwell columns of one stretch: key and interval, and circle or line (as direction,
    offset). A line's key is its dwell angle; an arc's is its dwell key, the angle in a column
    of its own."""
    p = found.fit_point[i, level, part]
    start, end = float(found.phi_start[i, level, part]), float(found.phi_end[i, level, part])
    if arc:
        key = float(arc_dwell_key(end - start, found.excursion[i, level], found.tolerances[level]))
        return {"dwell_key": key, "dwell_angle": end - start, "phi_start": start, "x": float(p.real),
                "y": float(p.imag), "direction": None, "radius": float(found.fit_radius[i, level, part])}
    direction = float(np.angle(found.fit_direction[i, level, part]))
    return {"dwell_key": end - start, "dwell_angle": None, "phi_start": start, "x": line_offset(complex(p), direction),
            "y": None, "direction": direction, "radius": None}


def _ordinals(linkage: NDArray[np.int64]) -> NDArray[np.int64]:
    """Position of each segment within its linkage (segments arrive grouped in canonical order)."""
    out = np.zeros(linkage.size, dtype=np.int64)
    if linkage.size:
        start = np.r_[0, np.flatnonzero(np.diff(linkage)) + 1]
        counts = np.diff(np.r_[start, linkage.size])
        out = np.arange(linkage.size) - np.repeat(start, counts)
    return out
