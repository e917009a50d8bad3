"""Limit (dead-centre) positions of a reciprocating output: where its velocity vanishes.

The output y (a link's angle from the ground, or a prismatic pair's displacement) is followed
over the first input's range in one configuration; its derivatives y′ = dy/dx and y″ with
respect to the first input x come from :func:`~kinematics.assur.velocity.linkage_motion`.
Zeros of y′ are bracketed on a dense grid and refined by Brent's method to |Δx| ≤ 1e-13.

Why no zero is missed: y′ changes sign across every simple zero, which the grid brackets.
Two zeros inside one cell leave y′ with the same sign at both ends, but then y″ vanishes
between them (Rolle), so every cell where y″ changes sign is searched too: the extremum x* of
y′ in it (a zero of y″, refined by Brent) splits the cell into two brackets when y′(x*) has the
other sign. Only four or more zeros of y′ inside one cell of the default grid (0.1° for a full
turn) could hide — y‴ would then have to change sign twice within 0.1°.

A limit is a maximum where y″ < 0, a minimum where y″ > 0, and ``"stationary"`` (an inflection
with zero velocity, no reversal) where |y″| is at rounding level. Stroke (or swing) is max − min
of y over the range; for an input that turns fully at constant speed, the time ratio is the
longer over the shorter of the two input intervals between the global minimum and maximum.

References
----------
R. L. Norton, *Design of Machinery*, §3.5 (toggle/limit positions, time ratio).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from kinematics.assur.model import Linkage, Output, PrismaticPair
from kinematics.assur.positions import Assembly, assemble
from kinematics.assur.topology import Decomposition, decompose
from kinematics.assur.velocity import LinkageMotion, linkage_motion
from kinematics.status import AssemblyError, Status

__all__ = ["LimitPosition", "OutputLimits", "limit_positions", "output_at", "output_series"]

_XTOL = 1e-13
_RTOL = 4 * np.finfo(float).eps


@dataclass(frozen=True, slots=True)
class LimitPosition:
    """One position where the output velocity vanishes.

    ``input``: the first input there (rad or length); ``output``: the output there (rad or
    length); ``kind``: ``"max"``, ``"min"`` or ``"stationary"``; ``curvature``: y″ there (per
    input unit²).
    """

    input: float
    output: float
    kind: str
    curvature: float


@dataclass(frozen=True, slots=True)
class OutputLimits:
    """Limit positions of the output over the input range, with stroke and time ratio.

    ``stroke`` is max − min of the output over the range (rad for an angle: the swing).
    ``time_ratio`` (≥ 1), ``advance`` and ``return_`` (input angles from the minimum to the
    maximum and back, rad) exist only for a fully turning, periodic angle input; otherwise None.
    """

    output: Output
    positions: tuple[LimitPosition, ...]
    stroke: float
    output_min: float
    output_max: float
    full_turn: bool
    time_ratio: float | None = None
    advance: float | None = None
    return_: float | None = None


def output_series(linkage: Linkage, motion: LinkageMotion, output: Output) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(y, y′, y″) of ``output`` from a motion computed with unit rate of the first input.

    An angle output is unwrapped along the positions (continuous over a turn).
    """
    if output.kind == "angle":
        y = np.unwrap(motion.assembly.theta[:, output.index])
        return y, motion.omega[:, output.index], motion.alpha[:, output.index]
    col = [i for i, p in enumerate(linkage.pairs) if isinstance(p, PrismaticPair)].index(output.index)
    return motion.s[:, col], motion.ds[:, col], motion.dds[:, col]


def output_at(
    linkage: Linkage, start: Assembly, output: Output, *, decomposition: Decomposition | None = None
) -> Callable[[np.ndarray], np.ndarray]:
    """The exact output y(x) of the configuration of ``start`` as a function of the first
    input x (rad or length; other inputs at the start's values): an array of any shape →
    y of the same shape (an angle on any 2π branch, rad; a slide, length). Positions where
    the configuration does not assemble raise :class:`AssemblyError`.

    Triads are tracked from the start's pose along the inputs in increasing order, so the
    positions may come in any order.
    """
    dec = decompose(linkage) if decomposition is None else decomposition

    def y(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, float)
        flat = x.reshape(-1)
        order = np.argsort(flat, kind="stable")
        rows = np.repeat(start.inputs[:1], flat.size, axis=0)
        rows[:, 0] = flat[order]
        asm = assemble(linkage, rows, start, decomposition=dec)
        if np.any(asm.status & Status.NOT_ASSEMBLABLE):
            bad = float(rows[int(np.argmax((asm.status & Status.NOT_ASSEMBLABLE) != 0)), 0])
            raise AssemblyError(
                f"{linkage.name}: this configuration does not assemble at input {_fmt_input(linkage, bad)}"
            )
        if output.kind == "angle":
            value = asm.theta[:, output.index]
        else:
            pair = linkage.pairs[output.index]
            U = asm.e[:, pair.guide] * pair.direction
            value = (np.conj(U) * (asm.point(pair.block, pair.block_point) - asm.point(pair.guide, pair.through))).real
        out = np.empty_like(flat)
        out[order] = value
        return out.reshape(x.shape)

    return y


def limit_positions(
    linkage: Linkage,
    start: Assembly,
    output: Output,
    *,
    first: float | None = None,
    last: float | None = None,
    samples: int = 3600,
) -> OutputLimits:
    """Limit positions of ``output`` as the first input runs from ``first`` to ``last``.

    ``start`` (one position) picks the configuration. Without ``first``/``last`` an angle
    input makes one full turn from the start's value; a slide input needs both. Other inputs
    stay at the start's values. Raises :class:`AssemblyError` if the configuration does not
    assemble or is singular somewhere on the range (no limit can be trusted across that).
    """
    from scipy.optimize import brentq  # ~1 s to import: on first use, not at every command's start

    if not linkage.inputs:
        raise AssemblyError("limit positions need an input to vary")
    x0 = float(start.inputs[0, 0])
    angle = linkage.inputs[0].kind == "angle"
    if first is None and last is None and angle:
        first, last = x0, x0 + 2 * np.pi
    if first is None or last is None or not last > first:
        raise AssemblyError("limit positions need an input range: --from and --to with --to > --from")
    full_turn = angle and abs((last - first) - 2 * np.pi) < 1e-12
    dec = decompose(linkage)
    grid = np.linspace(first, last, samples + 1)
    inputs = np.repeat(start.inputs[:1], grid.size, axis=0)
    inputs[:, 0] = grid
    asm = assemble(linkage, inputs, start, decomposition=dec)
    motion = linkage_motion(linkage, asm)
    bad = motion.status != 0
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        what = "does not assemble" if motion.status[i] & Status.NOT_ASSEMBLABLE else "is singular"
        raise AssemblyError(
            f"{linkage.name}: this configuration {what} at input {_fmt_input(linkage, grid[i])} "
            "inside the range of the limit-position search"
        )
    y, y1, y2 = output_series(linkage, motion, output)

    def evaluate(x: float, near: int) -> tuple[float, float, float]:
        row = inputs[near : near + 1].copy()
        row[0, 0] = x
        a = assemble(linkage, row, asm.at(near), decomposition=dec)
        m = linkage_motion(linkage, a)
        yy, d1, d2 = output_series(linkage, m, output)
        # keep the angle on the branch of the grid value it came from
        base = y[near]
        val = float(yy[0])
        if output.kind == "angle":
            val = base + float(np.angle(np.exp(1j * (val - base))))
        return val, float(d1[0]), float(d2[0])

    roots: list[float] = []
    last_cell = samples - 1
    tiny = 1e-12 * max(float(np.max(np.abs(y1))), 1e-300)
    zero = np.abs(y1) <= tiny  # y′ vanishes at a grid point (up to rounding)
    done = np.zeros(samples, bool)  # cells already searched
    for j in np.flatnonzero(zero):
        if full_turn and j == samples:
            continue  # the same position as j = 0
        left, right = j - 1, j + 1
        x_left = grid[left] if left >= 0 else (grid[samples - 1] - 2 * np.pi if full_turn else None)
        x_right = grid[right] if right <= samples else None
        y_left = y1[left] if left >= 0 else (y1[samples - 1] if full_turn else 0.0)
        y_right = y1[right] if right <= samples else 0.0
        if left >= 0 or full_turn:
            done[left if left >= 0 else last_cell] = True
        if right <= samples:
            done[j] = True
        if x_left is not None and x_right is not None and y_left * y_right < 0:
            roots.append(brentq(lambda x: evaluate(x, j)[1], x_left, x_right, xtol=_XTOL, rtol=_RTOL))
        else:
            roots.append(grid[j])  # touches zero, or sits at an end of the range
    for i in np.flatnonzero(~done):
        a, b = grid[i], grid[i + 1]
        if y1[i] * y1[i + 1] < 0:
            roots.append(brentq(lambda x: evaluate(x, i)[1], a, b, xtol=_XTOL, rtol=_RTOL))
        elif y2[i] * y2[i + 1] < 0:  # y′ has an extremum inside: two zeros may hide there
            xs = brentq(lambda x: evaluate(x, i)[2], a, b, xtol=_XTOL, rtol=_RTOL)
            mid = evaluate(xs, i)[1]
            if abs(mid) <= tiny:
                roots.append(xs)
            elif mid * y1[i] < 0:
                roots.append(brentq(lambda x: evaluate(x, i)[1], a, xs, xtol=_XTOL, rtol=_RTOL))
                roots.append(brentq(lambda x: evaluate(x, i)[1], xs, b, xtol=_XTOL, rtol=_RTOL))

    found: list[LimitPosition] = []
    scale = max(np.max(np.abs(y2)), 1e-300)
    if full_turn:
        wrapped = (float(np.mod(x - first, 2 * np.pi)) for x in roots)
        roots = [first + (w if w < 2 * np.pi - 1e-9 else 0.0) for w in wrapped]
    for x in sorted(roots):
        if found and abs(x - found[-1].input) < 1e-9:
            continue
        near = int(np.clip(np.searchsorted(grid, x) - 1, 0, samples))
        val, _, curv = evaluate(x, near)
        kind = "stationary" if abs(curv) <= 1e-9 * scale else ("max" if curv < 0 else "min")
        found.append(LimitPosition(float(x), val, kind, curv))
    if full_turn and len(found) > 1 and abs(found[-1].input - found[0].input - 2 * np.pi) < 1e-9:
        found.pop()

    values = np.concatenate([y, [p.output for p in found]])
    lo_i, hi_i = int(np.argmin(values)), int(np.argmax(values))
    y_min, y_max = float(values[lo_i]), float(values[hi_i])
    result = dict(
        output=output,
        positions=tuple(found),
        stroke=y_max - y_min,
        output_min=y_min,
        output_max=y_max,
        full_turn=full_turn,
    )
    periodic = full_turn and _same_pose(asm, 0, samples, linkage.length_scale)
    extremes = [p for p in found if p.kind in ("max", "min")]
    if periodic and len(extremes) >= 2:
        p_max = max(extremes, key=lambda p: p.output)
        p_min = min(extremes, key=lambda p: p.output)
        advance = float(np.mod(p_max.input - p_min.input, 2 * np.pi))
        back = 2 * np.pi - advance
        result.update(time_ratio=max(advance, back) / min(advance, back), advance=advance, return_=back)
    return OutputLimits(**result)


def _same_pose(asm: Assembly, i: int, j: int, scale: float) -> bool:
    dr = np.abs(asm.r[i] - asm.r[j]).max()
    de = np.abs(asm.e[i] - asm.e[j]).max()
    return bool(dr <= 1e-7 * scale and de <= 1e-7)


def _fmt_input(linkage: Linkage, x: float) -> str:
    if linkage.inputs[0].kind == "angle":
        return f"{np.degrees(x):.6g} deg"
    return f"{x:.6g} {linkage.units}"
