"""The dwell's ends refined on a six-bar's exact path, compiled: what
:func:`synth.output_range.dwell_intervals` does after its grid search, one pass per (row,
dwell) with ψ evaluated pointwise inside the pass.

The numpy form of the refinement builds ``(rows, dwells, windows, points)`` arrays at every
stage and calls the exact ψ a dozen times per batch; at the query's batch sizes (a hundred
six-bars) its per-call overhead cost more than the ψ evaluations themselves. Here each
candidate window's (start, end) pair search, the two finer searches of the best pair and the
final push of both ends run in one loop per row and dwell, with ψ(φ) = atan2 of the output's
direction (:func:`synth.sixbar_kernel.output_phasor`) taken on the 2π branch of a reference,
as :func:`synth.output_range._rewrap` takes it. The stages, their points and the order of their
operations are those of :mod:`synth.output_range` (see ``dwell_intervals``' Notes); two
things differ: ψ at a point is atan2 of that point's direction (the batch evaluator sums the
steps between the points of one call, which rounds differently in the last bits), and a
point of the first stage's lattice that two candidate windows share is evaluated once.
``tests/synth/test_dwell_ends_kernel.py`` holds the two forms to the same dwells.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from synth.pair_search import pair_query
from synth.parallel_rows import over_rows
from synth.sample_ranges import range_max_min
from synth.sixbar_kernel import output_phasor
from synth.types import F64

__all__ = ["refine_windows"]

_TWO_PI = 2.0 * math.pi
#: Slots of the per-(row, dwell) memo of the first stage's lattice points (power of two; a
#: dwell's candidate windows evaluate at most CANDIDATES × 3·DWELL_FINE of them).
_MEMO = 1024
_EMPTY = -(1 << 62)


@numba.njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _psi(params, rpr, i, phi, pin_eps, ref):
    """Exact ψ of six-bar ``i`` at crank angle ``phi`` on the 2π branch nearest ``ref``
    (``ref + wrap_angle(ψ − ref)``, :func:`synth.output_range._rewrap`)."""
    ex, ey, _ = output_phasor(params, rpr, i, phi, pin_eps)
    return ref + (((math.atan2(ey, ex) - ref) + math.pi) % _TWO_PI - math.pi)


@numba.njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _fine_path(params, rpr, i, pin_eps, E, r, m, net, first, steps, K, phi0, h, at, vals, keys, memo):
    """:func:`synth.output_range._fine_path` for one window: ψ at K points per grid step over
    ``steps`` steps from sample ``first`` into ``at`` and ``vals`` (``steps·K + 1`` points;
    the samples keep their values, the points between are exact, each looked up in the memo
    ``keys``/``memo`` by its place on the lattice of K points per step first)."""
    T = E.shape[1]
    for j in range(steps * K + 1):
        t = j / K
        at[j] = phi0 + (first + t) * h
        k = min(math.floor(t), steps - 1)
        w = t - k
        a, b = first + k, first + k + 1
        ya = E[r, min(a, T - 1)] if a >= 0 else E[r, a % m] - net
        yb = E[r, min(b, T - 1)] if b >= 0 else E[r, b % m] - net
        ref = (1 - w) * ya + w * yb
        if j % K == 0:
            vals[j] = ref
            continue
        key = first * K + j
        slot = (key * 40503) & (_MEMO - 1)
        while keys[slot] != _EMPTY and keys[slot] != key:
            slot = (slot + 1) & (_MEMO - 1)
        if keys[slot] != key:
            keys[slot] = key
            memo[slot] = _psi(params, rpr, i, at[j], pin_eps, ref)
        vals[j] = memo[slot]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _refine(params, rpr, six, E, upper, lower, band, phi0, h, cs, ok, nn, pin_eps, K, extend_points, out):
    R, C, W = cs.shape
    T = E.shape[1]
    m = T // 2
    nl, nr = K + 1, 2 * K + 1
    left_at, lv, right_at, rv = np.empty(nl), np.empty(nl), np.empty(nr), np.empty(nr)
    scratch, last_of = np.empty((7, nr)), np.empty(nr, np.int64)
    keys, memo = np.empty(_MEMO, np.int64), np.empty(_MEMO)
    t_pair = np.empty(K + 1)  # np.linspace(-1, 1, K + 1)
    for j in range(K + 1):
        t_pair[j] = -1.0 + j * (2.0 / K)
    t_pair[K] = 1.0
    for r in range(R):
        i = six[r]
        net = E[r, m] - E[r, 0]
        b = band[r]
        for c in range(C):
            keys[:] = _EMPTY
            n = nn[r, c]
            best, start, end, low, high = -np.inf, 0.0, 0.0, 0.0, 0.0
            # each candidate grid window: start in [φ_{s−1}, φ_s], end in [φ_{e₀}, φ_{e₀+2}]
            for w in range(W):
                if not ok[r, c, w]:
                    continue
                s = cs[r, c, w]
                e0 = s + max(n - 2, 0)
                n_in = e0 - s - 1
                hi_in, lo_in = -np.inf, np.inf
                if n_in >= 1:
                    hi_in, lo_in = range_max_min(upper, lower, r, s + 1, n_in)
                _fine_path(params, rpr, i, pin_eps, E, r, m, net, s - 1, 1, K, phi0, h, left_at, lv, keys, memo)
                _fine_path(params, rpr, i, pin_eps, E, r, m, net, e0, 2, K, phi0, h, right_at, rv, keys, memo)
                _, _, s1, e1, l1, h1, _, _, reach = pair_query(left_at, lv, right_at, rv, hi_in, lo_in, b,
                                                               scratch, last_of)
                if reach - s1 > best:
                    best, start, end, low, high = reach - s1, s1, e1, l1, h1
            # the best pair again at 2/K of its spacing, twice (re-centred)
            step = h / K
            for _ in range(2):
                a_off = int(math.floor((start + step - phi0) / h)) + 1
                b_off = int(math.ceil((end - step - phi0) / h)) - 1
                a_off = min(max(a_off, 0), T - 1)
                count = min(b_off, T - 1) - a_off + 1
                inner_hi, inner_lo = -np.inf, np.inf
                if count >= 1:
                    inner_hi, inner_lo = range_max_min(upper, lower, r, a_off, count)
                level = 0.5 * (low + high)
                for j in range(K + 1):
                    left_at[j] = start + step * t_pair[j]
                    right_at[j] = end + step * t_pair[j]
                    lv[j] = _psi(params, rpr, i, left_at[j], pin_eps, level)
                    rv[j] = _psi(params, rpr, i, right_at[j], pin_eps, level)
                _, _, s2, e2, l2, h2, _, _, _ = pair_query(left_at, lv, right_at[: K + 1], rv[: K + 1],
                                                           inner_hi, inner_lo, b, scratch, last_of)
                if e2 - s2 > end - start:
                    start, end, low, high = s2, e2, l2, h2
            # each end pushed outwards while the band holds: the start, then the end
            for side in (-1, 1):
                spacing = 2 * step / K
                for _ in range(2):
                    edge = origin = start if side < 0 else end
                    ref = 0.5 * (low + high)
                    cmax, cmin = high, low
                    for j in range(extend_points):
                        at = origin + (side * spacing) * ((j + 1) / extend_points)
                        v = _psi(params, rpr, i, at, pin_eps, ref)
                        cmax, cmin = max(cmax, v), min(cmin, v)
                        if cmax - cmin > b:
                            break
                        edge, high, low = at, cmax, cmin
                    if side < 0:
                        start = edge
                    else:
                        end = edge
                    spacing = spacing / extend_points
            out[r, c, 0], out[r, c, 1], out[r, c, 2], out[r, c, 3] = start, end, low, high


def refine_windows(params: F64, rpr: np.ndarray, six: np.ndarray, E: F64, upper: F64, lower: F64, band: F64,
                   phi0: float, h: float, cs: np.ndarray, ok: np.ndarray, nn: np.ndarray, pin_eps: float,
                   fine: int, extend_points: int) -> tuple[F64, F64, F64, F64]:
    """The refinement of :func:`synth.output_range.dwell_intervals` after its grid search, for
    rows whose exact ψ is six-bar ``six[r]``'s (``params``, ``rpr``: the kernel's rows,
    :func:`synth.sixbar._kernel_inputs`): ``E`` ``(R, 2M)`` the samples over two turns,
    ``upper``/``lower`` their vertex bounds, ``band`` ``(R,)``, the grid (φ₀, h), the candidate
    windows' starts ``cs`` and flags ``ok`` ``(R, C, W)``, the grid dwell's sample count ``nn``
    ``(R, C)``, ``fine`` points per grid step (``DWELL_FINE``) and ``extend_points``. Returns
    (start, end, low, high), each ``(R, C)``."""
    R, C = nn.shape
    out = np.empty((R, C, 4))
    args = [np.ascontiguousarray(x) for x in (E, upper, lower)]
    cs, ok, nn = np.ascontiguousarray(cs, np.int64), np.ascontiguousarray(ok, np.bool_), np.ascontiguousarray(nn, np.int64)
    six = np.ascontiguousarray(six, np.int64)
    band = np.ascontiguousarray(band, float)

    def block(lo: int, hi: int) -> None:
        _refine(params, rpr, six[lo:hi], args[0][lo:hi], args[1][lo:hi], args[2][lo:hi], band[lo:hi], phi0, h,
                cs[lo:hi], ok[lo:hi], nn[lo:hi], pin_eps, fine, extend_points, out[lo:hi])

    # ~500 exact points a dwell at ~80 ns each
    over_rows(R, block, 40_000 * R * C)
    return out[..., 0], out[..., 1], out[..., 2], out[..., 3]
