"""Status flags, assembly branches and the one exception for geometry that cannot assemble.

Every numeric kernel in ``kinematics/`` and ``synth/`` reports degenerate geometry through a
``Status`` array of the broadcast shape instead of NaN or inf. Flags combine (``IntFlag``): a
toggle position may also put the pole at infinity, for instance.
"""

from __future__ import annotations

import enum
from typing import Literal

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "AssemblyError",
    "Branch",
    "OnDegenerate",
    "Status",
    "assembly_status",
    "check_on_degenerate",
    "describe_status",
    "first_flagged",
    "raise_on_flags",
]


class Status(enum.IntFlag):
    """Why a value at one (linkage, crank angle[, ray]) is not an ordinary finite answer.

    Values that carry a flag are finite placeholders (0 or the last safe value), never NaN/inf.
    """

    OK = 0
    NOT_ASSEMBLABLE = 1 << 0  #: the loop cannot close at this input (|cos| > 1)
    TOGGLE = 1 << 1  #: coupler and rocker (or rod and slider guide) aligned: sin(θ−γ) = 0
    POLE_AT_INFINITY = 1 << 2  #: θ′ = 0, the coupler is momentarily translating
    INFLECTION_CIRCLE_COLLAPSED = 1 << 3  #: |Z2| = 0, the inflection circle has no diameter
    CIRCLE_POINT_AT_INFINITY = (
        1 << 4
    )  #: the ray meets the cubic at infinity (a straight "arc"), or too near it to place to 1e-9
    RAY_ALONG_POLE_TANGENT = 1 << 5  #: R2 = 0: the ray is the pole tangent
    CENTER_POINT_AT_INFINITY = 1 << 6  #: the circle point lies on (or within rounding of) the inflection circle
    AT_INFINITY = 1 << 7  #: any other point at infinity (e.g. a coupler point 1e6 cranks away)
    #: the point is the pole itself, where its path has a cusp (ray along the pole normal, Ball's
    #: point at a rocker dead-centre); needs uint16 status arrays (``synth/``)
    AT_POLE = 1 << 8
    #: the loop is too ill-conditioned here for the curvature invariants (near a toggle, or a
    #: coupler or rocker tiny against the other links): see ``synth.types.MAX_CONDITION``
    ILL_CONDITIONED = 1 << 9


#: Human-readable reasons, used by the CLI and by stability summaries.
_REASONS: dict[Status, str] = {
    Status.NOT_ASSEMBLABLE: "linkage cannot assemble at this crank angle",
    Status.TOGGLE: "toggle position (coupler and rocker aligned), derivatives undefined",
    Status.POLE_AT_INFINITY: "pole at infinity (coupler momentarily translating, theta' = 0)",
    Status.INFLECTION_CIRCLE_COLLAPSED: "inflection circle collapsed (|Z2| = 0)",
    Status.CIRCLE_POINT_AT_INFINITY: "circle point at infinity on this ray (straight path), or within rounding of it: "
    "not placeable to 1e-9 at this instant",
    Status.RAY_ALONG_POLE_TANGENT: "ray along the pole tangent (R2 = 0)",
    Status.CENTER_POINT_AT_INFINITY: "centre point at infinity (circle point on the inflection circle), or within "
    "rounding of it: not placeable to 1e-9 at this instant",
    Status.AT_INFINITY: "point at infinity",
    Status.AT_POLE: "point at the pole (its path has a cusp there: no tangent, no curvature)",
    Status.ILL_CONDITIONED: "loop too ill-conditioned for curvature invariants (near a toggle or extreme link ratio)",
}


def describe_status(flags: int) -> list[str]:
    """Names of the individual flags set in ``flags`` (empty for OK)."""
    return [f.name.lower() for f in Status if f and (int(flags) & f)]


def reason(flag: Status) -> str:
    """One-line explanation of a single flag."""
    return _REASONS[flag]


class Branch(enum.IntEnum):
    """Assembly branch of a four-bar (and of any RRR dyad built the same way).

    ``LEFT`` (+1) puts the coupler–rocker joint B to the left of the directed line A→B0,
    ``RIGHT`` (−1) to the right. Stored as the small integer in the database.
    """

    LEFT = 1
    RIGHT = -1


class AssemblyError(ValueError):
    """Input that cannot be assembled, or lengths that make no linkage.

    The message names the violated condition, e.g. ``"four-bar cannot assemble at crank
    angle 200°: |R| = 3.1 > b + c = 3"``.
    """


OnDegenerate = Literal["flag", "raise"]
_ON_DEGENERATE = ("flag", "raise")


def check_on_degenerate(on_degenerate: str) -> OnDegenerate:
    """Validate the keyword-only ``on_degenerate`` choice once, with the list of options."""
    if on_degenerate not in _ON_DEGENERATE:
        raise ValueError(f"on_degenerate must be one of {', '.join(map(repr, _ON_DEGENERATE))}, not {on_degenerate!r}")
    return on_degenerate  # type: ignore[return-value]


def assembly_status(bad: np.ndarray, toggle: np.ndarray) -> NDArray[np.uint8]:
    """Status of a loop solve: NOT_ASSEMBLABLE where ``bad``, else TOGGLE where ``toggle``."""
    return np.where(bad, np.uint8(Status.NOT_ASSEMBLABLE), np.asarray(toggle, bool).view(np.uint8) << 1)


def first_flagged(status: np.ndarray, flags: int) -> tuple[tuple[int, ...], int] | None:
    """Index of the first element of ``status`` carrying one of ``flags`` and how many do,
    or None when none does (for error messages that name the offending position)."""
    status = np.asarray(status)
    bad = np.flatnonzero((status & int(flags)).ravel())
    if bad.size == 0:
        return None
    return tuple(int(k) for k in np.unravel_index(bad[0], status.shape)), int(bad.size)


def raise_on_flags(status: np.ndarray, where: str, flags: Status = Status.NOT_ASSEMBLABLE) -> None:
    """Raise :class:`AssemblyError` if any element of ``status`` carries one of ``flags``."""
    found = first_flagged(status, flags)
    if found is not None:
        index, count = found
        names = ", ".join(n.replace("_", " ") for n in describe_status(int(np.asarray(status)[index]) & int(flags)))
        raise AssemblyError(f"{where}: {names} at {count} position(s)")
