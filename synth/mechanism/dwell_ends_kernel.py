"""The ends of a six-bar's dwells and of its deviation windows refined on its exact path,
compiled: what :func:`synth.mechanism.output_range.dwell_intervals` and
:func:`synth.mechanism.output_range.output_deviation` do after their grid searches, one pass per row
(and dwell) with ψ evaluated pointwise inside the pass.

The numpy form of the refinement builds ``(rows, dwells, windows, points)`` arrays at every
stage and calls the exact ψ a dozen times per batch; at the query's batch sizes (a hundred
six-bars) its per-call overhead cost more than the ψ evaluations themselves. Here each
candidate window's (start, end) pair search, the two finer searches of the best pair and the
final push of both ends run in one loop per row and dwell, with ψ(φ) = atan2 of the output's
direction (:func:`synth.mechanism.sixbar_kernel.output_phasor`) taken on the 2π branch of a reference,
as :func:`synth.mechanism.output_range._rewrap` takes it. The stages, their points and the order of
their operations are those of :mod:`synth.mechanism.output_range` (see ``dwell_intervals``' Notes and
``_refine_window``); two things differ: ψ at a point is atan2 of that point's direction (the
batch evaluator sums the steps between the points of one call, which rounds differently in
the last bits), and a point of the first stage's lattice that two candidate windows share is
evaluated once.
``tests/synth/test_dwell_ends_kernel.py`` holds the two forms to the same dwells.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from synth.mechanism.pair_search import pair_query
from synth.mechanism.sample_ranges import range_max_min
from synth.mechanism.sixbar_kernel import output_phasor
from synth.parallel_rows import one_signature, over_rows
from synth.types import F64

__all__ = ["refine_deviation_windows", "refine_windows"]

_TWO_PI = 2.0 * math.pi
#: Slots of the per-(row, dwell) memo of the first stage's lattice points (power of two; a
#: dwell's candidate windows evaluate at most CANDIDATES × 3·DWELL_FINE of them).
_MEMO = 1024
_EMPTY = -(1 << 62)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _psi(params, rpr, i, phi, pin_eps, ref):
    """Exact ψ of six-bar ``i`` at crank angle ``phi`` on the 2π branch nearest ``ref``
    (``ref + wrap_angle(ψ − ref)``, :func:`synth.mechanism.output_range._rewrap`)."""
    ex, ey, _ = output_phasor(params, rpr, i, phi, pin_eps)
    return ref + (((math.atan2(ey, ex) - ref) + math.pi) % _TWO_PI - math.pi)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _fine_path(params, rpr, i, pin_eps, E, r, m, net, first, steps, K, phi0, h, at, vals, keys, memo):
    """:func:`synth.mechanism.output_range._fine_path` for one window: ψ at K points per grid step over
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
                _, _, s1, e1, l1, h1, _, _, reach = pair_query(
                    left_at, lv, right_at, rv, hi_in, lo_in, b, scratch, last_of
                )
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
                _, _, s2, e2, l2, h2, _, _, _ = pair_query(
                    left_at, lv, right_at[: K + 1], rv[: K + 1], inner_hi, inner_lo, b, scratch, last_of
                )
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


def refine_windows(
    params: F64,
    rpr: np.ndarray,
    six: np.ndarray,
    E: F64,
    upper: F64,
    lower: F64,
    band: F64,
    phi0: float,
    h: float,
    cs: np.ndarray,
    ok: np.ndarray,
    nn: np.ndarray,
    pin_eps: float,
    fine: int,
    extend_points: int,
) -> tuple[F64, F64, F64, F64]:
    """The refinement of :func:`synth.mechanism.output_range.dwell_intervals` after its grid search, for
    rows whose exact ψ is six-bar ``six[r]``'s (``params``, ``rpr``: the kernel's rows,
    :func:`synth.mechanism.sixbar.kernel_inputs`): ``E`` ``(R, 2M)`` the samples over two turns,
    ``upper``/``lower`` their vertex bounds, ``band`` ``(R,)``, the grid (φ₀, h), the candidate
    windows' starts ``cs`` and flags ``ok`` ``(R, C, W)``, the grid dwell's sample count ``nn``
    ``(R, C)``, ``fine`` points per grid step (``DWELL_FINE``) and ``extend_points``. Returns
    (start, end, low, high), each ``(R, C)``."""
    R, C = nn.shape
    if cs.shape[-1] * (3 * fine + 1) > _MEMO // 2:  # the memo's open addressing needs room to spare
        raise ValueError(f"{cs.shape[-1]} windows of {fine} points a step overflow the memo of {_MEMO} points")
    out = np.empty((R, C, 4))
    args = [np.ascontiguousarray(x) for x in (E, upper, lower)]
    cs, ok, nn = (
        np.ascontiguousarray(cs, np.int64),
        np.ascontiguousarray(ok, np.bool_),
        np.ascontiguousarray(nn, np.int64),
    )
    six = np.ascontiguousarray(six, np.int64)
    band = np.ascontiguousarray(band, float)
    # band arrives writable or read-only (a broadcast): one compile for both
    whole = (params, rpr, six, *args, band, phi0, h, cs, ok, nn, pin_eps, fine, extend_points, out)
    one_signature(_refine, whole, read_only=(6,))

    def block(lo: int, hi: int) -> None:
        _refine(
            params,
            rpr,
            six[lo:hi],
            args[0][lo:hi],
            args[1][lo:hi],
            args[2][lo:hi],
            band[lo:hi],
            phi0,
            h,
            cs[lo:hi],
            ok[lo:hi],
            nn[lo:hi],
            pin_eps,
            fine,
            extend_points,
            out[lo:hi],
        )

    # ~500 exact points a dwell at ~80 ns each
    over_rows(R, block, 40_000 * R * C)
    return out[..., 0], out[..., 1], out[..., 2], out[..., 3]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _slab_ref(slab, r, i_lo, x, phi0, h):
    """ψ linear between the slab's samples at crank angle x (slab offset 0 is sample
    i_lo − 1): the 2π branch to evaluate on."""
    idx = (x - phi0) / h - (i_lo - 1)
    j = min(max(math.floor(idx), 0), slab.shape[1] - 2)
    w = idx - j
    return (1 - w) * slab[r, j] + w * slab[r, j + 1]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _best_split(
    params, rpr, i, pin_eps, slab, r, i_lo, f, L, c, phi0, h, mid_hi, mid_lo, fv, gv, sf_max, sf_min, pg_max, pg_min
):
    """ψ at the window starts ``f`` and ends f + L, the suffix extremes of the starts' values
    and prefix extremes of the ends', and the allowed start (within [c − L, c]) whose window
    has the least range with ``mid_hi``/``mid_lo`` between them: (index, range), (−1, inf) if
    none is allowed."""
    n = f.shape[0]
    for j in range(n):
        g = f[j] + L
        fv[j] = _psi(params, rpr, i, f[j], pin_eps, _slab_ref(slab, r, i_lo, f[j], phi0, h))
        gv[j] = _psi(params, rpr, i, g, pin_eps, _slab_ref(slab, r, i_lo, g, phi0, h))
    sf_max[n - 1], sf_min[n - 1] = fv[n - 1], fv[n - 1]
    for j in range(n - 2, -1, -1):
        sf_max[j], sf_min[j] = max(fv[j], sf_max[j + 1]), min(fv[j], sf_min[j + 1])
    pg_max[0], pg_min[0] = gv[0], gv[0]
    for j in range(1, n):
        pg_max[j], pg_min[j] = max(pg_max[j - 1], gv[j]), min(pg_min[j - 1], gv[j])
    best, best_range = -1, np.inf
    for j in range(n):
        if f[j] >= (c - L) - 1e-12 and f[j] <= c + 1e-12:
            top = max(max(sf_max[j], pg_max[j]), mid_hi)
            bot = min(min(sf_min[j], pg_min[j]), mid_lo)
            if top - bot < best_range:
                best, best_range = j, top - bot
    return best, best_range


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _windows(params, rpr, six, slab, i_lo, k, nL, L, c, dev, s_best, phi0, h, pin_eps, K2, fine, out_dev, out_start):
    R = slab.shape[0]
    n1, n3 = K2 + 1, fine + 1
    f, f3 = np.empty(n1), np.empty(n3)
    fv, gv, sf_max, sf_min, pg_max, pg_min = (
        np.empty(n1),
        np.empty(n1),
        np.empty(n1),
        np.empty(n1),
        np.empty(n1),
        np.empty(n1),
    )
    fv3, gv3, sf3_max, sf3_min, pg3_max, pg3_min = (
        np.empty(n3),
        np.empty(n3),
        np.empty(n3),
        np.empty(n3),
        np.empty(n3),
        np.empty(n3),
    )
    t3 = np.empty(n3)  # np.linspace(-1, 1, fine + 1)
    for j in range(n3):
        t3[j] = -1.0 + j * (2.0 / fine)
    t3[fine] = 1.0
    for r in range(R):
        i = six[r]
        out_dev[r], out_start[r] = dev[r], s_best[r]
        if nL[r] < 2:  # start and end regions overlap: the grid placement is kept
            continue
        # starts over the two steps around the best grid start, ends L later
        s_lo = phi0 + (i_lo[r] - 2 + k[r]) * h
        for j in range(n1):
            f[j] = s_lo + 2 * h * (j / K2)
        n_in = nL[r] - 2
        hi_in, lo_in = -np.inf, np.inf
        if n_in >= 1:
            hi_in, lo_in = range_max_min(slab, slab, r, k[r] + 2, n_in)
        j, fine_range = _best_split(
            params,
            rpr,
            i,
            pin_eps,
            slab,
            r,
            i_lo[r],
            f,
            L[r],
            c[r],
            phi0,
            h,
            hi_in,
            lo_in,
            fv,
            gv,
            sf_max,
            sf_min,
            pg_max,
            pg_min,
        )
        if j < 0:
            continue
        f_best = f[j]
        # again around the best fine start, ±one fine step on ``fine`` + 1 points
        d = 2 * h / K2
        for q in range(n3):
            f3[q] = f_best + d * t3[q]
        a_off = (f_best + d - phi0) / h - (i_lo[r] - 1)
        b_off = (f_best - d + L[r] - phi0) / h - (i_lo[r] - 1)
        i0 = math.floor(a_off) + 1
        cnt = math.ceil(b_off) - 1 - i0 + 1
        mid_hi, mid_lo = -np.inf, np.inf
        if cnt >= 1:
            mid_hi, mid_lo = range_max_min(slab, slab, r, i0, cnt)
        if j + 1 <= K2:
            mid_hi, mid_lo = max(mid_hi, sf_max[j + 1]), min(mid_lo, sf_min[j + 1])
        if j >= 1:
            mid_hi, mid_lo = max(mid_hi, pg_max[j - 1]), min(mid_lo, pg_min[j - 1])
        j3, fine3 = _best_split(
            params,
            rpr,
            i,
            pin_eps,
            slab,
            r,
            i_lo[r],
            f3,
            L[r],
            c[r],
            phi0,
            h,
            mid_hi,
            mid_lo,
            fv3,
            gv3,
            sf3_max,
            sf3_min,
            pg3_max,
            pg3_min,
        )
        if j3 >= 0 and fine3 < fine_range and nL[r] >= 4:
            out_dev[r], out_start[r] = fine3, f3[j3]
        else:
            out_dev[r], out_start[r] = fine_range, f_best


def refine_deviation_windows(
    params: F64,
    rpr: np.ndarray,
    six: np.ndarray,
    slab: F64,
    i_lo,
    k,
    nL,
    L,
    c,
    dev,
    s_best,
    phi0: float,
    h: float,
    pin_eps: float,
    steps: int,
    fine: int,
) -> tuple[F64, F64]:
    """The refinement of :func:`synth.mechanism.output_range.output_deviation`'s best grid window
    (``_refine_window``) for rows whose exact ψ is six-bar ``six[r]``'s: ``slab`` ``(R, W)``
    the samples from i_lo − 1 on, the best grid start at slab offset ``k``, ``nL`` samples per
    window, window length ``L`` and the angle ``c`` it must contain, the grid's ``dev`` and
    start ``s_best`` (kept where nothing refines), ``steps`` (K2) points over the first
    stage's two grid steps and ``fine`` + 1 points in the second. Returns (deviation, start),
    each ``(R,)``."""
    R = slab.shape[0]
    out_dev, out_start = np.empty(R), np.empty(R)
    ints = [np.ascontiguousarray(x, np.int64) for x in (six, i_lo, k, nL)]
    floats = [np.ascontiguousarray(x, float) for x in (slab, L, c, dev, s_best)]
    # L, c, dev and s_best arrive writable or read-only (broadcasts): one compile for both
    whole = (params, rpr, ints[0], floats[0], *ints[1:], *floats[1:], phi0, h, pin_eps, steps, fine, out_dev, out_start)
    one_signature(_windows, whole, read_only=(7, 8, 9, 10))

    def block(lo: int, hi: int) -> None:
        _windows(
            params,
            rpr,
            *(x[lo:hi] for x in ints[:1]),
            floats[0][lo:hi],
            *(x[lo:hi] for x in ints[1:]),
            *(x[lo:hi] for x in floats[1:]),
            phi0,
            h,
            pin_eps,
            steps,
            fine,
            out_dev[lo:hi],
            out_start[lo:hi],
        )

    # ~2·(steps + fine + 2) exact points a row at ~80 ns each
    over_rows(R, block, 160 * (steps + fine + 2) * R)
    return out_dev, out_start
