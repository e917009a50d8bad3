"""The kinds synth/ names: segment kinds and output kinds, one spelling each.

``StrEnum`` members are the strings the atlas stores and the ids show (``SegmentKind.ARC ==
"arc"``), so database rows, JSON and candidate ids keep their spelling; the integer ``code`` of
a segment kind is its position in :data:`SEGMENT_KINDS`, for the vectorised search's arrays.
"""

from __future__ import annotations

import enum

__all__ = ["SEGMENT_KINDS", "OutputKind", "OutputTag", "SegmentKind"]


class SegmentKind(enum.StrEnum):
    """A dwell segment of a coupler curve (``segment.kind`` and ``dwell.kind`` in the atlas).

    ``LINE``: nearly straight around Ball's point; ``ARC``: nearly circular around a circle
    point; ``DOUBLE_LINE``: a double Ball point, two straight stretches (two dwells per turn).
    """

    LINE = "line"
    ARC = "arc"
    DOUBLE_LINE = "double_line"

    @property
    def code(self) -> int:
        """Small-integer code in the search's arrays: the position in :data:`SEGMENT_KINDS`."""
        return SEGMENT_KINDS.index(self)

    @property
    def output(self) -> OutputTag:
        """The output of the six-bars fitted to a segment of this kind: a line's slotted rocker
        (RPR), an arc's rod and rocker (RRR), a double line's slotted rocker at the lines'
        intersection (DOUBLE_RPR)."""
        return {SegmentKind.LINE: OutputTag.RPR, SegmentKind.ARC: OutputTag.RRR}.get(self, OutputTag.DOUBLE_RPR)


#: Segment kinds in their canonical order (the order of ``SegmentKind.code``).
SEGMENT_KINDS: tuple[SegmentKind, ...] = tuple(SegmentKind)


class OutputKind(enum.StrEnum):
    """The output dyad of a six-bar (:class:`synth.mechanism.sixbar.OutputDyad`, the JSON ``type``).

    ``RPR``: slotted rocker driven by the coupler point; ``RRR``: rod and rocker.
    """

    RPR = "RPR"
    RRR = "RRR"


class OutputTag(enum.StrEnum):
    """The output of a candidate six-bar as its id spells it (``1234500007-rrr0.1@30``).

    ``DOUBLE_RPR`` ("dbl") is a slotted rocker pivoted at a double Ball point's intersection:
    two dwells per turn, its swing not requested.
    """

    RPR = "rpr"
    RRR = "rrr"
    DOUBLE_RPR = "dbl"

    @property
    def dyad(self) -> OutputKind:
        """The output dyad the tag stands for."""
        return OutputKind.RRR if self is OutputTag.RRR else OutputKind.RPR
