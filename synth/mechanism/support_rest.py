"""Short slotted-rocker rests at a coupler curve's support points, compiled: where an RPR
output rests for a short dwell at a small swing.

A slotted rocker whose pivot S lies far along the tangent of the coupler curve at a point
P0 turns, to first order in 1/R (R = |S − P0|), by (P·n − h)/R, where n is the unit normal
of the slot at P0 and h = max P·n the curve's support function in direction n: the output
rests at the support point, swings ≈ W/R over the turn (W = h(n) + h(−n), the curve's width
across the slot) and stays within a band β while P·n stays within β·R ≈ (β/S)·W of h (S
the swing). So, far from the curve, dwell and swing depend on the curve and the direction
only: a rest of the requested length needs the run of crank samples about the support point
within (β/S)·W of its support line to last the dwell (± its tolerance), the run about the
opposite support point to last no longer, and no other stretch of the turn to spread less
than (β/S)·W over more than the dwell — a small swing leaves the output slow everywhere, and
a slow stretch anywhere is a rest. A harmonic output of swing S rests 2·arccos(1 − 2β/S)
(:func:`harmonic_rest`: 23.0° at 10°): a short rest at a small swing needs a curve that
turns sharply at its support points and moves evenly between them, which no stored straight
stretch predicts.

:func:`support_points` tests every direction of a grid on every path; a six-bar with its
slot pivot on the support tangent at the reach that swings the output as asked (≈ W/S far
from the curve; :func:`slot_pivots`) is a near miss the query's refinement moves onto the
request (the far-field test is first order: the exact rests are longer, up to ~2×).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from synth.parallel_rows import one_signature, over_rows

__all__ = ["DIRECTIONS", "harmonic_rest", "slot_pivots", "support_points"]

#: Slot directions tried per path, evenly over the turn (5° apart).
DIRECTIONS = 72
#: The reaches tried about W/S, and the rescalings toward the requested swing after the
#: nearest of them (each ~10× closer to it).
REACH_LADDER = np.geomspace(0.25, 4.0, 17)
SWING_STEPS = 3


def harmonic_rest(band: float, swing: float) -> float:
    """The rest (crank rad) of a harmonic output ψ = (S/2)·cos φ of swing S within a band β at
    its extreme: (S/2)(1 − cos φ) ≤ β, so 2·arccos(1 − 2β/S) (all angles in radians); 2π when
    the band holds the whole swing."""
    return 2 * math.acos(max(-1.0, 1 - 2 * band / swing))


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _support_points(x, y, cos_k, sin_k, ratio, shortest, longest, span, support):
    R, N = x.shape
    K = cos_k.shape[0]
    proj = np.empty(N)
    for r in range(R):
        for k in range(K):
            c, s = cos_k[k], sin_k[k]
            top = -np.inf
            bottom = np.inf
            i_top = 0
            i_bottom = 0
            for i in range(N):
                p = x[r, i] * c + y[r, i] * s
                proj[i] = p
                if p > top:
                    top, i_top = p, i
                if p < bottom:
                    bottom, i_bottom = p, i
            tol = ratio * (top - bottom)
            support[r, k] = -1
            if not tol > 0:
                continue
            # the run of samples about the support point within tol of its line
            run = 1
            while run <= longest and top - proj[(i_top + run) % N] <= tol:
                run += 1
            back = 1
            while run + back - 1 <= longest and top - proj[(i_top - back) % N] <= tol:
                back += 1
            run += back - 1
            if run < shortest or run > longest:
                continue
            other = 1
            while other <= longest and proj[(i_bottom + other) % N] - bottom <= tol:
                other += 1
            back = 1
            while other + back - 1 <= longest and proj[(i_bottom - back) % N] - bottom <= tol:
                back += 1
            if other + back - 1 > longest:
                continue
            # no stretch of span samples anywhere spreads within tol (a rest longer than asked)
            slow = False
            for i in range(N):
                hi = proj[i]
                lo = proj[i]
                for j in range(1, span):
                    p = proj[(i + j) % N]
                    hi = max(hi, p)
                    lo = min(lo, p)
                if hi - lo <= tol:
                    slow = True
                    break
            if not slow:
                support[r, k] = i_top


def support_points(
    paths: np.ndarray, *, dwell: float, dwell_tol: float, swing: float, band: float, directions: int = DIRECTIONS
) -> np.ndarray:
    """``(R, directions)`` int64: per path and slot normal n_k = e^{2πik/directions}, the
    index of the support point in direction n_k (the sample of largest P·n_k) where the
    far-field test of the module docstring passes, −1 where it does not.

    ``paths`` is ``(R, N)`` complex, each row a coupler path on an even crank grid of N
    samples over the turn; ``dwell``, ``dwell_tol``, ``swing`` and ``band`` in radians (the
    dwell in crank angle, the others in output angle)."""
    paths = np.ascontiguousarray(paths, dtype=np.complex128)
    R, N = paths.shape
    step = 2 * math.pi / N
    shortest = max(2, int(math.floor((dwell - dwell_tol) / step)) + 1)  # samples of a run
    longest = int(math.ceil((dwell + dwell_tol) / step)) + 1
    x, y = np.ascontiguousarray(paths.real), np.ascontiguousarray(paths.imag)
    angle = np.arange(directions) * (2 * math.pi / directions)
    cos_k, sin_k = np.cos(angle), np.sin(angle)
    support = np.empty((R, directions), np.int64)
    args = (x, y, cos_k, sin_k, band / swing, shortest, longest, longest + 1, support)
    one_signature(_support_points, args)
    over_rows(
        R,
        lambda lo, hi: _support_points(
            x[lo:hi], y[lo:hi], cos_k, sin_k, band / swing, shortest, longest, longest + 1, support[lo:hi]
        ),
        2.0 * R * directions * N,
    )  # ~2 ns a sample and direction
    return support


def slot_pivots(
    paths: np.ndarray, direction: np.ndarray, support: np.ndarray, *, swing: float, directions: int = DIRECTIONS
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(hits, pivots, swings): for each passing (path, direction) — ``paths`` ``(H, N)`` the paths,
    ``direction`` the slot normal's index k and ``support`` the support point's sample
    (:func:`support_points`) — the two slot pivots on the support tangent, one each way, at
    the reach that swings the output by ``swing`` on the path's samples (from R = W/``swing``,
    W the path's width across the slot: the nearest of a ladder of reaches, as the swing is ≈
    W/R only far from the curve, then rescaled by the swing it gives); ``hits`` the index
    (into ``paths``) of each pivot, ``swings`` its slot's swing on the samples (rad: near the
    curve it can stay far from ``swing``)."""
    hits = np.arange(len(paths))
    if not hits.size:
        return hits, np.empty(0, np.complex128), np.empty(0)
    n = np.exp(1j * direction * (2 * math.pi / directions))
    proj = (paths * np.conj(n)[:, None]).real
    reach = (proj.max(axis=1) - proj.min(axis=1)) / swing
    p0 = paths[hits, support]
    rows = np.concatenate([hits, hits])
    p0 = np.concatenate([p0, p0])
    tangent = np.concatenate([-1j * n, 1j * n])
    reach = np.concatenate([reach, reach])
    each_way = paths[rows]
    # near the curve the swing is not ≈ W/R: the nearest of a ladder of reaches first
    ladder = reach[:, None] * REACH_LADDER[None, :]
    swung = np.stack([_swing(each_way, p0 + r * tangent) for r in ladder.T], axis=1)
    reach = ladder[np.arange(len(rows)), np.argmin(np.abs(swung - swing), axis=1)]
    for _ in range(SWING_STEPS):
        swung = _swing(each_way, p0 + reach * tangent)
        reach = reach * np.where(swung > 0, swung / swing, 1.0)
    pivots = p0 + reach * tangent
    return rows, pivots, _swing(each_way, pivots)


def _swing(paths: np.ndarray, pivots: np.ndarray) -> np.ndarray:
    """The swing (rad) of the slot through each of ``pivots`` over its path's samples."""
    psi = np.unwrap(np.angle(paths - pivots[:, None]), axis=1)
    return psi.max(axis=1) - psi.min(axis=1)
