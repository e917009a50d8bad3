"""The atlas's row format and row ids: what a shard's arrays become in the database.

``synth`` measures segments as arrays (:class:`synth.segment_search.segments.FoundSegments`), ``atlas.shard``
computes a shard; this module alone decides how they are stored (the columns of
:mod:`db.schema`) and how rows are named. Ids are deterministic, so the content of an atlas does
not depend on the worker count, the order in which shards finish, or how often a build was
interrupted and resumed:

* linkage id = 2·sweep_index + (0 for branch +1, 1 for branch −1) + 1
* segment id = linkage id · :data:`SEGMENTS_PER_LINKAGE` + ordinal of the segment in its linkage
* a dwell row is named by (segment id, level); its key in the table is (kind code, level,
  dwell key, segment id), the query's walk order (:class:`db.schema.Dwell`): a line's dwell
  key is its dwell angle, an arc's its dwell angle × excursion^¼ (:mod:`synth.segment_search.dwell_key`)

A table's rows stay columns (:class:`TableColumns`: an array per column, a mask where it is
NULL) from the shard to the packing and the digest; :meth:`TableColumns.rows` spells them out as
dicts of plain Python values. Units as :mod:`db.schema` says (crank lengths, radians, fixed
frame).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from operator import itemgetter
from typing import Any

import numpy as np
from numpy.typing import NDArray

from synth.kinds import SEGMENT_KINDS, SegmentKind
from synth.linkage import FourBar
from synth.segment_search.dwell_key import arc_dwell_key
from synth.segment_search.segments import FoundSegments

__all__ = [
    "SEGMENTS_PER_LINKAGE",
    "TableColumns",
    "length_ceil_milli",
    "line_offset",
    "line_offsets",
    "line_point",
    "line_points",
    "linkage_columns",
    "linkage_id",
    "linkage_ids",
    "segment_columns",
    "transmission_floor_cdeg",
]

#: Room for segment ordinals inside one linkage's id range (ids stay below 2^63 for 10^8 linkages).
SEGMENTS_PER_LINKAGE = 100_000


def linkage_ids(sweep_index: NDArray, branch: NDArray) -> NDArray[np.int64]:
    """The deterministic primary keys of (proportion, branch) pairs (the module docstring's rule)."""
    return 2 * np.asarray(sweep_index, np.int64) + (np.asarray(branch) != 1) + 1


def linkage_id(sweep_index: int, branch: int) -> int:
    """The deterministic primary key of one (proportion, branch) pair."""
    return int(linkage_ids(np.array([sweep_index]), np.array([branch]))[0])


@dataclass(frozen=True, slots=True)
class TableColumns:
    """One table's rows as columns, in row order: ``values`` by column name (a float64 or int64
    array, or a list of ``str``), and ``nulls`` by column name where it is NULL somewhere (a bool
    array, True: NULL; the value there is a placeholder and means nothing). What a shard
    computes, digests (:func:`db.digest.shard_digest`) and turns into rows (:meth:`rows`)."""

    values: dict[str, Any]
    nulls: dict[str, NDArray[np.bool_]] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(next(iter(self.values.values()))) if self.values else 0

    def lists(self) -> list[list[Any]]:
        """The columns in :attr:`values`' order as lists of plain Python values (``tolist``: no
        numpy scalars), None where NULL."""
        out = []
        for name, values in self.values.items():
            null = self.nulls.get(name)
            if null is not None and null.any():
                if isinstance(values, np.ndarray):
                    values = values.astype(object)  # a float64 as a Python float
                    values[null] = None
                else:  # texts as they are (a numpy string array would drop trailing NULs)
                    values = [None if n else v for v, n in zip(values, null.tolist())]
            out.append(values.tolist() if isinstance(values, np.ndarray) else list(values))
        return out

    def rows(self) -> list[dict[str, Any]]:
        """The rows as dicts keyed by column name, in :attr:`values`' order (as :meth:`lists`)."""
        names = list(self.values)
        return [dict(zip(names, row)) for row in zip(*self.lists())]

    def first_nonfinite(self) -> tuple[int, str, float] | None:
        """(row, column, value) of the first NaN or ±inf, row by row, a row's columns in
        :attr:`values`' order (a NULL is none); None if every float is finite."""
        first = None
        for name, values in self.values.items():
            if not (isinstance(values, np.ndarray) and values.dtype.kind == "f"):
                continue
            bad = ~np.isfinite(values)
            if name in self.nulls:
                bad &= ~self.nulls[name]
            if bad.any():
                i = int(np.argmax(bad))
                if first is None or i < first[0]:
                    first = (i, name, float(values[i]))
        return first

    @classmethod
    def of_rows(
        cls, names: Sequence[str] | None, rows: Sequence[Sequence[Any]] | Sequence[Mapping[str, Any]]
    ) -> TableColumns:
        """The columns ``names`` of ``rows`` given as tuples of values in ``names`` order, or as
        dicts (``names`` None: the first row's keys): None is NULL. A column of ``str`` stays a
        list; every other column becomes a float64 array if it holds a float, int64 otherwise."""
        if rows and isinstance(rows[0], Mapping):
            names = list(rows[0]) if names is None else names
            rows = [itemgetter(*names)(row) if len(names) > 1 else (row[names[0]],) for row in rows]
        names = list(names or [])
        columns = list(zip(*rows)) if rows else [() for _ in names]
        values, nulls = {}, {}
        for name, column in zip(names, columns):
            if None in column:
                nulls[name] = np.fromiter((v is None for v in column), bool, len(column))
                fill = "" if any(isinstance(v, str) for v in column) else 0
                column = [fill if v is None else v for v in column]
            if any(isinstance(v, str) for v in column):
                values[name] = list(column)
            else:
                values[name] = np.array(column, np.float64 if any(isinstance(v, float) for v in column) else np.int64)
        return cls(values, nulls)


def linkage_columns(
    shard_index: int, sweep_index: NDArray, fourbar: FourBar, grashof: NDArray, transmission: NDArray
) -> TableColumns:
    """The ``linkage`` table's columns, one row per four-bar of ``fourbar`` (a record of (N,)
    arrays, crank-normalised: its ``a`` is not stored); ``transmission`` (N, M) holds its
    folded transmission angle over the turn (rad; NaN where it does not assemble, not read)."""
    sweep_index = np.asarray(sweep_index, np.int64)
    branch = np.asarray(fourbar.branch, np.int64)
    with warnings.catch_warnings():  # a linkage of no assembled sample (none reaches a row) is all NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        low, high = np.nanmin(transmission, axis=1), np.nanmax(transmission, axis=1)
    return TableColumns(
        {
            "id": linkage_ids(sweep_index, branch),
            "shard_index": np.full(sweep_index.size, int(shard_index), np.int64),
            "sweep_index": sweep_index,
            "b": np.asarray(fourbar.b, np.float64),
            "c": np.asarray(fourbar.c, np.float64),
            "d": np.asarray(fourbar.d, np.float64),
            "branch": branch,
            "grashof": np.asarray(grashof, np.int64),
            "transmission_min": np.asarray(low, np.float64),
            "transmission_max": np.asarray(high, np.float64),
        }
    )


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
    :func:`line_offset` up to the line's own points (:func:`line_points` of one line)."""
    return complex(line_points(np.array([offset], float), np.array([direction], float))[0])


def line_points(offset: NDArray[np.float64], direction: NDArray[np.float64]) -> NDArray[np.complex128]:
    """:func:`line_point` of each (offset, direction): offset·i·e^{iδ}, its parts written as
    rounded products, so that a line's foot is the same float alone or in an array."""
    foot = np.empty(np.shape(offset), np.complex128)
    foot.real, foot.imag = -(offset * np.sin(direction)), offset * np.cos(direction)
    return foot


def segment_columns(found: FoundSegments, linkages: TableColumns) -> tuple[TableColumns, TableColumns]:
    """The ``segment`` and ``dwell`` tables' columns for ``found``, whose ``linkage`` indexes
    the rows of ``linkages`` (:func:`linkage_columns`). Each dwell row carries conservative
    integer copies of its linkage's constraint figures (smallest transmission angle floored
    to 0.01°, longest link ceiled to 0.001 crank), so that the query's walk filters on them
    without a join. A double line gets a dwell row only at the levels where both its
    stretches have one.

    Rows come segment by segment, a segment's dwell rows level by level. The figures are
    worked out for all rows at once (:func:`_stretches`), each to the same float as
    :func:`line_offset` and :func:`synth.segment_search.dwell_key.arc_dwell_key` give it for one row."""
    code = found.kind
    double = code == SegmentKind.DOUBLE_LINE.code
    owner = found.linkage
    link_id = np.asarray(linkages.values["id"], np.int64)
    sids = link_id[owner] * SEGMENTS_PER_LINKAGE + _ordinals(owner)
    names = np.array([kind.value for kind in SEGMENT_KINDS], dtype=object)
    segments = TableColumns(
        {
            "id": sids,
            "linkage_id": link_id[owner],
            "kind": names[code].tolist(),
            "phi_gen": found.phi_gen,
            "phi_gen2": np.where(double, found.phi_gen2, 0.0),
            "u": found.uv.real.copy(),
            "v": found.uv.imag.copy(),
        },
        {"phi_gen2": ~double},
    )

    # the dwell rows: (segment, level) where the first stretch has a dwell (a double line: both)
    has = found.has_dwell[:, : len(found.tolerances)]
    seg, level = np.nonzero(has[:, :, 0] & (has[:, :, 1] | ~double[:, None]))  # segment-major: the rows' order
    # the integer copies, worked out once per linkage by the scalar rules
    low, b, c, d = (linkages.values[n].tolist() for n in ("transmission_min", "b", "c", "d"))
    copy_min = np.array([transmission_floor_cdeg(t) for t in low], np.int64)
    copy_longest = np.array([length_ceil_milli(max(x)) for x in zip(b, c, d)], np.int64)
    values, nulls = _stretches(found, seg, level)
    dwells = TableColumns(
        {
            "kind": code[seg],
            "level": level.astype(np.int64),
            "segment_id": sids[seg],
            "transmission_min_cdeg": copy_min[owner[seg]],
            "longest_link_milli": copy_longest[owner[seg]],
            **values,
        },
        nulls,
    )
    return segments, dwells


def _stretches(found: FoundSegments, seg: NDArray[np.int64], level: NDArray[np.int64]) -> tuple[dict, dict]:
    """The dwell columns of the rows (``seg``, ``level``), from ``dwell_key`` to ``direction2``,
    and where each is NULL (a column that does not apply). A line's key is its dwell angle; an
    arc's is its dwell key, the angle in a column of its own. A double line's first stretch is
    a line's, its second goes in the ``…2`` columns."""
    code = found.kind[seg]
    arc = code == SegmentKind.ARC.code
    line = ~arc
    double = code == SegmentKind.DOUBLE_LINE.code
    start = found.phi_start[seg, level, 0]
    angle = found.phi_end[seg, level, 0] - start
    point = found.fit_point[seg, level, 0]
    key = angle.copy()  # a line's
    key[arc] = arc_dwell_key(
        angle[arc], found.excursion[seg[arc], level[arc]], np.asarray(found.tolerances)[level[arc]]
    )
    # np.angle of an array runs the arctan2 loop np.angle of one value runs: the same floats
    direction = np.zeros(seg.size)
    direction[line] = np.angle(found.fit_direction[seg[line], level[line], 0])
    x = point.real.copy()  # an arc's centre
    x[line] = line_offsets(point[line], direction[line])
    start2 = np.where(double, found.phi_start[seg, level, 1], 0.0)
    direction2 = np.where(double, np.angle(found.fit_direction[seg, level, 1]), 0.0)
    x2 = np.zeros(seg.size)
    x2[double] = line_offsets(found.fit_point[seg[double], level[double], 1], direction2[double])
    values = {
        "dwell_key": key,
        "dwell_angle": np.where(arc, angle, 0.0),
        "phi_start": start,
        "x": x,
        "y": np.where(arc, point.imag, 0.0),
        "direction": direction,
        "radius": np.where(arc, found.fit_radius[seg, level, 0], 0.0),
        "dwell_angle2": np.where(double, found.phi_end[seg, level, 1] - found.phi_start[seg, level, 1], 0.0),
        "phi_start2": start2,
        "x2": x2,
        "direction2": direction2,
    }
    nulls = {
        "dwell_angle": line,
        "y": line,
        "direction": arc,
        "radius": line,
        "dwell_angle2": ~double,
        "phi_start2": ~double,
        "x2": ~double,
        "direction2": ~double,
    }
    return values, nulls


def _ordinals(linkage: NDArray[np.int64]) -> NDArray[np.int64]:
    """Position of each segment within its linkage (segments arrive grouped in canonical order)."""
    out = np.zeros(linkage.size, dtype=np.int64)
    if linkage.size:
        start = np.r_[0, np.flatnonzero(np.diff(linkage)) + 1]
        counts = np.diff(np.r_[start, linkage.size])
        out = np.arange(linkage.size) - np.repeat(start, counts)
    return out
