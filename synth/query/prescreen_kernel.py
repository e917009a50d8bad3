"""The prescreen of fitted and moved output dyads compiled: :func:`synth.query.fitting._output_screen`'s
output angle and :func:`synth.query.candidates.output_may_meet`'s tests, one pass per dyad.

A sparse answer screens every fitted dyad's pivot moved in a few dozen places
(:func:`synth.query.reseat`): tens of thousands of dyads on the fit's crank grid per request.
The numpy form made ~25 passes over (dyads × samples) — the RRR loop's circle intersection,
the angles, their running sum, the rolled second differences and the window filters — at
~90 ns a sample. Here each dyad's output angle is built sample by sample (RRR: the rocker's
moving pivot Q from :func:`synth.mechanism.sixbar_kernel.closing_point`, the operations of
:func:`kinematics.loop.circle_intersection_xy`) and a dyad stops as soon as it cannot meet
the request: its loop does not close at a sample, or its output has already swung further
than the request allows. The window tests are two monotone queues over the cyclic samples
(every window of the given length, as the ``wrap`` filters of
:func:`synth.query.candidates.within_band` read them).

The same tests on the same samples; the angle is a scalar ``atan2`` where numpy's vectorised
``arctan2`` may round the last bit otherwise, so a dyad exactly at a threshold may be decided
the other way (``tests/synth/test_prescreen_kernel.py``: the same decisions wherever the
margin exceeds 1e-9).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from kinematics.status import Status
from synth.mechanism.sixbar_kernel import closing_point
from synth.parallel_rows import over_rows

__all__ = ["screen_outputs"]

_NA = int(Status.NOT_ASSEMBLABLE)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _within_band(psi, m, length, band, top, bottom):
    """Some cyclic window of ``length`` consecutive samples of ``psi[:m]`` lies within ``band``
    (max − min ≤ band); a window longer than the turn holds every sample."""
    if length >= m:
        hi, lo = psi[0], psi[0]
        for j in range(1, m):
            hi, lo = max(hi, psi[j]), min(lo, psi[j])
        return hi - lo <= band
    t0 = t1 = b0 = b1 = 0
    for k in range(m + length - 1):  # windows starting at 0 .. m − 1, cyclic
        j = k % m
        x = psi[j]
        while t1 > t0 and psi[top[t1 - 1] % m] <= x:
            t1 -= 1
        top[t1] = k
        t1 += 1
        while b1 > b0 and psi[bottom[b1 - 1] % m] >= x:
            b1 -= 1
        bottom[b1] = k
        b1 += 1
        start = k - length + 1
        if start >= 0:
            while top[t0] < start:
                t0 += 1
            while bottom[b0] < start:
                b0 += 1
            if psi[top[t0] % m] - psi[bottom[b0] % m] <= band:
                return True
    return False


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _screen(P, D, rest, rod, rocker, branch, rrr, has_swing, swing, swing_tol, band, shortest, longest, ok):
    n, m = P.shape
    psi = np.empty(m)
    top, bottom = np.empty(2 * m, np.int64), np.empty(2 * m, np.int64)
    widest = swing + swing_tol
    for i in range(n):
        ok[i] = False
        dx, dy = D[i].real, D[i].imag
        rx, ry = rest[i].real - dx, rest[i].imag - dy  # the angle is measured from rest − D
        base = acc = 0.0
        qx = qy = 0.0  # the previous sample's w·conj(rest − D)
        hi, lo = -np.inf, np.inf
        failed = False
        for j in range(m):
            x, y = P[i, j].real, P[i, j].imag
            if rrr:  # Q = P + ρ·e1, e1 from the loop of circles about P (ρ) and D (L)
                c1, s1, _, _, st, _, _ = closing_point(dx - x, dy - y, rod[i], rocker[i], branch[i])
                if st & _NA:
                    failed = True
                    break
                x, y = x + rod[i] * c1, y + rod[i] * s1
            wx, wy = x - dx, y - dy
            ax, ay = wx * rx + wy * ry, wy * rx - wx * ry  # w·conj(rest − D)
            if j == 0:
                base = math.atan2(ay, ax)
                psi[0] = base
            else:  # unwrapped: the sum of the turns between samples
                acc += math.atan2(ay * qx - ax * qy, ax * qx + ay * qy)
                psi[j] = base + acc
            qx, qy = ax, ay
            hi, lo = max(hi, psi[j]), min(lo, psi[j])
            if has_swing and hi - lo > widest:  # swung further than the request allows
                failed = True
                break
        if failed:
            continue
        stray = 0.0  # the largest |Δ²ψ|/8 over the cyclic samples
        for j in range(m):
            stray = max(stray, abs(psi[(j + 1) % m] - 2 * psi[j] + psi[(j - 1) % m]))
        stray = stray / 8
        if has_swing and hi - lo + 2 * stray < swing - swing_tol:
            continue
        if shortest >= 2 and not _within_band(psi, m, shortest, band, top, bottom):
            continue
        if longest < m and _within_band(psi, m, longest, band - 2 * stray, top, bottom):
            continue
        ok[i] = True


def screen_outputs(
    P: np.ndarray,
    D: np.ndarray,
    rest: np.ndarray,
    rrr: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
    swing: float | None,
    swing_tol: float,
    band: float,
    shortest: int,
    longest: int,
) -> np.ndarray:
    """Which dyads may meet a request: coupler points ``P`` ``(n, M)`` on a uniform full-turn
    grid, output pivots ``D`` and references ``rest`` ``(n,)``, ``rrr`` = (rod, rocker, branch)
    ``(n,)`` for RRR dyads (None: slots); the request's swing (rad, None: any) and tolerance,
    its band, and the run lengths :func:`synth.query.candidates.output_may_meet` derives from its
    dwell (``shortest`` samples must fit in the band somewhere; ``longest`` must not, in the
    band narrowed by twice the stray)."""
    P = np.ascontiguousarray(P, np.complex128)
    n = P.shape[0]
    D, rest = (np.ascontiguousarray(np.reshape(x, n), np.complex128) for x in (D, rest))
    if rrr is None:
        rod = rocker = branch = np.zeros(n)
    else:
        rod, rocker, branch = (np.ascontiguousarray(np.reshape(x, n), float) for x in rrr)
    ok = np.empty(n, bool)
    has_swing = swing is not None
    s = 0.0 if swing is None else float(swing)

    def block(lo: int, hi: int) -> None:
        _screen(
            P[lo:hi],
            D[lo:hi],
            rest[lo:hi],
            rod[lo:hi],
            rocker[lo:hi],
            branch[lo:hi],
            rrr is not None,
            has_swing,
            s,
            float(swing_tol),
            float(band),
            int(shortest),
            int(longest),
            ok[lo:hi],
        )

    over_rows(n, block, 40 * P.size)  # ~40 ns a sample (RRR), less where a dyad stops early
    return ok
