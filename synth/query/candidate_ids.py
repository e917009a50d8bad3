"""A candidate's id and the dimensions it carries (pure): the id names the stored segment, the
output fit and the tolerance level a six-bar was rebuilt from (:func:`candidate_id`,
:func:`parse_candidate_id`); a refined six-bar's id appends its crank-normalised dimensions as
base64url float32 (:func:`encode_dimensions`), and :func:`round_dimensions` is the six-bar as
that text holds it. :func:`dimension_vector` and :func:`sixbar_from_vector` are the nine free
dimensions an id carries and the refinement moves.
"""

from __future__ import annotations

import base64
import binascii
import math
import struct

from synth.kinds import OutputKind, OutputTag
from synth.mechanism.sixbar import OutputDyad, SixBar

__all__ = [
    "REFINED_MARK",
    "candidate_dimensions",
    "candidate_id",
    "decode_dimensions",
    "dimension_vector",
    "encode_dimensions",
    "parse_candidate_id",
    "round_dimensions",
    "sixbar_from_vector",
    "sixbar_like",
    "with_dimensions",
]

_TAGS = tuple(t.value for t in OutputTag)

#: Separates a refined candidate's id from the id of the six-bar it was refined from.
REFINED_MARK = "~"
_FLAG_BRANCH, _FLAG_DYAD_BRANCH, _FLAG_RRR = 1, 2, 4


def candidate_id(
    segment_id: int, output: str, slot: int, level: int, swing: float | None, dimensions: SixBar | None = None
) -> str:
    """``<segment>-<rpr|rrr|dbl><slot>.<level>@<swing°>``: enough to rebuild the six-bar from
    the atlas (the fit is deterministic; ``slot`` indexes the fit's candidates, found or not;
    ``level`` is the tolerance level whose fitted line or circle was used). A refined six-bar
    (crank-normalised ``dimensions``) appends ``~`` and :func:`encode_dimensions`."""
    sw = "free" if swing is None else f"{math.degrees(swing):.6g}"
    base = f"{segment_id}-{output}{slot}.{level}@{sw}"
    return base if dimensions is None else f"{base}{REFINED_MARK}{encode_dimensions(dimensions)}"


def with_dimensions(text: str, sixbar: SixBar) -> str:
    """The id of ``sixbar`` (crank-normalised) refined from the candidate ``text``."""
    return f"{text.strip().split(REFINED_MARK)[0]}{REFINED_MARK}{encode_dimensions(sixbar)}"


def parse_candidate_id(text: str) -> tuple[int, str, int, int, float | None]:
    """Inverse of :func:`candidate_id` (the six-bar a refined id was refined from; its
    dimensions: :func:`candidate_dimensions`); ValueError with the reason on a malformed id."""
    try:
        head, sw = text.strip().split(REFINED_MARK)[0].split("@")
        seg, kind = head.split("-")
        slot_text, level_text = kind[3:].split(".")
        output, slot, level = kind[:3], int(slot_text), int(level_text)
        if output not in _TAGS:
            raise ValueError
        output = OutputTag(output)
        swing = None if sw == "free" else math.radians(float(sw))
        if swing is not None and not (0 < swing < math.pi):
            raise ValueError
        dims = candidate_dimensions(text)
        if dims is not None and (dims.dyad.kind == OutputKind.RRR) != (output == OutputTag.RRR):
            raise ValueError
        return int(seg), output, slot, level, swing
    except ValueError:
        raise ValueError(f"not a candidate id: {text!r} (expected e.g. 1234500007-rrr0.1@30)") from None


def candidate_dimensions(text: str) -> SixBar | None:
    """The refined six-bar (crank-normalised) an id carries after ``~``, None for an id without
    one; ValueError on a malformed suffix."""
    parts = text.strip().split(REFINED_MARK)
    if len(parts) == 1:
        return None
    if len(parts) != 2:
        raise ValueError(f"not a candidate id: {text!r} (more than one {REFINED_MARK!r})")
    return decode_dimensions(parts[1])


def encode_dimensions(sixbar: SixBar) -> str:
    """A crank-normalised six-bar (a = 1) as base64url text (no padding): one flag byte (four-bar
    branch −1, dyad branch −1, RRR) and b, c, d, u, v, D.x, D.y (and RRR L, ρ) as big-endian
    float32 — 39 characters for an RPR, 50 for an RRR. The six-bar is rounded to float32 (about
    7 significant digits): :func:`round_dimensions` gives what the text holds."""
    dy = sixbar.dyad
    rrr = dy.kind == OutputKind.RRR
    flags = _FLAG_BRANCH * (sixbar.branch == -1) | _FLAG_DYAD_BRANCH * (dy.branch == -1) | _FLAG_RRR * rrr
    values = dimension_vector(sixbar)[: 9 if rrr else 7]
    raw = struct.pack(f">B{len(values)}f", flags, *values)
    return base64.urlsafe_b64encode(raw).decode("ascii").rstrip("=")


def decode_dimensions(text: str) -> SixBar:
    """Inverse of :func:`encode_dimensions` (a = 1); ValueError naming the problem."""
    try:
        raw = base64.urlsafe_b64decode(text + "=" * (-len(text) % 4))
    except (binascii.Error, ValueError):
        raise ValueError(f"refined dimensions {text!r} are not base64url") from None
    if not raw or len(raw) not in (1 + 4 * 7, 1 + 4 * 9) or raw[0] & ~7:
        raise ValueError(f"refined dimensions {text!r} do not describe a six-bar")
    flags = raw[0]
    rrr = bool(flags & _FLAG_RRR)
    if len(raw) != 1 + 4 * (9 if rrr else 7) or base64.urlsafe_b64encode(raw).decode("ascii").rstrip("=") != text:
        raise ValueError(f"refined dimensions {text!r} do not describe a six-bar")
    values = [float(x) for x in struct.unpack(f">{(len(raw) - 1) // 4}f", raw[1:])]
    branch = -1 if flags & _FLAG_BRANCH else 1
    dyad_branch = -1 if flags & _FLAG_DYAD_BRANCH else 1
    try:
        return sixbar_from_vector(values + [0.0, 0.0][: 9 - len(values)], branch, dyad_branch, rrr)
    except ValueError as exc:  # AssemblyError is a ValueError
        raise ValueError(f"refined dimensions {text!r} do not describe a six-bar: {exc}") from None


def dimension_vector(sixbar: SixBar) -> list[float]:
    """A six-bar's free dimensions over its crank: b, c, d, u, v, D.x, D.y, L, ρ (L = ρ = 0 for
    an RPR) — what an id carries and what refinement varies."""
    dy, a = sixbar.dyad, sixbar.a
    return [
        x / a
        for x in (sixbar.b, sixbar.c, sixbar.d, sixbar.u, sixbar.v, dy.pivot.real, dy.pivot.imag, dy.rocker, dy.rod)
    ]


def sixbar_from_vector(p, branch: int, dyad_branch: int, rrr: bool) -> SixBar:
    """The crank-normalised six-bar of :func:`dimension_vector` ``p`` on the given branches
    (ValueError if it is no six-bar)."""
    pivot = complex(p[5], p[6])
    dyad = OutputDyad.rrr(pivot, p[7], p[8], dyad_branch) if rrr else OutputDyad.rpr(pivot)
    return SixBar(1.0, p[0], p[1], p[2], branch, p[3], p[4], dyad)


def sixbar_like(p, like: SixBar) -> SixBar:
    """The crank-normalised six-bar of :func:`dimension_vector` ``p`` on the branches and with
    the output dyad kind of ``like`` (ValueError if it is no six-bar)."""
    return sixbar_from_vector([float(x) for x in p], like.branch, like.dyad.branch, like.dyad.kind is OutputKind.RRR)


def round_dimensions(sixbar: SixBar) -> SixBar:
    """``sixbar`` (crank-normalised) as its id holds it (float32 dimensions): refine, then
    round, then compute the figures, so that a query and a report show the same numbers."""
    return decode_dimensions(encode_dimensions(sixbar))
