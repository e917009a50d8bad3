"""Minimum-zone lines and circles through sampled coupler paths (docs/curvature.md §3).

:func:`path_deviation` is the one definition of a path's signed distance from a line or a
circle; :func:`minimum_zone_fit` moves a line or circle towards the minimum-zone (Chebyshev,
minimax) one through path samples — Lawson's iteratively reweighted least squares on the fit
linearised about the current geometry (C. L. Lawson, 1961; batched closed-form 2×2/3×3 solves);
:func:`peak_deviation` is the largest deviation over samples, raised to the parabola's vertex
between them. Units: crank lengths, radians. Used by the segment search (``synth.segments``)
and the dwell bounds (``synth.dwell_bounds``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinematics.loop import parabola_vertex
from synth.kinds import SegmentKind
from synth.types import C128, F64

__all__ = ["minimum_zone_fit", "path_deviation", "peak_deviation"]


def path_deviation(z: C128, kind: NDArray[np.integer] | int, point: C128, direction: C128, radius: F64) -> F64:
    """Signed distance of path points ``z`` from a line (``kind`` ``SegmentKind.LINE.code``:
    through ``point`` along unit ``direction``, positive to its left) or a circle
    (``SegmentKind.ARC.code``: centre ``point``, ``radius``, positive outside). Arguments
    broadcast."""
    kind = np.asarray(kind)
    if kind.size and np.all(kind == kind.flat[0]):  # one kind: compute only its distance
        if kind.flat[0] == SegmentKind.LINE.code:
            return np.broadcast_to(np.imag(np.conj(direction) * (z - point)), np.broadcast_shapes(np.shape(z), kind.shape, np.shape(point), np.shape(direction)))
        return np.broadcast_to(np.abs(z - point) - radius, np.broadcast_shapes(np.shape(z), kind.shape, np.shape(point), np.shape(radius)))
    line = np.imag(np.conj(direction) * (z - point))
    circle = np.abs(z - point) - radius
    return np.where(kind == SegmentKind.LINE.code, line, circle)


def _solve_symmetric(M: dict[tuple[int, int], F64], rhs: list[F64]) -> list[F64]:
    """x with M·x = rhs for batches of symmetric 2×2 or 3×3 systems (entries M[i, k], i ≤ k,
    each of shape (n,)), by Cramer's rule: far cheaper than a batched LAPACK call at this size."""
    if len(rhs) == 2:
        a, b, c = M[0, 0], M[0, 1], M[1, 1]
        det = a * c - b * b
        return [(c * rhs[0] - b * rhs[1]) / det, (a * rhs[1] - b * rhs[0]) / det]
    a, b, c, d, e, f = M[0, 0], M[0, 1], M[0, 2], M[1, 1], M[1, 2], M[2, 2]
    # cofactors of the symmetric matrix [[a b c] [b d e] [c e f]]
    A, B, C = d * f - e * e, c * e - b * f, b * e - c * d
    D, E, F = a * f - c * c, b * c - a * e, a * d - b * b
    det = a * A + b * B + c * C
    r0, r1, r2 = rhs
    return [(A * r0 + B * r1 + C * r2) / det, (B * r0 + D * r1 + E * r2) / det, (C * r0 + E * r1 + F * r2) / det]


def _lawson(cols: list[F64], r0: F64, iterations: int) -> F64:
    """Approximate Chebyshev (minimax) solution x of r0 ≈ Σ x_k·cols[k], batched over the
    first axis (Lawson's iteratively reweighted least squares; each column (n, samples), 2
    or 3 of them). Returns the best x seen, (n, p)."""
    n, size = r0.shape
    p = len(cols)
    w = np.full((n, size), 1.0 / size)
    best_x = np.zeros((n, p))
    best_h = np.abs(r0).max(axis=1)
    for _ in range(iterations):
        wc = [w * col for col in cols]
        M = {(i, k): np.einsum("ij,ij->i", wc[i], cols[k]) for i in range(p) for k in range(i, p)}
        # ridge: keeps near-singular fits (a stretch seen almost edge-on) finite
        ridge = 1e-13 * sum(M[i, i] for i in range(p)) + 1e-300
        for i in range(p):
            M[i, i] = M[i, i] + ridge
        with np.errstate(divide="ignore", invalid="ignore"):
            x = _solve_symmetric(M, [np.einsum("ij,ij->i", wc[i], r0) for i in range(p)])
        # a singular system (a column that vanishes on every sample) leaves the geometry as it is
        x = [np.where(np.isfinite(v), v, 0.0) for v in x]
        res = r0 - x[0][:, None] * cols[0]
        for i in range(1, p):
            res -= x[i][:, None] * cols[i]
        np.abs(res, out=res)
        h = res.max(axis=1)
        better = h < best_h
        best_x[better] = np.stack(x, axis=1)[better]
        best_h = np.where(better, h, best_h)
        w *= res
        total = w.sum(axis=1, keepdims=True)
        w = np.where(total > 0, w / np.where(total > 0, total, 1.0), 1.0 / size)
    return best_x


def minimum_zone_fit(z: C128, kind: int, point: C128, direction: C128, radius: F64, iterations: int):
    """Minimum-zone line (``kind`` ``SegmentKind.LINE.code``) or circle (``ARC.code``) through
    path samples ``z`` (n, samples),
    starting from the given one.

    Linearised about the current geometry: a line moves by δo along its normal and turns by
    δβ; a circle's centre moves by δc and its radius by δρ (first order in the change, which
    is of the order of the band over the stretch)."""
    r0 = path_deviation(z, kind, point[:, None], direction[:, None], radius[:, None])
    rel = z - point[:, None]
    if kind == SegmentKind.LINE.code:
        # r ≈ r0 − δo − δβ·s (s along the line, scaled to O(1) for conditioning)
        s = np.real(np.conj(direction[:, None]) * rel)
        scale = np.maximum(np.abs(s).max(axis=1), 1e-12)
        x = _lawson([np.ones_like(s), s / scale[:, None]], r0, iterations)
        return point + 1j * direction * x[:, 0], direction * np.exp(1j * x[:, 1] / scale), radius
    # r ≈ r0 − Re(δc·conj(e)) − δρ, e the unit vector from the centre. On a short arc e hardly
    # turns, so its components are nearly constant: centred and scaled to O(1), the columns
    # stay independent enough for the closed-form solve (the constant absorbs their means).
    e = rel / np.maximum(np.abs(rel), 1e-300)
    cols, means, scales = [], [], []
    for comp in (e.real, e.imag):
        mean = comp.mean(axis=1, keepdims=True)
        scale = np.maximum(np.abs(comp - mean).max(axis=1, keepdims=True), 1e-12)
        cols.append((comp - mean) / scale)
        means.append(mean[:, 0])
        scales.append(scale[:, 0])
    x = _lawson([*cols, np.ones_like(r0)], r0, iterations)
    dcx, dcy = x[:, 0] / scales[0], x[:, 1] / scales[1]
    return point + dcx + 1j * dcy, direction, radius + x[:, 2] - dcx * means[0] - dcy * means[1]


def peak_deviation(absdev: F64, mask: NDArray[np.bool_]) -> F64:
    """Largest |deviation| over the masked samples, with each interior local maximum raised
    to the vertex of the parabola through it and its neighbours: a fitted band touches ε
    between samples too, and the band must hold on the whole interval, not only at samples."""
    d = np.where(mask, absdev, 0.0)
    h = d.max(axis=1)
    mid = d[:, 1:-1]
    row, col = np.nonzero((mid >= d[:, :-2]) & (mid >= d[:, 2:]) & mask[:, :-2] & mask[:, 2:])
    # few peaks per row: the parabola only where there is one
    top = d[row, col + 1]
    vertex = parabola_vertex(d[row, col], top, d[row, col + 2])
    np.maximum.at(h, row, top + np.where(vertex.curvature < 0, vertex.rise, 0.0))
    return h
