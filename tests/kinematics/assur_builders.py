"""Random linkages that assemble by construction (for the Assur-group property tests).

Every builder first draws the pose of every link at the crank angle φ0 and only then derives
the description (local points, guide lines), so the drawn pose is one of the configurations the
solver must return. A crank O→A (O at the origin) drives the group; the group's external pairs
go to the crank and to the ground.
"""

from __future__ import annotations

import cmath
import math
from pathlib import Path

import numpy as np
from hypothesis import assume

from kinematics.assur import Assembly, assemble, linkage_from_mapping, linkage_from_text, linkage_motion
from kinematics.status import Status

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "linkages"


def example(name: str):
    """A linkage of ``examples/linkages``."""
    return linkage_from_text((EXAMPLES / name).read_text())


def xy(z: complex) -> list[float]:
    return [z.real, z.imag]


class Builder:
    """Collects links and pairs of a description while the poses are known."""

    def __init__(self, phi0: float, crank: float):
        self.phi0 = phi0
        self.poses = {"ground": (0j, 1 + 0j), "crank": (0j, cmath.exp(1j * phi0))}
        self.ground = {"O": [0.0, 0.0]}
        self.links = {"crank": {"points": {"O": [0.0, 0.0], "A": [crank, 0.0]}}}
        self.prismatic = []
        self.names = 0

    def add_link(self, name: str, r: complex, angle: float) -> None:
        self.poses[name] = (r, cmath.exp(1j * angle))
        self.links[name] = {"points": {}}

    def local(self, link: str, z: complex) -> complex:
        r, e = self.poses[link]
        return (z - r) / e

    def world(self, link: str, p: complex) -> complex:
        r, e = self.poses[link]
        return r + e * p

    def put(self, link: str, name: str, z: complex) -> None:
        if link == "ground":
            self.ground[name] = xy(z)
        else:
            self.links[link]["points"][name] = xy(self.local(link, z))

    def revolute(self, a: str, b: str, at: complex) -> str:
        self.names += 1
        name = f"J{self.names}"
        self.put(a, name, at)
        self.put(b, name, at)
        return name

    def prismatic_pair(self, guide: str, block: str, at: complex, direction_angle: float, block_angle: float) -> str:
        """A prismatic pair whose block point sits at global ``at`` on a line of global direction."""
        self.names += 1
        name = f"P{self.names}"
        U = cmath.exp(1j * direction_angle)
        through = at - 0.37 * U  # a point of the line a little behind the block
        rg, eg = self.poses[guide]
        rb, eb = self.poses[block]
        u_local = U / eg
        w_local = U / eb
        self.prismatic.append(
            {
                "name": name,
                "guide": guide,
                "block": block,
                "through": xy(self.local(guide, through)),
                "angle": math.degrees(cmath.phase(u_local)),
                "block_point": xy(self.local(block, at)),
                "block_angle": math.degrees(cmath.phase(w_local)),
            }
        )
        return name

    def pair(self, kind: str, a: str, b: str, at: complex, angle: float, guide_first: bool) -> str:
        if kind == "R":
            return self.revolute(a, b, at)
        guide, block = (a, b) if guide_first else (b, a)
        return self.prismatic_pair(guide, block, at, angle, 0.0)

    def description(self, output: dict | None = None) -> dict:
        doc = {
            "name": "random",
            "units": "mm",
            "ground": self.ground,
            "links": self.links,
            "prismatic": self.prismatic,
            "inputs": [{"joint": "O", "link": "crank", "value": math.degrees(self.phi0)}],
        }
        if output:
            doc["output"] = output
        return doc

    def linkage(self):
        return linkage_from_mapping(self.description())

    def assembly(self, linkage) -> Assembly:
        """The drawn pose as an Assembly (one position)."""
        n = len(linkage.links)
        r = np.zeros((1, n), complex)
        e = np.ones((1, n), complex)
        for i, link in enumerate(linkage.links):
            r[0, i], e[0, i] = self.poses[link.name]
        return Assembly(np.array([[self.phi0]]), r, e, np.zeros(1, np.uint8), ())


def dyad_linkage(kinds: str, values: list[float], flips: list[bool]):
    """Crank + a dyad with pairs ``kinds`` (E1 to the crank, I, E2 to the ground).

    ``values``: 12 numbers in [0, 1) that place everything; ``flips``: which side of each
    prismatic pair carries the guide.
    """
    v = iter(values)
    nxt = lambda lo, hi: lo + (hi - lo) * next(v)  # noqa: E731
    phi0 = nxt(-math.pi, math.pi)
    b = Builder(phi0, nxt(20, 40))
    b.add_link("L1", complex(nxt(-60, 60), nxt(-60, 60)), nxt(-math.pi, math.pi))
    b.add_link("L2", complex(nxt(-60, 60), nxt(-60, 60)), nxt(-math.pi, math.pi))
    A = b.world("crank", complex(b.links["crank"]["points"]["A"][0], 0))
    B = complex(nxt(-80, 80), nxt(-80, 80))
    C = complex(nxt(-100, 100), nxt(-100, 100))
    angles = [nxt(-math.pi, math.pi) for _ in range(3)]
    b.pair(kinds[0], "crank", "L1", A, angles[0], flips[0])
    b.pair(kinds[1], "L1", "L2", B, angles[1], flips[1])
    b.pair(kinds[2], "L2", "ground", C, angles[2], flips[2])
    return b


def triad_linkage(legs: list[str], values: list[float], flips: list[bool]):
    """Crank + a class III triad; leg i's type ``legs[i]`` is (external, internal). Leg 1 hangs
    from the crank, legs 2 and 3 from the ground. ``values``: 24 numbers in [0, 1)."""
    v = iter(values)
    nxt = lambda lo, hi: lo + (hi - lo) * next(v)  # noqa: E731
    phi0 = nxt(-math.pi, math.pi)
    b = Builder(phi0, nxt(10, 30))
    b.add_link("T", complex(nxt(-30, 30), nxt(-30, 30)), nxt(-math.pi, math.pi))
    A = b.world("crank", complex(b.links["crank"]["points"]["A"][0], 0))
    for i, kinds in enumerate(legs):
        leg = f"leg{i + 1}"
        b.add_link(leg, complex(nxt(-80, 80), nxt(-80, 80)), nxt(-math.pi, math.pi))
        known = "crank" if i == 0 else "ground"
        ext = A if i == 0 else complex(nxt(-120, 120), nxt(-120, 120))
        internal = b.world("T", complex(nxt(-40, 40), nxt(-40, 40)))
        b.pair(kinds[0], known, leg, ext, nxt(-math.pi, math.pi), flips[2 * i])
        b.pair(kinds[1], leg, "T", internal, nxt(-math.pi, math.pi), flips[2 * i + 1])
    return b


def check_derivatives(lk, config, phi0, h=1e-4):
    """Central differences of positions (velocity) and of velocities (acceleration), with one
    Richardson step (steps h and h/2: error O(h⁴))."""
    L = lk.length_scale
    phi = phi0 + np.array([[-h], [-h / 2], [0.0], [h / 2], [h]])
    asm = assemble(lk, phi, config)
    assume(not np.any(asm.status & Status.NOT_ASSEMBLABLE))
    m = linkage_motion(lk, asm)
    assume(np.all(m.condition > 1e-2))  # finite differences need room to the next toggle

    def diff(x):
        return (4 * (x[3] - x[1]) / h - (x[4] - x[0]) / (2 * h)) / 3

    theta = np.unwrap(np.angle(asm.e), axis=0)
    vs = max(1.0, float(np.max(np.abs(m.v[2]))))
    As = max(1.0, float(np.max(np.abs(m.a[2]))))
    assert np.max(np.abs(diff(asm.r) - m.v[2])) < 1e-6 * vs
    assert np.max(np.abs(diff(theta) - m.omega[2])) * L < 1e-6 * vs
    assert np.max(np.abs(diff(m.v) - m.a[2])) < 1e-5 * As
    assert np.max(np.abs(diff(m.omega) - m.alpha[2])) * L < 1e-5 * As
    if m.s.shape[1]:
        assert np.max(np.abs(diff(m.s) - m.ds[2])) < 1e-6 * vs
