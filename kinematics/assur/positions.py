"""Positions of a general linkage: every assembly configuration, and one configuration tracked
over a sweep of the inputs.

The Assur groups of :func:`~kinematics.assur.topology.decompose` are solved in order; a
*configuration* is one choice per group (a dyad's branch, a triad's real root), and a linkage
has up to 2ᵈ·6ᵗ of them (d dyads with two branches, t triads). :func:`configurations` lists
all that assemble at one input position; :func:`assemble` follows one of them along a sweep —
dyads keep their branch (closed form, vectorized over the positions), triads are followed by
continuity (at every position all real roots are found and the one nearest the previous pose is
kept; the sweep is subdivided internally so that no input moves more than 1° or 1/200 of the
linkage size between two solves).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from kinematics.assur import dyads
from kinematics.assur.model import Linkage, RevolutePair
from kinematics.assur.pairs import Joint, Pin, Sleeve, Slide, sleeve, slide_from_block, slide_from_guide
from kinematics.assur.topology import AssurGroup, Decomposition, decompose
from kinematics.assur.triads import leg_equation, leg_pose, solve_triad
from kinematics.status import AssemblyError, Status

__all__ = [
    "MAX_CONFIGURATIONS",
    "MAX_PARTIAL_CONFIGURATIONS",
    "Assembly",
    "ConfigurationLimit",
    "assemble",
    "configurations",
    "loop_closure",
]

#: Most configurations :func:`configurations` lists at one position (a chain of n dyads has 2ⁿ:
#: 18 dyads took 75 s and 600 MB to list 262 144 of them).
MAX_CONFIGURATIONS = 1024
#: Most partial configurations (a choice for the first groups) tried while listing: bounds the
#: work when deep groups fail to assemble on most branches.
MAX_PARTIAL_CONFIGURATIONS = 100_000


class ConfigurationLimit(AssemblyError):
    """The configurations at a position are more than can be listed (one line: how many groups,
    the limit, and how to follow one configuration instead)."""


_DYAD_SOLVERS = {
    "RRR": dyads.solve_rrr,
    "RRP": dyads.solve_rrp,
    "RPR": dyads.solve_rpr,
    "PRP": dyads.solve_prp,
    "RPP": dyads.solve_rpp,
}
#: Largest input change between two triad solves while tracking: 1° for angles, 1/200 of the
#: linkage size for slides.
_TRACK_STEP_ANGLE = np.radians(1.0)
_TRACK_STEP_LENGTH = 1 / 200
#: Positions put into a step that needs a closer look, and the smallest step (in units of the
#: tracking step) below which a configuration that cannot be followed has ended.
_REFINE = 8
_MIN_STEP = 1e-6
#: Largest loop-closure error (relative to the linkage size) of a configuration that is kept.
_CLOSURE = 1e-9
#: A tracked root farther than this fraction of the distance to the next root is ambiguous.
_AMBIGUOUS = 0.25


@dataclass(frozen=True, slots=True)
class Assembly:
    """The linkage at M input positions in one configuration (struct of arrays).

    Attributes
    ----------
    inputs : float64 (M, k)
        Input values (rad for angles, length for slides), in the linkage's input order.
    r, e : complex128 (M, n)
        Pose of every link: frame origin r (length) and unit phasor e = e^{iθ}; link 0 is the
        ground (r = 0, e = 1).
    status : uint8 (M,)
        :class:`~kinematics.status.Status`: NOT_ASSEMBLABLE where this configuration does not
        exist, TOGGLE where two configurations meet.
    choice : tuple of int
        Per group: the dyad branch (+1/−1, 0 for a single-solution dyad) or the triad's root
        number (1-based, by increasing θ of its ternary link) at the first position.
    """

    inputs: np.ndarray
    r: np.ndarray
    e: np.ndarray
    status: np.ndarray
    choice: tuple[int, ...]

    @property
    def theta(self) -> np.ndarray:
        """Link angles θ = arg e in (−π, π], (M, n)."""
        return np.angle(self.e)

    def point(self, link: int, p: complex) -> np.ndarray:
        """Global position of local point ``p`` of ``link``, (M,)."""
        return self.r[:, link] + self.e[:, link] * p

    def at(self, index: int) -> Assembly:
        """The single position ``index`` (M = 1)."""
        return self.rows(slice(index, index + 1))

    def rows(self, index) -> Assembly:
        """The positions ``index`` (a slice, integer array or mask)."""
        return Assembly(self.inputs[index], self.r[index], self.e[index], self.status[index], self.choice)


def loop_closure(linkage: Linkage, assembly: Assembly) -> np.ndarray:
    """Largest violation of any pair at each position, as a length (M,).

    Revolute: |B_i(p_i) − B_j(p_j)|. Prismatic: distance of the block point from the guide line
    and L·|sin| of the angle between block and guide directions (L the linkage size).
    """
    L = linkage.length_scale
    out = np.zeros(assembly.r.shape[0])
    for pair in linkage.pairs:
        if isinstance(pair, RevolutePair):
            (i, j), (pi, pj) = pair.links, pair.at
            err = np.abs(assembly.point(i, pi) - assembly.point(j, pj))
        else:
            g, b = pair.guide, pair.block
            U = assembly.e[:, g] * pair.direction
            d = assembly.point(b, pair.block_point) - assembly.point(g, pair.through)
            across = np.abs((np.conj(U) * d).imag)
            twist = L * np.abs((np.conj(U) * assembly.e[:, b] * pair.block_direction).imag)
            err = np.maximum(across, twist)
        out = np.maximum(out, err)
    return out


# -- building blocks ---------------------------------------------------------------------------


class _State:
    """Poses being filled in group by group, plus each link's place in its body."""

    def __init__(self, linkage: Linkage, dec: Decomposition, inputs: np.ndarray):
        self.linkage, self.dec = linkage, dec
        M, n = inputs.shape[0], len(linkage.links)
        self.M = M
        self.r = np.zeros((M, n), complex)
        self.e = np.ones((M, n), complex)
        self.status = np.zeros(M, np.uint8)
        # pose of each link in its body's frame (the driven pairs fix it)
        self.mr = np.zeros((M, n), complex)
        self.me = np.ones((M, n), complex)
        for body in dec.bodies:
            for link, parent, k in body.tree:
                rel_r, rel_e = _driven_transform(linkage, k, parent, inputs[:, k])
                self.mr[:, link] = self.mr[:, parent] + self.me[:, parent] * rel_r
                self.me[:, link] = self.me[:, parent] * rel_e
        self.set_body(dec.body_of[0], np.zeros(M, complex), np.ones(M, complex))

    def set_body(self, body: int, R, E, rows=slice(None)) -> None:
        for link in self.dec.bodies[body].members:
            self.r[rows, link] = R + E * self.mr[rows, link]
            self.e[rows, link] = E * self.me[rows, link]

    # body-frame geometry of a link's point and direction
    def local(self, link: int, p: complex) -> np.ndarray:
        return self.mr[:, link] + self.me[:, link] * p

    def turn(self, link: int, u: complex) -> np.ndarray:
        return self.me[:, link] * u

    def world(self, link: int, p: complex) -> np.ndarray:
        return self.r[:, link] + self.e[:, link] * p


def _driven_transform(linkage: Linkage, k: int, parent: int, value: np.ndarray):
    """Pose of the child link of driven pair ``k`` in ``parent``'s frame, for input values."""
    inp = linkage.inputs[k]
    pair = linkage.pairs[inp.pair]
    if isinstance(pair, RevolutePair):
        rot = np.exp(1j * value)  # θ_link − θ_relative_to
        (a, b), (pa, pb) = pair.links, pair.at
        p_parent, p_child = (pa, pb) if a == parent else (pb, pa)
        child = b if a == parent else a
        rel_e = rot if child == inp.link else np.conj(rot)
        return p_parent - rel_e * p_child, rel_e
    # prismatic: block pose in the guide frame is (q + s·u − ρ·o, ρ) with ρ = u·conj(w)
    rho = pair.direction * np.conj(pair.block_direction)
    rel_r = pair.through + value * pair.direction - rho * pair.block_point
    rel_e = np.full_like(rel_r, rho)
    if parent == pair.guide:
        return rel_r, rel_e
    return -np.conj(rel_e) * rel_r, np.conj(rel_e)


def _external(state: _State, k: int, body: int) -> Pin | Slide:
    """Pair ``k`` seen from unknown ``body`` whose other side is known."""
    pair = state.linkage.pairs[k]
    mine = state.dec.body_of
    if isinstance(pair, RevolutePair):
        (a, b), (pa, pb) = pair.links, pair.at
        if mine[a] == body:
            a, b, pa, pb = b, a, pb, pa
        return Pin(state.world(a, pa), state.local(b, pb))
    if mine[pair.block] == body:  # the known link carries the guide
        g = pair.guide
        return slide_from_guide(
            state.world(g, pair.through),
            state.e[:, g] * pair.direction,
            state.local(pair.block, pair.block_point),
            state.turn(pair.block, pair.block_direction),
        )
    b = pair.block
    return slide_from_block(
        state.world(b, pair.block_point),
        state.e[:, b] * pair.block_direction,
        state.local(pair.guide, pair.through),
        state.turn(pair.guide, pair.direction),
    )


def _internal(state: _State, k: int, body1: int) -> Joint | Sleeve:
    """Pair ``k`` between two unknown bodies, read from ``body1`` to the other."""
    pair = state.linkage.pairs[k]
    mine = state.dec.body_of
    if isinstance(pair, RevolutePair):
        (a, b), (pa, pb) = pair.links, pair.at
        if mine[a] != body1:
            a, b, pa, pb = b, a, pb, pa
        return Joint(state.local(a, pa), state.local(b, pb))
    return sleeve(
        mine[pair.guide] == body1,
        state.local(pair.guide, pair.through),
        state.turn(pair.guide, pair.direction),
        state.local(pair.block, pair.block_point),
        state.turn(pair.block, pair.block_direction),
    )


def _solve_dyad(state: _State, group: AssurGroup, branch: int) -> np.ndarray:
    b1, b2 = group.bodies
    e1, i, e2 = group.pairs
    views = (_external(state, e1, b1), _internal(state, i, b1), _external(state, e2, b2))
    r1, q1, r2, q2, status = _DYAD_SOLVERS[group.kind](*views, branch)
    state.set_body(b1, r1, q1)
    state.set_body(b2, r2, q2)
    return np.broadcast_to(status, (state.M,))


def _triad_views(state: _State, group: AssurGroup):
    t, *legs = group.bodies
    views = []
    for leg, ext, internal in zip(legs, group.pairs[0::2], group.pairs[1::2]):
        views.append((_external(state, ext, leg), _internal(state, internal, leg)))
    return views


def _triad_roots(state: _State, group: AssurGroup):
    views = _triad_views(state, group)
    eqs = [leg_equation(x, y, (state.M,)) for x, y in views]
    return views, solve_triad(eqs, state.linkage.length_scale)


def _set_triad(state: _State, group: AssurGroup, views, rows, X, e) -> None:
    t, *legs = group.bodies
    state.set_body(t, X, e, rows)
    for leg, (x, y) in zip(legs, views):
        r, q = leg_pose(x, y, X, e, rows, state.M)
        state.set_body(leg, r, q, rows)


def _prepare(linkage: Linkage, inputs) -> tuple[Decomposition, np.ndarray]:
    values = np.asarray(inputs, float)
    k = len(linkage.inputs)
    if values.ndim <= 1 and values.size == k:
        values = values.reshape(1, k)
    if values.ndim != 2 or values.shape[1] != k:
        raise ValueError(f"inputs must have shape (M, {k}), got {np.shape(inputs)}")
    return decompose(linkage), values


# -- all configurations at one position ---------------------------------------------------------


def configurations(
    linkage: Linkage, inputs, *, decomposition: Decomposition | None = None, limit: int = MAX_CONFIGURATIONS
) -> list[Assembly]:
    """The configurations that assemble at one input position (``inputs``: k values): all of
    them, or the first ``limit`` (the list then has exactly ``limit`` items; the caller can tell).

    Ordered by group: branch +1 before −1, triad roots by increasing angle of the ternary link.
    An empty list means the linkage cannot assemble there. Raises :class:`ConfigurationLimit`
    when more than :data:`MAX_PARTIAL_CONFIGURATIONS` partial choices would have to be tried.
    """
    dec, values = (
        _prepare(linkage, inputs)
        if decomposition is None
        else (decomposition, np.asarray(inputs, float).reshape(1, -1))
    )
    if values.shape[0] != 1:
        raise ValueError("configurations() takes one input position")
    out: list[Assembly] = []
    tried = [0]
    for state, choice in _branches(linkage, dec, values, 0, _State(linkage, dec, values), (), tried):
        found = Assembly(values.copy(), state.r.copy(), state.e.copy(), state.status.copy(), choice)
        if loop_closure(linkage, found)[0] <= _CLOSURE * linkage.length_scale:  # checked, not assumed
            out.append(found)
            if len(out) >= limit:
                break
    return out


def _branches(
    linkage, dec, values, g, state: _State, choice, tried: list[int]
) -> Iterator[tuple[_State, tuple[int, ...]]]:
    """Depth first over the groups' choices; ``tried`` counts partial configurations."""
    tried[0] += 1
    if tried[0] > MAX_PARTIAL_CONFIGURATIONS:
        dyads = sum(gr.is_dyad for gr in dec.groups)
        raise ConfigurationLimit(
            f"{linkage.name}: its {dyads} dyad(s) and {len(dec.groups) - dyads} triad(s) have up to "
            f"2^{dyads}·6^{len(dec.groups) - dyads} assembly configurations; {MAX_PARTIAL_CONFIGURATIONS} partial "
            "ones were tried without finding enough that assemble (it may not assemble at this position)"
        )
    if g == len(dec.groups):
        yield state, choice
        return
    group = dec.groups[g]
    if group.is_dyad:
        options = (1, -1) if group.kind in ("RRR", "RRP", "RPR") else (0,)
        for branch in options:
            trial = _copy(state)
            status = _solve_dyad(trial, group, branch)
            if status[0] & Status.NOT_ASSEMBLABLE or (branch == -1 and status[0] & Status.TOGGLE):
                continue
            trial.status |= status
            yield from _branches(linkage, dec, values, g + 1, trial, choice + (branch,), tried)
        return
    views, roots = _triad_roots(state, group)
    for n in range(roots.position.size):
        trial = _copy(state)
        rows = np.zeros(1, int)
        _set_triad(trial, group, views, rows, roots.X[n : n + 1], roots.e[n : n + 1])
        yield from _branches(linkage, dec, values, g + 1, trial, choice + (n + 1,), tried)


def _copy(state: _State) -> _State:
    new = object.__new__(_State)
    new.linkage, new.dec, new.M = state.linkage, state.dec, state.M
    for name in ("r", "e", "status", "mr", "me"):
        setattr(new, name, getattr(state, name).copy())
    return new


# -- one configuration along a sweep ---------------------------------------------------------


def assemble(linkage: Linkage, inputs, start: Assembly, *, decomposition: Decomposition | None = None) -> Assembly:
    """Follow the configuration of ``start`` (one position, from :func:`configurations`) to the
    input positions ``inputs`` (M × k), in order.

    Dyads keep their branch. Triads are tracked by continuity from ``start``'s pose along the
    path start → inputs[0] → inputs[1] → …; where the tracked root disappears (the input left
    the range this configuration reaches) the remaining positions are NOT_ASSEMBLABLE.
    """
    dec, values = _prepare(linkage, inputs) if decomposition is None else (decomposition, np.asarray(inputs, float))
    if len(start.choice) != len(dec.groups):
        raise ValueError("start does not belong to this linkage")
    if all(g.is_dyad for g in dec.groups):
        state = _State(linkage, dec, values)
        for group, branch in zip(dec.groups, start.choice):
            state.status |= _solve_dyad(state, group, branch)
        return Assembly(values, state.r, state.e, state.status, start.choice)
    path, original = _subdivide(linkage, np.vstack([start.inputs[:1], values]))
    steps = _track_steps(linkage)
    while True:
        state = _State(linkage, dec, path)
        refine = None
        for group, choice in zip(dec.groups, start.choice):
            if group.is_dyad:
                state.status |= _solve_dyad(state, group, choice)
                continue
            views, roots = _triad_roots(state, group)
            root = dec.bodies[group.bodies[0]].root  # the body's frame is its root link's
            X, E, status, refine = _track(roots, path, steps, start.r[0, root], start.e[0, root], linkage.length_scale)
            if refine is not None:
                break
            rows = np.flatnonzero(status == 0)
            _set_triad(state, group, views, rows, X[rows], E[rows])
            state.status |= status
        if refine is None:
            break
        # an ambiguous or jumping step: put more positions into it and follow again
        f = (np.arange(1, _REFINE) / _REFINE)[:, None]
        extra = path[refine - 1] + f * (path[refine] - path[refine - 1])
        path = np.vstack([path[:refine], extra, path[refine:]])
        original = np.concatenate([original[:refine], np.zeros(_REFINE - 1, bool), original[refine:]])
    keep = np.flatnonzero(original)
    out = Assembly(values, state.r[keep], state.e[keep], state.status[keep], start.choice)
    open_loop = loop_closure(linkage, out) > _CLOSURE * linkage.length_scale
    return Assembly(
        values,
        out.r,
        out.e,
        out.status | np.where(open_loop, np.uint8(Status.NOT_ASSEMBLABLE), 0).astype(np.uint8),
        start.choice,
    )


def _track_steps(linkage: Linkage) -> np.ndarray:
    return np.array(
        [_TRACK_STEP_ANGLE if i.kind == "angle" else _TRACK_STEP_LENGTH * linkage.length_scale for i in linkage.inputs]
    )


def _subdivide(linkage: Linkage, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Insert positions so that no input moves more than the tracking step.

    Returns the path (its first row is the start) and a mask of the rows of ``values[1:]``.
    """
    if values.shape[1] == 0:
        return values, np.arange(values.shape[0]) > 0
    jumps = np.abs(np.diff(values, axis=0)) / _track_steps(linkage)
    counts = np.maximum(1, np.ceil(jumps.max(axis=1)).astype(int))
    pieces, mask = [values[:1]], [False]
    for i, c in enumerate(counts):
        f = (np.arange(1, c + 1) / c)[:, None]
        pieces.append(values[i] + f * (values[i + 1] - values[i]))
        mask += [False] * (c - 1) + [True]
    return np.vstack(pieces), np.asarray(mask)


def _track(roots, path: np.ndarray, steps: np.ndarray, X_prev: complex, e_prev: complex, scale: float):
    """Pick at each position the root nearest the previous pose (distance |ΔX| + L·|Δθ|).

    A step is trusted when its root is unambiguous — less than a quarter as far as the next
    nearest — and it moves at most ten times as far as the step before (scaled by the input
    steps). Near a fold the tracked root and the one it merges with approach like √δ (δ the
    input's distance to the fold), so the step before the fold is always ambiguous by this
    test (its ratio is at least 1 − √½ ≈ 0.29 for equal steps). An untrusted step is returned as
    ``refine`` to be subdivided, unless it is already below the smallest step: then the
    configuration ends there and the rest is NOT_ASSEMBLABLE.
    """
    M = path.shape[0]
    X = np.zeros(M, complex)
    E = np.ones(M, complex)
    status = np.full(M, np.uint8(Status.NOT_ASSEMBLABLE))
    bounds = np.searchsorted(roots.position, np.arange(M + 1))
    size = (np.abs(np.diff(path, axis=0)) / steps).max(axis=1, initial=0.0) if M > 1 else np.zeros(0)
    moved = None
    for m in range(M):
        lo, hi = bounds[m], bounds[m + 1]
        trusted = hi > lo
        if trusted:
            dist = np.abs(roots.X[lo:hi] - X_prev) + scale * np.abs(np.angle(roots.e[lo:hi] * np.conj(e_prev)))
            order = np.argsort(dist)
            k = int(order[0])
            if m > 0 and order.size > 1 and dist[k] > _AMBIGUOUS * dist[order[1]]:
                trusted = False
            if (
                moved is not None
                and size[m - 2] > 0
                and dist[k] > 10 * moved * size[m - 1] / size[m - 2] + 1e-6 * scale
            ):
                trusted = False
        if not trusted:
            if m > 0 and size[m - 1] > _MIN_STEP:
                return X, E, status, m
            break
        if m > 0:
            moved = float(dist[k])
        X_prev, e_prev = roots.X[lo + k], roots.e[lo + k]
        X[m], E[m], status[m] = X_prev, e_prev, 0
    return X, E, status, None
