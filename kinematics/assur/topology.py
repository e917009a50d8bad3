"""Decomposition of a linkage into Assur groups, in solving order.

The inputs come first: a driven pair has a known relative position, so the two links it joins
move as one rigid *body* (a crank driven against the ground becomes part of the ground body; a
driven actuator between two moving links fuses them). On the bodies, with the ground body
known, the smallest groups of unknown bodies with zero degrees of freedom relative to the known
ones are split off one after the other (Assur 1914; Artobolevsky's structural analysis):

* a **dyad** (class II): two bodies, one pair between them and one pair from each to known
  bodies — 3 pairs, 2·3 = 3·2 equations. Named by its pairs from one known body to the other:
  RRR, RRP, RPR, PRP, RPP (PRR and PPR are the same groups read backwards; PPP is no group,
  its bodies could translate freely).
* a **triad** (class III): a ternary body T with three binary bodies ("legs"), each joined to T
  by one pair and to a known body by one pair — 6 pairs, 2·6 = 3·4 equations.

Class IV and higher groups are reported as unsupported.

References
----------
I. I. Artobolevsky, *Theory of Mechanisms and Machines*, ch. 2 (structural classification).
R. L. Norton, *Design of Machinery*, §2.5 (Grübler–Kutzbach mobility).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

from kinematics.assur.model import Linkage, LinkageFileError

__all__ = ["AssurGroup", "Body", "Decomposition", "decompose"]


@dataclass(frozen=True, slots=True)
class Body:
    """Links that move as one because the pairs between them are driven.

    ``root`` is the link whose frame is the body's frame (the ground for the ground body);
    ``tree`` lists ``(link, parent link, input index)`` from the root outwards.
    """

    root: int
    members: tuple[int, ...]
    tree: tuple[tuple[int, int, int], ...]


@dataclass(frozen=True, slots=True)
class AssurGroup:
    """One Assur group, its bodies and pairs in the order its solver reads them.

    ``kind`` is ``"RRR" | "RRP" | "RPR" | "PRP" | "RPP"`` for a dyad (``bodies = (L1, L2)``,
    ``pairs = (E1, I, E2)``: external pair of L1, internal pair, external pair of L2) or
    ``"triad"`` (``bodies = (T, L1, L2, L3)``, ``pairs = (E1, I1, E2, I2, E3, I3)``: for each
    leg its external pair and its pair with T). Bodies are body indices of the decomposition.
    """

    kind: str
    bodies: tuple[int, ...]
    pairs: tuple[int, ...]
    legs: tuple[str, ...] = ()  #: triad leg types, e.g. ("RR", "RR", "PR") (external, internal)

    @property
    def is_dyad(self) -> bool:
        return self.kind != "triad"

    def describe(self, linkage: Linkage, decomposition: Decomposition) -> str:
        names = "-".join(decomposition.body_name(linkage, b) for b in self.bodies)
        if self.is_dyad:
            return f"{self.kind} dyad ({names})"
        return f"class III triad {'/'.join(self.legs)} ({names})"


@dataclass(frozen=True, slots=True)
class Decomposition:
    """Bodies, the body of every link, and the Assur groups in solving order."""

    bodies: tuple[Body, ...]
    body_of: tuple[int, ...]
    groups: tuple[AssurGroup, ...]

    def body_name(self, linkage: Linkage, body: int) -> str:
        b = self.bodies[body]
        return "+".join(linkage.links[m].name for m in b.members)


def decompose(linkage: Linkage) -> Decomposition:
    """Split ``linkage`` into bodies and Assur groups in solving order.

    Raises :class:`LinkageFileError` for inputs that close a loop, for groups of class IV or
    higher, for an overconstrained part, and for the PPP "dyad".
    """
    bodies, body_of = _bodies(linkage)
    driven = {inp.pair for inp in linkage.inputs}
    edges: list[tuple[int, int, int]] = []  # (pair, body a, body b)
    for k, pair in enumerate(linkage.pairs):
        if k in driven:
            continue
        a, b = (body_of[i] for i in pair.links)
        if a == b:
            raise LinkageFileError(
                f"joint {pair.joint!r} joins links that the inputs already hold rigidly together "
                "(the driven joints close a loop)"
            )
        edges.append((k, a, b))

    ground = body_of[0]
    known = {ground}
    unknown = set(range(len(bodies))) - known
    groups: list[AssurGroup] = []
    while unknown:
        group = _find_dyad(linkage, edges, known, unknown) or _find_triad(edges, known, unknown, linkage)
        if group is None:
            names = ", ".join(sorted("+".join(linkage.links[m].name for m in bodies[b].members) for b in unknown))
            raise LinkageFileError(
                f"links {names} do not split into dyads or class III triads: the linkage has a class IV "
                "or higher Assur group, or an overconstrained loop (not supported)"
            )
        groups.append(group)
        known.update(group.bodies)
        unknown.difference_update(group.bodies)
    return Decomposition(tuple(bodies), tuple(body_of), tuple(groups))


def _bodies(linkage: Linkage) -> tuple[list[Body], list[int]]:
    n = len(linkage.links)
    adjacency: dict[int, list[tuple[int, int]]] = {i: [] for i in range(n)}
    for k, inp in enumerate(linkage.inputs):
        a, b = linkage.pairs[inp.pair].links
        adjacency[a].append((b, k))
        adjacency[b].append((a, k))
    body_of = [-1] * n
    bodies: list[Body] = []
    for start in range(n):
        if body_of[start] >= 0:
            continue
        members, tree, todo = [start], [], [start]
        body_of[start] = len(bodies)
        while todo:
            x = todo.pop(0)
            for y, k in adjacency[x]:
                if body_of[y] < 0:
                    body_of[y] = len(bodies)
                    members.append(y)
                    tree.append((y, x, k))
                    todo.append(y)
        driven_inside = {k for m in members for _, k in adjacency[m]}
        if len(driven_inside) > len(members) - 1:
            joints = ", ".join(repr(linkage.pairs[linkage.inputs[k].pair].joint) for k in sorted(driven_inside))
            raise LinkageFileError(
                f"the inputs at joints {joints} close a loop of driven joints: their values could not all hold"
            )
        bodies.append(Body(start, tuple(members), tuple(tree)))
    return bodies, body_of


def _kinds(linkage: Linkage, pairs: tuple[int, ...]) -> str:
    return "".join(linkage.pairs[k].kind for k in pairs)


def _find_dyad(linkage, edges, known, unknown) -> AssurGroup | None:
    for k, a, b in edges:
        if a not in unknown or b not in unknown:
            continue
        inside = [
            e for e in edges if (e[1] in (a, b) or e[2] in (a, b)) and e[1] in known | {a, b} and e[2] in known | {a, b}
        ]
        if len(inside) != 3:
            continue
        ext_a = [e for e in inside if a in e[1:] and b not in e[1:]]
        ext_b = [e for e in inside if b in e[1:] and a not in e[1:]]
        if len(ext_a) != 1 or len(ext_b) != 1:
            continue
        pairs = (ext_a[0][0], k, ext_b[0][0])
        bodies = (a, b)
        kind = _kinds(linkage, pairs)
        if kind in ("PRR", "PPR"):
            pairs, bodies, kind = pairs[::-1], bodies[::-1], kind[::-1]
        if kind == "PPP":
            names = " and ".join(linkage.links[x].name for x in (a, b))
            raise LinkageFileError(
                f"links {names} form a dyad of three prismatic pairs (PPP): it can translate freely, "
                "so it is not an Assur group; replace one prismatic pair by a revolute"
            )
        return AssurGroup(kind, bodies, pairs)
    return None


def _find_triad(edges, known, unknown, linkage) -> AssurGroup | None:
    for t in sorted(unknown):
        to_unknown = [e for e in edges if t in e[1:] and (e[1] if e[2] == t else e[2]) in unknown]
        for chosen in combinations(to_unknown, 3):
            legs = [e[1] if e[2] == t else e[2] for e in chosen]
            if len(set(legs)) != 3 or t in legs:
                continue
            group = set(legs) | {t}
            inside = [
                e for e in edges if (e[1] in group or e[2] in group) and e[1] in known | group and e[2] in known | group
            ]
            if len(inside) != 6:
                continue
            pairs: list[int] = []
            kinds: list[str] = []
            ok = True
            for leg, internal in zip(legs, chosen):
                ext = [e for e in inside if leg in e[1:] and e is not internal]
                if len(ext) != 1 or (ext[0][1] in group and ext[0][2] in group):
                    ok = False
                    break
                pairs += [ext[0][0], internal[0]]
                kinds.append(linkage.pairs[ext[0][0]].kind + linkage.pairs[internal[0]].kind)
            if not ok:
                continue
            if "PP" in kinds:
                j = kinds.index("PP")
                joints = " and ".join(repr(linkage.pairs[k].joint) for k in pairs[2 * j : 2 * j + 2])
                raise LinkageFileError(f"a class III triad leg with two prismatic pairs ({joints}) is not supported")
            return AssurGroup("triad", (t, *legs), tuple(pairs), tuple(kinds))
    return None
