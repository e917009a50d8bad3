"""The clearances of :func:`synth.mechanism.buildability.clearances` compiled: every pair of
:data:`synth.mechanism.buildability.CLEARANCE_PAIRS` measured in one pass over each six-bar's samples,
instead of a ``(six-bars, samples)`` array (and its temporaries) per pair.

The same distances as the numpy expressions it replaced — a point's distance to a segment
through the clipped projection — compared squared, one square root per pair at the end
(the root is monotone: the same minimum); numpy's ``abs`` and complex products run on other
instructions (SIMD ``hypot``, fused multiply-adds), so the distances can differ in their
last bits, and a pair that ties another to rounding may be named instead of it
(``tests/synth/test_buildability.py`` holds the two to 1e-12).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from synth.parallel_rows import over_rows

__all__ = ["clearance_rows", "pair_clearances"]

#: Pairs (of CLEARANCE_PAIRS) an RRR has, and those an RPR has (its slot's two).
_RRR_PAIRS, _RPR_PAIRS = 14, 2


@numba.njit(cache=True)
def _squared(x, y):
    return x * x + y * y


@numba.njit(cache=True)
def _segment_distance2(px, py, ax, ay, bx, by):
    """Squared distance from p to the segment a–b."""
    abx, aby = bx - ax, by - ay
    length2 = _squared(abx, aby)
    t = ((px - ax) * abx - (py - ay) * (-aby)) / (length2 if length2 > 0 else 1.0)
    t = min(max(t, 0.0), 1.0)
    return _squared(px - (ax + t * abx), py - (ay + t * aby))


@numba.njit(cache=True, nogil=True)
def clearance_rows(A, B, P, Q, psi, d, pivot, rpr, every, reach, smallest):
    """:func:`pair_clearances` into ``reach`` and ``smallest``, for compiled callers too."""
    N, M = psi.shape
    for n in range(N):
        b0 = d[n]
        dx, dy = pivot[n].real, pivot[n].imag
        best = smallest[n]  # squared until the end
        best[:] = np.inf
        rmax = -np.inf
        for j in range(reach.shape[1]):
            k = j * every
            px, py = P[n, k].real, P[n, k].imag
            reach2 = _squared(px - dx, py - dy)
            reach[n, j] = math.sqrt(reach2)
            rmax = max(rmax, reach[n, j])
            ax, ay, bx, by = A[n, k].real, A[n, k].imag, B[n, k].real, B[n, k].imag
            # joints to the fixed pivots they are not pinned to
            best[0] = min(best[0], _squared(ax - b0, ay))
            best[1] = min(best[1], _squared(ax - dx, ay - dy))
            best[2] = min(best[2], _squared(bx, by))
            best[3] = min(best[3], _squared(bx - dx, by - dy))
            best[4] = min(best[4], _squared(px, py))
            best[5] = min(best[5], _squared(px - b0, py))
            if not rpr[n]:
                qx, qy = Q[n, k].real, Q[n, k].imag
                best[6] = min(best[6], reach2)
                best[7] = min(best[7], _squared(qx, qy))
                best[8] = min(best[8], _squared(qx - b0, qy))
                # the rod P–Q and the rocker D–Q to the pivots off them
                best[9] = min(best[9], _segment_distance2(0.0, 0.0, px, py, qx, qy))
                best[10] = min(best[10], _segment_distance2(b0, 0.0, px, py, qx, qy))
                best[11] = min(best[11], _segment_distance2(dx, dy, px, py, qx, qy))
                best[12] = min(best[12], _segment_distance2(0.0, 0.0, dx, dy, qx, qy))
                best[13] = min(best[13], _segment_distance2(b0, 0.0, dx, dy, qx, qy))
        if rpr[n]:  # the slot, from D to its far end along ψ, to A0 and B0
            for j in range(reach.shape[1]):
                k = j * every
                ex, ey = dx + rmax * math.cos(psi[n, k]), dy + rmax * math.sin(psi[n, k])
                best[14] = min(best[14], _segment_distance2(0.0, 0.0, dx, dy, ex, ey))
                best[15] = min(best[15], _segment_distance2(b0, 0.0, dx, dy, ex, ey))
        for p in range(16):
            best[p] = math.sqrt(best[p])


def pair_clearances(A, B, P, Q, psi, d, pivot, rpr, every: int):
    """Per six-bar the smallest distance of each pair of ``CLEARANCE_PAIRS`` over every
    ``every``-th sample (inf for the pairs its dyad kind does not have) and |P − D| at those
    samples: (smallest ``(N, 16)``, reach ``(N, ⌈M/every⌉)``). ``A, B, P, Q``: complex
    ``(N, M)`` (broadcast views are fine), ``psi`` ``(N, M)``, ``d`` the ground link and
    ``pivot`` D per six-bar, ``rpr`` which are RPR."""
    N, M = psi.shape
    reach = np.empty((N, len(range(0, M, every))))
    smallest = np.empty((N, 16))
    # d contiguous: a strided column would compile the kernel a second time (~1.2 s of CPU)
    d, pivot, rpr = np.ascontiguousarray(d, float), np.asarray(pivot, complex), np.asarray(rpr, np.bool_)

    def block(lo: int, hi: int) -> None:
        clearance_rows(
            A[lo:hi],
            B[lo:hi],
            P[lo:hi],
            Q[lo:hi],
            psi[lo:hi],
            d[lo:hi],
            pivot[lo:hi],
            rpr[lo:hi],
            int(every),
            reach[lo:hi],
            smallest[lo:hi],
        )

    over_rows(N, block, 25 * N * M)  # ~25 ns a sample
    return smallest, reach
