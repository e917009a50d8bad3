"""What the query reads of a stored segment: one row (:class:`SegmentRow`) or a batch of rows
of one kind and level as columns (:class:`SegmentBatch`, what the complete search walks).

Angles in radians, lengths in crank lengths, the fixed frame of the four-bar (A0 at the
origin, B0 at (d, 0)). A stretch (a *part*; a double line has two) is (phi_start, phi_end, x,
y, direction or None, radius or None): its crank interval, a point of its line (the foot from
A0) or its arc's centre, and the line's direction or the arc's radius.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["SegmentBatch", "SegmentRow"]

Part = tuple[float, float, float, float, float | None, float | None]


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
    b: float
    c: float
    d: float
    branch: int
    u: float
    v: float
    phi_gen: float
    #: per part: (phi_start, phi_end, x, y, direction or None, radius or None)
    parts: tuple[Part, ...]
    fourbar_transmission_min: float


#: A part's columns in a :class:`SegmentBatch`, in :data:`Part` order.
_PART_FIELDS = ("start", "end", "x", "y", "direction", "radius")


@dataclass(frozen=True, slots=True, eq=False)
class SegmentBatch(Sequence[SegmentRow]):
    """Rows of one segment kind as columns, in row order: what the complete search fits
    without making an object per row (most rows yield no six-bar). A :class:`SegmentRow` is
    spelled out only for the rows that need one (:meth:`__getitem__`).

    ``parts`` holds, per part, a (rows, 6) float array in :data:`Part` order with NaN for a
    direction or radius the part has not (a line has no radius, an arc no direction), and
    ``has_parts`` (rows,) how many parts each row has (a double line with one stretch at a
    level has one)."""

    kind: str
    segment_id: NDArray[np.int64]
    level: NDArray[np.int64]
    tolerance: NDArray[np.float64]
    b: NDArray[np.float64]
    c: NDArray[np.float64]
    d: NDArray[np.float64]
    branch: NDArray[np.int64]
    u: NDArray[np.float64]
    v: NDArray[np.float64]
    phi_gen: NDArray[np.float64]
    fourbar_transmission_min: NDArray[np.float64]
    parts: tuple[NDArray[np.float64], ...]
    has_parts: NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.segment_id.size)

    def __getitem__(self, i):  # type: ignore[override]
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self)))]
        n = len(self)
        if not -n <= i < n:
            raise IndexError(f"row {i} of a batch of {n}")
        i %= n
        parts = tuple(tuple(None if np.isnan(x) and f in ("direction", "radius") else x
                            for f, x in zip(_PART_FIELDS, p[i].tolist()))
                      for p in self.parts[: int(self.has_parts[i])])
        return SegmentRow(int(self.segment_id[i]), self.kind, int(self.level[i]), float(self.tolerance[i]),
                          float(self.b[i]), float(self.c[i]), float(self.d[i]), int(self.branch[i]), float(self.u[i]),
                          float(self.v[i]), float(self.phi_gen[i]), parts, float(self.fourbar_transmission_min[i]))

    def __iter__(self) -> Iterator[SegmentRow]:
        return (self[i] for i in range(len(self)))

    def part(self, k: int, field: str) -> NDArray[np.float64]:
        """Column ``field`` (one of :data:`_PART_FIELDS`) of part ``k`` (NaN where a row has
        no such part or value)."""
        return self.parts[k][:, _PART_FIELDS.index(field)]

    def point(self, k: int = 0) -> NDArray[np.complex128]:
        """Part ``k``'s line point or arc centre (complex)."""
        return _complex(self.part(k, "x"), self.part(k, "y"))

    def coupler_point(self) -> NDArray[np.complex128]:
        """The coupler point u + iv in the coupler's frame."""
        return _complex(self.u, self.v)

    @classmethod
    def of_rows(cls, rows: Sequence[SegmentRow], kind: str) -> SegmentBatch:
        """``rows`` (all of segment kind ``kind``) as a batch that spells out the same rows."""
        if isinstance(rows, SegmentBatch):
            return rows
        if any(r.kind != kind for r in rows):
            raise ValueError(f"a batch holds rows of one kind ({kind})")
        n = len(rows)
        width = max((len(r.parts) for r in rows), default=1) or 1
        parts = [np.full((n, 6), np.nan) for _ in range(width)]
        for i, r in enumerate(rows):
            for k, p in enumerate(r.parts):
                parts[k][i] = [np.nan if x is None else x for x in p]

        def column(name: str, dtype) -> np.ndarray:
            return np.array([getattr(r, name) for r in rows], dtype).reshape(n)

        return cls(kind, column("segment_id", np.int64), column("level", np.int64), column("tolerance", np.float64),
                   *(column(name, np.float64) for name in ("b", "c", "d")), column("branch", np.int64),
                   *(column(name, np.float64) for name in ("u", "v", "phi_gen", "fourbar_transmission_min")),
                   tuple(parts), np.array([len(r.parts) for r in rows], np.int64).reshape(n))
