"""The one model of a general planar linkage: links, lower pairs, inputs and an output.

Every link is a rigid body with its own frame; its named points are complex numbers in that
frame (the ground's frame is the global frame). A link's pose is (r, e): origin r and unit
phasor e = e^{iθ}, so a local point p sits at r + e·p. Pairs:

* :class:`RevolutePair` — a point of one link coincides with a point of the other.
* :class:`PrismaticPair` — the block's point ``block_point`` runs on a line of the guide (through
  ``through`` along the unit ``direction``, guide frame) and the block's direction
  ``block_direction`` stays parallel to ``direction``; the pair's displacement s is measured
  from ``through`` along ``direction``.

Angles are radians and lengths are in the file's unit here; degrees live only at the file and
command-line boundary (:mod:`kinematics.assur.linkage_file`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

from kinematics.status import AssemblyError

__all__ = [
    "GROUND",
    "Input",
    "Link",
    "Linkage",
    "LinkageFileError",
    "Output",
    "PrismaticPair",
    "RevolutePair",
]

#: Name (and index 0) of the fixed link.
GROUND = "ground"


class LinkageFileError(AssemblyError):
    """A mechanism description that makes no linkage; the message names the link or joint."""


@dataclass(frozen=True, slots=True)
class Link:
    """A rigid link: named points in its own frame (the ground's points are global)."""

    name: str
    points: Mapping[str, complex]


@dataclass(frozen=True, slots=True)
class RevolutePair:
    """Revolute pair at the joint ``joint``: point ``at[0]`` of ``links[0]`` = ``at[1]`` of ``links[1]``."""

    joint: str
    links: tuple[int, int]
    at: tuple[complex, complex]

    kind = "R"


@dataclass(frozen=True, slots=True)
class PrismaticPair:
    """Prismatic pair ``joint``: ``block`` slides on a line fixed in ``guide``.

    Attributes
    ----------
    through, direction : complex
        A point of the line and its unit direction, guide frame.
    block_point, block_direction : complex
        The block's point that runs on the line (its displacement s from ``through`` along
        ``direction`` is the pair's coordinate) and the block's unit direction that stays
        parallel to ``direction``, block frame.
    """

    joint: str
    guide: int
    block: int
    through: complex
    direction: complex
    block_point: complex = 0j
    block_direction: complex = 1 + 0j

    kind = "P"

    @property
    def links(self) -> tuple[int, int]:
        return (self.guide, self.block)


Pair = RevolutePair | PrismaticPair


@dataclass(frozen=True, slots=True)
class Input:
    """A driven pair: the relative angle of a revolute pair or the displacement of a prismatic one.

    ``kind == "angle"``: the input is θ_link − θ_relative_to (rad), the angle of ``link``'s
    x-axis measured from ``relative_to``'s. ``kind == "slide"``: the displacement s (length)
    of the prismatic pair (``link`` is its block, ``relative_to`` its guide). ``value`` is the
    default position, ``sweep`` an optional default range (first, last) in the same units.
    """

    pair: int
    kind: Literal["angle", "slide"]
    link: int
    relative_to: int
    value: float = 0.0
    sweep: tuple[float, float] | None = None


@dataclass(frozen=True, slots=True)
class Output:
    """The reciprocating output whose limit positions are wanted.

    ``kind == "angle"``: the angle of link ``index`` measured from the ground (rad);
    ``kind == "slide"``: the displacement of prismatic pair ``index`` (length).

    ``band`` (rad, an angle output only) is the total width of the band within which the
    output counts as at rest: with it the limit positions come with the output's dwells, the
    ``dwells`` longest disjoint crank intervals (1 or 2) on which it stays within the band.
    ``leave`` (rad, two dwells only; None: the dwell finder's default, 0.5°) is how far the
    output must leave the band between two rests for them to count as two (``dwell query``'s
    ``--swing-tol``).
    """

    kind: Literal["angle", "slide"]
    index: int
    name: str
    band: float | None = None
    dwells: int = 1
    leave: float | None = None


@dataclass(frozen=True, slots=True)
class Linkage:
    """A validated planar linkage (:func:`kinematics.assur.linkage_from_mapping` builds one).

    ``links[0]`` is the ground. ``pairs`` lists every lower pair once (a joint shared by k
    links contributes k − 1 revolute pairs). ``inputs`` are in file order. ``configuration``
    (1-based, None: not given) is the assembly configuration the description stands for,
    numbered as :func:`~kinematics.assur.configurations` lists them at the inputs' ``value``.
    """

    name: str
    units: str
    links: tuple[Link, ...]
    pairs: tuple[Pair, ...]
    inputs: tuple[Input, ...]
    output: Output | None = None
    configuration: int | None = None

    @property
    def dof(self) -> int:
        """Degrees of freedom by Grübler–Kutzbach: F = 3(n − 1) − 2·j₁ (lower pairs only)."""
        return 3 * (len(self.links) - 1) - 2 * len(self.pairs)

    @property
    def length_scale(self) -> float:
        """A characteristic length: the largest distance of any defined point from its frame's origin."""
        sizes = [abs(p) for link in self.links for p in link.points.values()]
        sizes += [abs(p.through) for p in self.pairs if isinstance(p, PrismaticPair)]
        return max([s for s in sizes if s > 0], default=1.0)

    def link_index(self, name: str) -> int:
        for i, link in enumerate(self.links):
            if link.name == name:
                return i
        raise KeyError(name)

    def moving_points(self) -> list[tuple[str, int, complex]]:
        """Every named point of a moving link, once: (name, link index, local point).

        A joint shared by several moving links is listed on the first of them (they coincide
        wherever the loop closes). Points of the ground are fixed and not listed.
        """
        ground_names = set(self.links[0].points)
        seen: set[str] = set()
        out = []
        for i, link in enumerate(self.links[1:], start=1):
            for name, p in link.points.items():
                if name in seen or name in ground_names:
                    continue
                seen.add(name)
                out.append((name, i, p))
        return out
