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

__all__ = ["SEGMENTS_PER_LINKAGE", "length_ceil_milli", "line_offset", "line_offsets", "line_point", "linkage_id", "linkage_rows", "segment_rows",
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
    origin A0, as the atlas stores a line: the line is {offset·i·e^{iδ} + t·e^{iδ}}
    (:func:`line_offsets` of one line)."""
    return float(line_offsets(np.array([point], complex), np.array([direction], float))[0])


def line_offsets(point: NDArray[np.complex128], direction: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`line_offset` of each (point, direction): Im(point·e^{−iδ}), its imaginary part
    written as two rounded products and a rounded sum, so that a line's offset is the same
    float alone or in an array (a complex product of arrays may fuse them)."""
    turn = np.exp(-1j * direction)  # −1j·δ: products by ±1 and ±0, exact
    return point.real * turn.imag + point.imag * turn.real


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
    stretches have one.

    Rows come segment by segment, a segment's dwell rows level by level. The figures are
    worked out for all rows at once (:func:`_stretches`), each to the same float as
    :func:`line_offset` and :func:`synth.dwell_key.arc_dwell_key` give it for one row; the
    dicts are made from plain lists (``tolist``: Python floats and ints)."""
    code = found.kind
    double = code == SegmentKind.DOUBLE_LINE.code
    owner = found.linkage.tolist()
    links = [linkages[j] for j in owner]
    sids = [link["id"] * SEGMENTS_PER_LINKAGE + o for link, o in zip(links, _ordinals(found.linkage).tolist())]
    names = [kind.value for kind in SEGMENT_KINDS]
    segments = [
        {"id": sid, "linkage_id": link["id"], "kind": kind, "phi_gen": phi, "phi_gen2": phi2, "u": u, "v": v}
        for sid, link, kind, phi, phi2, u, v in zip(
            sids, links, map(names.__getitem__, code.tolist()), found.phi_gen.tolist(),
            _nullable(double, found.phi_gen2[double]), found.uv.real.tolist(), found.uv.imag.tolist())
    ]

    # the dwell rows: (segment, level) where the first stretch has a dwell (a double line: both)
    has = found.has_dwell[:, :len(found.tolerances)]
    seg, level = np.nonzero(has[:, :, 0] & (has[:, :, 1] | ~double[:, None]))  # segment-major: the rows' order
    # the integer copies, worked out once per linkage
    copies = {j: (transmission_floor_cdeg(linkages[j]["transmission_min"]),
                  length_ceil_milli(max(linkages[j]["b"], linkages[j]["c"], linkages[j]["d"]))) for j in set(owner)}
    copy_min, copy_longest = ([copies[j][k] for j in owner] for k in (0, 1))
    seg_list = seg.tolist()
    columns = _stretches(found, seg, level)
    dwells = [
        {"kind": kind, "level": lv, "segment_id": sid, "transmission_min_cdeg": tmin, "longest_link_milli": longest,
         "dwell_key": key, "dwell_angle": angle, "phi_start": start, "x": x, "y": y, "direction": direction,
         "radius": radius, "dwell_angle2": angle2, "phi_start2": start2, "x2": x2, "direction2": direction2}
        for kind, lv, sid, tmin, longest, key, angle, start, x, y, direction, radius, angle2, start2, x2, direction2
        in zip(code[seg].tolist(), level.tolist(), map(sids.__getitem__, seg_list), map(copy_min.__getitem__, seg_list),
               map(copy_longest.__getitem__, seg_list), *columns)
    ]
    return segments, dwells


def _stretches(found: FoundSegments, seg: NDArray[np.int64], level: NDArray[np.int64]) -> list[list]:
    """The dwell columns of the rows (``seg``, ``level``), from ``dwell_key`` to ``direction2``
    in row order, as lists (None where a column does not apply). A line's key is its dwell
    angle; an arc's is its dwell key, the angle in a column of its own. A double line's first
    stretch is a line's, its second goes in the ``…2`` columns."""
    code = found.kind[seg]
    arc = code == SegmentKind.ARC.code
    line = ~arc
    double = code == SegmentKind.DOUBLE_LINE.code
    start = found.phi_start[seg, level, 0]
    angle = found.phi_end[seg, level, 0] - start
    point = found.fit_point[seg, level, 0]
    key = angle.copy()  # a line's
    key[arc] = arc_dwell_key(angle[arc], found.excursion[seg[arc], level[arc]], np.asarray(found.tolerances)[level[arc]])
    # np.angle of an array runs the arctan2 loop np.angle of one value runs: the same floats
    direction = np.angle(found.fit_direction[seg[line], level[line], 0])
    x = point.real.copy()  # an arc's centre
    x[line] = line_offsets(point[line], direction)
    start2 = found.phi_start[seg[double], level[double], 1]
    direction2 = np.angle(found.fit_direction[seg[double], level[double], 1])
    return [key.tolist(), _nullable(arc, angle[arc]), start.tolist(), x.tolist(), _nullable(arc, point.imag[arc]),
            _nullable(line, direction), _nullable(arc, found.fit_radius[seg[arc], level[arc], 0]),
            _nullable(double, found.phi_end[seg[double], level[double], 1] - start2), _nullable(double, start2),
            _nullable(double, line_offsets(found.fit_point[seg[double], level[double], 1], direction2)),
            _nullable(double, direction2)]


def _nullable(where: NDArray[np.bool_], values: NDArray) -> list:
    """A column of ``where.size`` rows: ``values`` (as Python floats) where ``where``, None elsewhere."""
    out = np.full(where.size, None, dtype=object)
    out[where] = values  # an object array takes a float64 as a Python float
    return out.tolist()


def _ordinals(linkage: NDArray[np.int64]) -> NDArray[np.int64]:
    """Position of each segment within its linkage (segments arrive grouped in canonical order)."""
    out = np.zeros(linkage.size, dtype=np.int64)
    if linkage.size:
        start = np.r_[0, np.flatnonzero(np.diff(linkage)) + 1]
        counts = np.diff(np.r_[start, linkage.size])
        out = np.arange(linkage.size) - np.repeat(start, counts)
    return out
