"""What the query reads of a stored segment: one row (:class:`SegmentRow`) or a batch of rows
of one kind and level as columns (:class:`SegmentBatch`, what the complete search walks).

Angles in radians, lengths in crank lengths, the fixed frame of the four-bar (A0 at the
origin, B0 at (d, 0)). A stretch (a *part*; a double line has two) is (phi_start, phi_end, x,
y, direction or None, radius or None): its crank interval, a point of its line (the foot from
A0) or its arc's centre, and the line's direction or the arc's radius.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from synth.linkage import CouplerFourBar

__all__ = ["Part", "SegmentBatch", "SegmentRow"]


class Part(NamedTuple):
    """One stretch of a stored segment at one level (a double line has two): its crank interval
    (rad), its line point or arc centre (crank lengths), a line's direction (rad) or an arc's
    radius (crank lengths; None for the other kind). A tuple: positional reads still work."""

    start: float
    end: float
    x: float
    y: float
    direction: float | None
    radius: float | None

    @property
    def point(self) -> complex:
        """The line point or arc centre as x + iy."""
        return complex(self.x, self.y)


def _complex(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.complex128]:
    """x + iy with x and y as they are (``x + 1j * y`` would turn a −0.0 in x into +0.0)."""
    z = np.empty(np.shape(x), np.complex128)
    z.real, z.imag = x, y
    return z


@dataclass(frozen=True, slots=True)
class SegmentRow:
    """A stored segment with the dwell row (one level; both parts for a double line) that
    matched the request. Angles in radians, lengths in crank lengths."""

    segment_id: int
    kind: str
    level: int
    tolerance: float
    #: the segment's linkage (crank-normalised: a = 1) and its coupler point
    fourbar: CouplerFourBar
    phi_gen: float
    #: per stretch: a :class:`Part` (start, end, x, y, direction or None, radius or None)
    parts: tuple[Part, ...]
    fourbar_transmission_min: float


#: A part's columns in a :class:`SegmentBatch`, in :data:`Part` order.
_PART_FIELDS = Part._fields


@dataclass(frozen=True, slots=True, eq=False)
class SegmentBatch(Sequence[SegmentRow]):
    """Rows of one segment kind as columns, in row order: what the complete search fits
    without making an object per row (most rows yield no six-bar). A :class:`SegmentRow` is
    spelled out only for the rows that need one (:meth:`__getitem__`).

    ``fourbar`` is one :class:`~synth.linkage.CouplerFourBar` of (rows,) arrays (the kernels
    read its columns as they are; a row's is spelled out as a record of floats). ``parts``
    holds, per part, a (rows, 6) float array in :data:`Part` order with NaN for a
    direction or radius the part has not (a line has no radius, an arc no direction), and
    ``has_parts`` (rows,) how many parts each row has (a double line with one stretch at a
    level has one)."""

    kind: str
    segment_id: NDArray[np.int64]
    level: NDArray[np.int64]
    tolerance: NDArray[np.float64]
    #: the rows' linkages (crank-normalised: a = 1) and coupler points, a record of arrays
    fourbar: CouplerFourBar
    phi_gen: NDArray[np.float64]
    fourbar_transmission_min: NDArray[np.float64]
    parts: tuple[NDArray[np.float64], ...]
    has_parts: NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.segment_id.size)

    def __getitem__(self, i):  # type: ignore[override]
        if isinstance(i, slice):
            return self.rows()[i]
        n = len(self)
        if not -n <= i < n:
            raise IndexError(f"row {i} of a batch of {n}")
        i %= n
        return self._spelled(i, i + 1)[0]

    def __iter__(self) -> Iterator[SegmentRow]:
        return iter(self.rows())

    def rows(self) -> list[SegmentRow]:
        """Every row spelled out, in order (one pass over the columns)."""
        return self._spelled(0, len(self))

    def _spelled(self, lo: int, hi: int) -> list[SegmentRow]:
        """Rows ``lo`` to ``hi`` (exclusive) as :class:`SegmentRow`: plain Python values
        (``tolist``), None for a NaN direction or radius."""
        columns = [
            x[lo:hi].tolist()
            for x in (
                self.segment_id,
                self.level,
                self.tolerance,
                self.fourbar.b,
                self.fourbar.c,
                self.fourbar.d,
                self.fourbar.branch,
                self.fourbar.u,
                self.fourbar.v,
                self.phi_gen,
                self.fourbar_transmission_min,
                self.has_parts,
            )
        ]
        parts = [p[lo:hi].tolist() for p in self.parts]
        out = []
        for k, (sid, level, tol, b, c, d, branch, u, v, phi_gen, mu, n_parts) in enumerate(zip(*columns)):
            spelled = tuple(
                Part(s, e, x, y, None if dr != dr else dr, None if r != r else r)  # x != x: NaN
                for s, e, x, y, dr, r in (part[k] for part in parts[:n_parts])
            )
            fourbar = CouplerFourBar(b=b, c=c, d=d, branch=branch, u=u, v=v)
            out.append(SegmentRow(sid, self.kind, level, tol, fourbar, phi_gen, spelled, mu))
        return out

    def part(self, k: int, field: str) -> NDArray[np.float64]:
        """Column ``field`` (one of :data:`_PART_FIELDS`) of part ``k`` (NaN where a row has
        no such part or value)."""
        return self.parts[k][:, _PART_FIELDS.index(field)]

    def point(self, k: int = 0) -> NDArray[np.complex128]:
        """Part ``k``'s line point or arc centre (complex)."""
        return _complex(self.part(k, "x"), self.part(k, "y"))

    def coupler_point(self) -> NDArray[np.complex128]:
        """The coupler point u + iv in the coupler's frame."""
        return _complex(self.fourbar.u, self.fourbar.v)

    @classmethod
    def of_rows(cls, rows: Sequence[SegmentRow], kind: str) -> SegmentBatch:
        """``rows`` (all of segment kind ``kind``) as a batch that spells out the same rows."""
        if isinstance(rows, SegmentBatch):
            return rows
        if any(r.kind != kind for r in rows):
            raise ValueError(f"a batch holds rows of one kind ({kind})")
        n = len(rows)
        width = max((len(r.parts) for r in rows), default=1) or 1
        nan = math.nan
        none = (nan,) * 6
        parts = [
            np.array(
                [
                    (p[0], p[1], p[2], p[3], nan if p[4] is None else p[4], nan if p[5] is None else p[5])
                    if (p := (r.parts[k] if k < len(r.parts) else None)) is not None
                    else none
                    for r in rows
                ],
                np.float64,
            ).reshape(n, 6)
            for k in range(width)
        ]

        def column(name: str, dtype) -> np.ndarray:
            return np.array([getattr(r, name) for r in rows], dtype).reshape(n)

        def linkage(name: str, dtype=np.float64) -> np.ndarray:
            return np.array([getattr(r.fourbar, name) for r in rows], dtype).reshape(n)

        fourbar = CouplerFourBar(
            b=linkage("b"),
            c=linkage("c"),
            d=linkage("d"),
            branch=linkage("branch", np.int64),
            u=linkage("u"),
            v=linkage("v"),
        )
        return cls(
            kind,
            column("segment_id", np.int64),
            column("level", np.int64),
            column("tolerance", np.float64),
            fourbar,
            *(column(name, np.float64) for name in ("phi_gen", "fourbar_transmission_min")),
            tuple(parts),
            np.array([len(r.parts) for r in rows], np.int64).reshape(n),
        )
