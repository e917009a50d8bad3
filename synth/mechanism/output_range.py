"""Windowed range of a sampled output angle ψ(φ) over one crank turn: the swing and net
output revolutions (:func:`output_swing`), the longest crank intervals on which ψ stays within
a band — the dwells (:func:`dwell_intervals`) — and the smallest peak-to-peak of ψ over a
window of a requested length around a dwell — the output deviation (:func:`output_deviation`).

Input: ψ sampled on a uniform full-turn crank grid, end excluded
(:func:`~synth.mechanism.sixbar.crank_grid`; :func:`grid_step` reads it back), unwrapped along the last
axis, vectorised over any leading shape; optionally the exact ψ(φ) as a callable (``psi_at``)
on which ends and extremes are refined beyond the grid, and ψ′ to pick the 2π branch of the
step that closes the turn. Nothing here knows the mechanism: :mod:`synth.mechanism.figures` passes the
exact simulation (:func:`~synth.mechanism.sixbar.simulate`). Angles in radians; a crank interval
[start, end] has start in [φ₀, φ₀ + 2π) and end = start + angle, so it may pass 2π.

On the grid, the longest window within the band from every start comes from one compiled pass
per row (:func:`synth.mechanism.band_windows.longest_windows`, O(M)), the extremes over other ranges of
samples from one compiled read of each range (:func:`synth.mechanism.sample_ranges.range_extremes`); the
refinement on the exact path is described in :func:`dwell_intervals` and :func:`output_deviation`
(checked against brute-force fine grids in ``tests/synth/test_sixbar.py`` and
``tests/synth/test_query_stage.py``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinematics.loop import parabola_vertex, wrap_angle
from synth.mechanism.sixbar import ExactOutput
from synth.types import F64

__all__ = [
    "Dwell",
    "DwellIntervals",
    "crank_degrees",
    "dwell_angle_bounds",
    "dwell_intervals",
    "grid_step",
    "least_bands",
    "output_deviation",
    "output_swing",
    "rests_separated",
    "wrap_angle",
]

#: ψ(φ) evaluator used to refine on the exact path: crank angles of shape ``(..., K)`` (the
#: leading shape of the ψ samples) → ψ of the same shape, on any 2π branch.
PsiAt = Callable[[F64], F64]


#: Crank-angle step (rad) that sets the subdivisions of one grid step in the first stage of the
#: deviation window's placement (at most DWELL_FINE of them; a second stage refines ×DWELL_FINE/2).
REFINE_STEP = math.radians(0.008)
#: Most subdivisions of one grid step in a refinement (bounds the work on coarse grids).
MAX_FINE = 128
#: Exact points per grid step in the dwell's (start, end) pair search.
DWELL_FINE = 16
#: Grid windows refined per dwell (those that may hold the longest exact interval).
CANDIDATES = 8
#: Points per round of the final push of each dwell end (two rounds).
EXTEND_POINTS = 8

_TWO_PI = 2.0 * math.pi

#: Two dwells are two rests, not one rest split in two, only if the crank turns at least this
#: much (rad) between them each way round the turn and the output leaves both rests' bands
#: between them (:func:`rests_separated`, the rule's one statement).
REST_GAP = math.radians(5.0)
#: How far (rad) the output must get outside the rests' bands between them when no swing
#: tolerance is given: the query's default ``--swing-tol``; a query passes its own.
REST_LEAVE = math.radians(0.5)


def rests_separated(gap: ArrayLike, leave: ArrayLike, tol: ArrayLike) -> NDArray[np.bool_]:
    """Whether two rests of one turn are two: the rule every double dwell is held to.

    Parameters
    ----------
    gap : (..., 2) float
        The crank's turn (rad) from the end of each rest to the start of the other (the two
        ways round the turn).
    leave : (..., 2) float
        Over each of those two crank intervals, how far (rad) the output gets outside the
        band of each rest, the smaller of the two: min over the rests b of
        max(max ψ − high_b, low_b − min ψ, 0), ψ over the interval.
    tol : float or (...,) float
        The swing tolerance (rad).

    Returns
    -------
    (...,) bool
        Both ways round, the crank turns at least ``REST_GAP`` (5°) and the output leaves
        both bands by at least ``tol``: the output moves between the rests, each way.
    """
    gap, leave = np.asarray(gap, float), np.asarray(leave, float)
    tol = np.asarray(tol, float)[..., None]
    return np.all((gap >= REST_GAP) & (leave >= tol), axis=-1)


def grid_step(phi: ArrayLike) -> tuple[float, float, int]:
    """(φ₀, h, M) of a uniform full-turn crank grid (see :func:`~synth.mechanism.sixbar.crank_grid`)."""
    phi = np.asarray(phi, dtype=float)
    if phi.ndim != 1 or phi.size < 8:
        raise ValueError("figures need a 1-D crank grid of at least 8 samples (see crank_grid)")
    m = phi.size
    h = _TWO_PI / m
    if not np.allclose(np.diff(phi), h, rtol=0, atol=1e-9 * h):
        raise ValueError("figures need a uniform grid over one full crank turn, end excluded (see crank_grid)")
    return float(phi[0]), h, m


def _closing_step(psi: F64, dpsi1: F64 | None, h: float) -> F64:
    """ψ(φ₀ + 2π) − ψ(φ_{M−1}): the step that closes the turn, on the nearest branch to the
    prediction (as :func:`~synth.mechanism.sixbar.simulate` unwraps ψ)."""
    pred = 0.0 if dpsi1 is None else 0.5 * (dpsi1[..., -1] + dpsi1[..., 0]) * h
    return pred + wrap_angle(psi[..., 0] - psi[..., -1] - pred)


def _net_change(psi: F64, dpsi1: F64 | None, h: float) -> F64:
    """ψ(φ₀ + 2π) − ψ(φ₀): 2π × the number of output revolutions per crank turn."""
    return psi[..., -1] + _closing_step(psi, dpsi1, h) - psi[..., 0]


def _rewrap(values, ref):
    """``values`` moved by multiples of 2π to the branch nearest to ``ref``."""
    return ref + wrap_angle(values - ref)


def output_swing(
    phi: ArrayLike, psi: ArrayLike, *, dpsi: tuple[F64, ...] | None = None, psi_at: PsiAt | None = None
) -> tuple[F64, NDArray[np.int64]]:
    """Swing max ψ − min ψ over the crank turn, and the net output revolutions per turn.

    Parameters
    ----------
    phi : (M,) float
        Uniform full-turn crank grid (:func:`~synth.mechanism.sixbar.crank_grid`), rad.
    psi : (..., M) float
        Output angle, unwrapped along the last axis (:attr:`~synth.mechanism.sixbar.SixBarMotion.psi`), rad.
    dpsi : (ψ′, ψ″), optional
        Closed-form derivatives: the extremes are then located by one Newton step on ψ′ = 0,
        otherwise by the parabola through the three samples around them.
    psi_at : callable, optional
        Exact ψ(φ) (shape ``(..., K)`` → ``(..., K)``); the extremes are then re-evaluated on the
        exact path at the located crank angle (the larger of sample and refined value is kept).

    Returns
    -------
    swing : (...,) float
        Rad, ≥ 0. Meaningless where the output revolves.
    turns : (...,) int
        Net revolutions of the output per crank turn; ≠ 0 means the output is not a rocker.
    """
    phi0, h, _ = grid_step(phi)
    psi = np.asarray(psi, dtype=float)
    d1 = None if dpsi is None else dpsi[0]
    net = _net_change(psi, d1, h)
    turns = np.rint(net / _TWO_PI).astype(np.int64)
    hi = _refined_extreme(psi, dpsi, psi_at, phi0, h, +1)
    lo = _refined_extreme(psi, dpsi, psi_at, phi0, h, -1)
    return hi - lo, turns


def _refined_extreme(psi, dpsi, psi_at, phi0, h, sign):
    """Max (sign +1) or min (sign −1) of ψ over the turn, refined between samples."""
    m = psi.shape[-1]
    k = np.argmax(sign * psi, axis=-1)[..., None]
    y0 = np.take_along_axis(psi, k, -1)[..., 0]
    if dpsi is not None and len(dpsi) >= 2:
        d1 = np.take_along_axis(dpsi[0], k, -1)[..., 0]
        d2 = np.take_along_axis(dpsi[1], k, -1)[..., 0]
        curved = sign * d2 < 0
        delta = np.where(curved, -d1 / np.where(curved, d2, 1.0), 0.0)
        taylor = y0 + np.where(curved, 0.5 * d1 * delta, 0.0)
    else:
        ym = np.take_along_axis(psi, (k - 1) % m, -1)[..., 0]
        yp = np.take_along_axis(psi, (k + 1) % m, -1)[..., 0]
        # cyclic neighbours of an end sample belong to the next turn: same branch only if net = 0
        ym, yp = _rewrap(ym, y0), _rewrap(yp, y0)
        vertex = parabola_vertex(ym, y0, yp)
        curved = sign * vertex.curvature < 0
        delta = np.where(curved, vertex.offset, 0.0) * h
        taylor = y0 + np.where(curved, vertex.rise, 0.0)
    delta = np.clip(delta, -h, h)
    if psi_at is None:
        value = taylor
    else:
        at = phi0 + k[..., 0] * h + delta
        exact = _rewrap(np.asarray(psi_at(at[..., None]), float)[..., 0], y0)
        value = exact
    return np.where(sign * value > sign * y0, value, y0)


class Dwell(NamedTuple):
    """One dwell: crank interval [start, end] (rad, start in [φ₀, φ₀ + 2π), end = start +
    angle, so it may pass 2π), its length ``angle`` (rad) and the output's ``rest`` angle, the
    middle of its band (rad, on the unwrapped ψ of the turn: two rests of one six-bar differ
    by the step between them)."""

    start: float
    end: float
    angle: float
    rest: float = 0.0

    def ends_deg(self) -> tuple[float, float]:
        """(start, end) in degrees, each in [0°, 360°): the interval as a user reads it. It runs
        counter-clockwise from start to end, so end < start when it passes 0°."""
        return crank_degrees(self.start), crank_degrees(self.end)

    def spans_deg(self) -> list[tuple[float, float]]:
        """The interval as one or two spans (low, high) in [0°, 360°], split where it passes
        360° (to shade it on a plot of one turn)."""
        s = crank_degrees(self.start)
        e = s + math.degrees(self.angle)
        return [(s, min(e, 360.0))] + ([(0.0, e - 360.0)] if e > 360.0 else [])


def crank_degrees(angle: float) -> float:
    """A crank angle (rad) in degrees in [0°, 360°) (``% 360`` alone gives 360.0 for a tiny
    negative angle)."""
    deg = math.degrees(angle) % 360.0
    return 0.0 if deg >= 360.0 else deg


@dataclass(frozen=True, slots=True)
class DwellIntervals:
    """Longest crank intervals on which ψ stays within a band, struct of arrays ``(..., count)``.

    Attributes
    ----------
    start, end, angle : float64
        Crank interval (rad; ``end = start + angle``, start in [φ₀, φ₀ + 2π)).
    low, high : float64
        min and max of ψ over the interval (rad, on the unwrapped branch of the input);
        high − low ≤ band.
    found : bool
        False for a second dwell that does not exist (the first covers the whole turn, or
        no rest is separated from the first by :func:`rests_separated`); its other fields
        are then 0.
    gap, leave : float64
        Two dwells found: from the end of each to the start of the other, the crank's turn
        (rad) and how far the output gets outside both bands (rad, on the grid samples in
        between; :func:`rests_separated`). 0 otherwise.
    """

    start: F64
    end: F64
    angle: F64
    low: F64
    high: F64
    found: NDArray[np.bool_]
    gap: F64
    leave: F64

    def dwells(self, index: tuple[int, ...] = ()) -> list[Dwell]:
        """The found dwells of one row (``index`` into the leading shape) as :class:`Dwell`."""
        out = []
        for j in range(self.start.shape[-1]):
            if self.found[index + (j,)]:
                k = index + (j,)
                out.append(
                    Dwell(
                        float(self.start[k]),
                        float(self.end[k]),
                        float(self.angle[k]),
                        0.5 * float(self.low[k] + self.high[k]),
                    )
                )
        return out


def _fine_count(h: float) -> int:
    """Subdivisions of one grid step for refinement to ``REFINE_STEP`` (at most ``MAX_FINE``:
    grids coarser than 2π/(MAX_FINE·REFINE_STEP), ~350 samples, are refined to h/MAX_FINE)."""
    return min(MAX_FINE, max(2, math.ceil(h / REFINE_STEP)))


def dwell_intervals(
    phi: ArrayLike,
    psi: ArrayLike,
    band: ArrayLike,
    *,
    count: int = 1,
    psi_at: PsiAt | None = None,
    dpsi1: ArrayLike | None = None,
    leave: float = REST_LEAVE,
) -> DwellIntervals:
    """Longest crank interval(s), cyclic over the turn, on which ψ stays within a band of
    total width ``band`` (max ψ − min ψ ≤ band).

    Parameters
    ----------
    phi : (M,) float
        Uniform full-turn crank grid (:func:`~synth.mechanism.sixbar.crank_grid`), rad.
    psi : (..., M) float
        Output angle unwrapped along the last axis, rad. A revolving output is continued into
        the next turn by its net change.
    band : float or (...,) float
        Total band width (rad, ≥ 0).
    count : {1, 2}
        1: the longest interval. 2: the longest interval and the longest one separated from
        it (a double-dwell mechanism), longest first: two rests with motion between them
        (:func:`rests_separated` with tolerance ``leave``). A second that is not separated
        from the first — a rest the band splits in two, or one the refinement on the exact
        path carries into the first — is not found.
    psi_at : callable, optional
        Exact ψ(φ) (shape ``(..., K)`` → ``(..., K)``, any 2π branch). With it both ends are
        refined on the exact path (see Notes) to well under 0.005° on the 0.5° grid; without
        it the ends are sample angles.
    dpsi1 : (..., M) float, optional
        ψ′, used only to pick the 2π branch of the turn-closing step (as in :func:`~synth.mechanism.sixbar.simulate`).
    leave : float
        Two dwells: how far (rad) the output must get outside both rests' bands between them,
        each way round (the swing tolerance; ``REST_LEAVE`` by default).

    Returns
    -------
    DwellIntervals
        Shape ``(..., count)``.

    Notes
    -----
    On the grid, the longest window from every start sample is found in one pass per row
    (:func:`synth.mechanism.band_windows.longest_windows`, two monotone queues, O(M)). The longest
    exact interval need not sit in the longest grid window: one of
    Λ ≥ (n − 1)·h holds at least n − 1 samples, so every start whose window holds ≥ n − 1
    samples is a candidate; the ``CANDIDATES`` of them whose band reaches furthest with ψ
    linear between samples are refined. For each, the start is searched in the step before
    its first sample and the end in the two steps from its (n − 2)-th, on ``DWELL_FINE``
    exact points per step, for the pair that maximises the length (ends ranked with ψ linear
    beyond the last point inside, so that the many near-equal pairs of a slowly drifting
    output are told apart); the best pair is searched again twice at 1/8 of that spacing,
    re-centred (the interval slides to where another constraint binds); then each end is
    pushed outwards while the band holds, in two rounds of ``EXTEND_POINTS`` points
    (h/8192, ~0.00006° on the 0.5° grid). The reported interval is conservative: every
    evaluated point in it is within the band. Inside, the samples stand for ψ, each local
    extreme raised to the vertex of the parabola through it and its neighbours (a peak between
    samples would otherwise let the ends overreach). Checked against a brute-force 0.001° grid
    in ``tests/synth/test_query_stage.py``.

    The second dwell is sought only among grid windows that can be separated from the first:
    each starts after, and ends before, a sample (ahead of and behind the first dwell) where ψ
    is more than ``leave`` outside the first's band, and ``REST_GAP`` of crank away from it.
    Once refined, the two are held to :func:`rests_separated` itself.
    """
    from synth.mechanism.band_windows import longest_windows  # numba: imported on first use

    if count not in (1, 2):
        raise ValueError(f"count must be 1 or 2, not {count!r}")
    phi0, h, m, lead, E, band_r = _two_turns(phi, psi, band, dpsi1)
    R = E.shape[0]
    # With the exact path at hand, each sample that is a local extreme stands for the vertex of
    # the parabola through it and its neighbours: a peak between samples (h²|ψ″|/8) inside a
    # dwell must not be missed once the ends are pushed to the band's edge.
    upper, lower = _vertex_bounds(E) if psi_at is not None else (E, E)
    length, w_max, w_min = longest_windows(upper, lower, band_r, m)

    rows = np.arange(R)
    s1 = np.argmax(length, axis=1)
    n1 = length[rows, s1]
    scores, starts, lens, found = [length], [s1], [n1], [np.ones(R, bool)]
    if count == 2:
        eff = _separable_windows(E, upper, lower, length, s1, n1, h, m, leave)
        s2 = np.argmax(eff, axis=1)
        n2 = eff[rows, s2]
        scores.append(eff)
        starts.append(s2)
        lens.append(n2)
        found.append(n2 > 0)
    s = np.stack(starts, axis=1)  # (R, C)
    n = np.maximum(np.stack(lens, axis=1), 1)
    fnd = np.stack(found, axis=1)
    hi_in, lo_in = _range_extremes(upper, lower, s, n)

    whole = n >= m
    start = phi0 + s * h
    end = start + (n - 1) * h
    low, high = lo_in, hi_in
    if psi_at is not None:
        # every grid window that may hold the longest exact interval, refined; the longest kept
        wanted = np.zeros((R, m), bool)
        for sc, nn in zip(scores, lens):
            wanted |= sc >= (nn - 1)[:, None]
        reach = _linear_reach(E, length, w_max, w_min, band_r, wanted & (length > 0))
        cand = np.stack([_near_longest(sc, nn, reach) for sc, nn in zip(scores, lens)], axis=1)  # (R, C, W)
        cs, ok = cand[..., 0, :], cand[..., 1, :].astype(bool)
        compiled = _compiled_rows(psi_at, R)
        if compiled is not None:  # the same stages in one compiled pass (synth.mechanism.dwell_ends_kernel)
            from synth.mechanism.dwell_ends_kernel import refine_windows  # numba: imported on first use

            start, end, low, high = refine_windows(
                psi_at.params,
                psi_at.rpr,
                compiled,
                E,
                upper,
                lower,
                band_r,
                phi0,
                h,
                cs,
                ok,
                n,
                psi_at.pin_eps,
                DWELL_FINE,
                EXTEND_POINTS,
            )
        else:
            start, end, low, high = _refine_candidates(E, cs, ok, n, band_r, phi0, h, psi_at, lead, upper, lower)
        start, end = np.where(whole, phi0 + s * h, start), np.where(whole, end, end)
        low, high = np.where(whole, lo_in, low), np.where(whole, hi_in, high)
    # A window covering the turn is the whole turn (no ends to refine).
    start = np.where(whole, phi0, start)
    end = np.where(whole, phi0 + _TWO_PI, end)
    angle = end - start
    if count == 2:
        # The grid windows are disjoint, but refinement may carry the second into the first:
        # then the output stays within one band across both — one rest that drifts, not two
        # (found by the query's refined near misses: two dwells reported as the same interval).
        into = np.mod(start[:, 1] - start[:, 0], _TWO_PI)
        fnd[:, 1] &= (into >= angle[:, 0]) & (into + angle[:, 1] <= _TWO_PI)
    start_n = phi0 + np.mod(start - phi0, _TWO_PI)
    end = start_n + angle
    gap = leave_by = np.zeros_like(start_n)
    if count == 2:
        gap, leave_by = _rest_gaps(E, phi0, h, m, start_n, angle, low, high)
        fnd[:, 1] &= rests_separated(gap, leave_by, leave)
        gap, leave_by = (np.where(fnd[:, 1:], x, 0.0) for x in (gap, leave_by))
    zero = lambda x: np.where(fnd, x, 0.0)
    shape = lead + (count,)
    return DwellIntervals(
        zero(start_n).reshape(shape),
        zero(end).reshape(shape),
        zero(angle).reshape(shape),
        zero(low).reshape(shape),
        zero(high).reshape(shape),
        fnd.reshape(shape),
        gap.reshape(shape),
        leave_by.reshape(shape),
    )


def _separable_windows(E, upper, lower, length, s1, n1, h, m, leave):
    """(R, M) lengths (samples) of the grid windows a second dwell may take from each start:
    the longest window within the band (``length``), cut to end ``REST_GAP`` before the first
    dwell and before the last sample ahead of it where ψ is beyond the first dwell's band
    widened by ``leave``; 0 unless it starts as far after the first dwell and after the first
    such sample. The first dwell is the grid window (s1, n1)."""
    hi1, lo1 = _range_extremes(upper, lower, s1[:, None], np.maximum(n1, 1)[:, None])
    psi = E[:, :m]  # ψ of a rocker is periodic: one turn's samples, read cyclically
    away = (psi > hi1 + leave) | (psi < lo1 - leave)
    i = np.arange(m)[None, :]
    e1 = s1 + n1 - 1
    ahead = np.mod(i - e1[:, None], m)  # samples from the first dwell's last one to i
    behind = np.mod(s1[:, None] - i, m)  # samples from i to the first dwell's first one
    first_away = np.where(away, ahead, m).min(axis=1)  # m: the output never leaves
    last_away = np.where(away, behind, m).min(axis=1)
    least = math.ceil(REST_GAP / h)
    open_ahead = np.maximum(first_away + 1, least)[:, None]
    open_behind = np.maximum(last_away + 1, least)[:, None]
    inside = np.mod(i - s1[:, None], m) < n1[:, None]
    room = behind - open_behind + 1  # samples the window from i may hold before the first dwell
    eff = np.where(inside | (ahead < open_ahead), 0, np.clip(np.minimum(length, room), 0, None))
    return np.where((n1 >= m)[:, None], 0, eff)


def _rest_gaps(E, phi0, h, m, start, angle, low, high):
    """For two dwells (R, 2) — crank intervals (start, angle), start in [φ₀, φ₀ + 2π), and
    bands [low, high] — from the end of each to the start of the other: the crank's turn
    (rad) and how far the output gets outside both bands there (rad, over the grid samples
    strictly inside; 0 with none)."""
    end = start + angle
    gap = np.mod(start[:, ::-1] - end, _TWO_PI)
    after = np.floor((end - phi0) / h).astype(np.int64) + 1  # first sample after the end
    before = np.ceil((end + gap - phi0) / h).astype(np.int64) - 1  # last before the other's start
    count = np.clip(before - after + 1, 0, m)
    # read on the two turns of E from the first turn's copy of ``after`` (ψ periodic)
    hi, lo = _range_extremes(E, E, np.mod(after, m), np.maximum(count, 1))
    beyond = [np.maximum(np.maximum(hi - high[:, b : b + 1], low[:, b : b + 1] - lo), 0.0) for b in range(2)]
    return gap, np.where(count >= 1, np.minimum(beyond[0], beyond[1]), 0.0)


def _refine_candidates(E, cs, ok, n, band, phi0, h, psi_at, lead, upper, lower):
    """The refinement on the exact path (see :func:`dwell_intervals`' Notes): every candidate
    window ``cs`` (``ok``: real ones) of each dwell, the best pair again twice, then both ends
    pushed out. Returns (start, end, low, high), each ``(R, C)``."""
    nn = np.broadcast_to(n[..., None], cs.shape)
    c_start, c_end, *c_rest, c_reach = _refine_dwell(E, cs, nn, band, phi0, h, psi_at, lead, upper, lower)
    best = np.argmax(np.where(ok, c_reach - c_start, -np.inf), axis=-1)[..., None]
    pick = lambda x: np.take_along_axis(x, best, -1)[..., 0]
    start, end, low, high = map(pick, (c_start, c_end, *c_rest[:2]))
    # the best pair again, at 2/DWELL_FINE of its spacing, twice (re-centred): the interval
    # may slide, one end gaining more than the other loses, to where another constraint binds
    step = h / DWELL_FINE
    for _ in range(2):
        inner_hi, inner_lo = _samples_between(upper, lower, start + step, end - step, phi0, h)
        start2, end2, low2, high2, _, _, _ = _refine_pair(
            start, end, 0.5 * (low + high), inner_hi, inner_lo, band, step, psi_at, lead
        )
        better = end2 - start2 > end - start
        start, end = np.where(better, start2, start), np.where(better, end2, end)
        low, high = np.where(better, low2, low), np.where(better, high2, high)
    return _extend_ends(start, end, low, high, band, 2 * step / DWELL_FINE, psi_at, lead)


def _compiled_rows(psi_at, R: int) -> NDArray[np.int64] | None:
    """For six-bars' exact ψ (:class:`synth.mechanism.sixbar.ExactOutput`, which the compiled refinement
    evaluates pointwise) whose batch the R rows repeat in order (each six-bar's rows
    together), the six-bar of each row; else None (the numpy stages call ``psi_at``)."""
    if not isinstance(psi_at, ExactOutput):
        return None
    N = psi_at.params.shape[0]
    if N == 0 or R % N:
        return None
    return np.arange(R, dtype=np.int64) // (R // N)


def _two_turns(phi, psi, band, dpsi1):
    """The inputs of :func:`dwell_intervals` checked and flattened to rows: (φ₀, h, M, the
    leading shape, ψ over two turns (R, 2M) — the second continued by the net change —, the
    band per row)."""
    phi0, h, m = grid_step(phi)
    psi = np.asarray(psi, dtype=float)
    lead = psi.shape[:-1]
    P = psi.reshape(-1, m)
    R = P.shape[0]
    band_r = np.broadcast_to(np.asarray(band, dtype=float), lead).reshape(R)
    if not np.all(np.isfinite(band_r)) or np.any(band_r < 0):
        raise ValueError("band must be finite and >= 0")
    d1 = None if dpsi1 is None else np.asarray(dpsi1, float).reshape(R, m)
    return phi0, h, m, lead, np.concatenate([P, P + _net_change(P, d1, h)[:, None]], axis=1), band_r


def dwell_angle_bounds(
    phi: ArrayLike, psi: ArrayLike, band: ArrayLike, *, dpsi1: ArrayLike | None = None
) -> tuple[F64, F64]:
    """Bounds (low, high) on the angle (rad) of the longest dwell :func:`dwell_intervals`
    reports when it refines on the exact path (``psi_at`` given), from the grid samples alone.

    Same inputs as :func:`dwell_intervals`; shape ``(...)``. With n the longest run of
    vertex-bounded samples within the band (what :func:`dwell_intervals` starts from), the
    window's own pair (φ_s, φ_{s+n−2}) is among the pairs its refinement chooses from, so the
    angle is ≥ (n − 2)·h. The samples inside the reported interval are within the band; a
    vertex-bounded sample is at most δ (the row's largest vertex lift) beyond its sample, so
    the interval holds at most n⁺ samples, n⁺ the longest run within band + 2δ, and is shorter
    than (n⁺ + 1)·h. A run over the whole turn is the whole turn (2π). Checked against the
    refined dwells of the ~1 200 six-bars the query fits to a spread of requests on the test
    atlas (``tests/synth/test_query_stage.py``).
    """
    from synth.mechanism.band_windows import longest_windows  # numba: imported on first use

    _, h, m, lead, E, band_r = _two_turns(phi, psi, band, dpsi1)
    upper, lower = _vertex_bounds(E)
    lift = np.maximum((upper - E).max(axis=1), (E - lower).max(axis=1))
    n = longest_windows(upper, lower, band_r, m)[0].max(axis=1)
    n_plus = longest_windows(upper, lower, band_r + 2 * lift, m)[0].max(axis=1)
    low = np.where(n >= m, _TWO_PI, np.maximum(n - 2, 0) * h)
    high = np.where(n_plus >= m, _TWO_PI, np.minimum((n_plus + 1) * h, _TWO_PI))
    return low.reshape(lead), high.reshape(lead)


def _linear_reach(E, length, w_max, w_min, band, mask):
    """(R, M) estimate, in grid steps, of how far the band reaches from each start where
    ``mask`` holds (−inf elsewhere): the grid window plus what ψ, taken linear between
    samples, adds on both sides, the band's placement [y, y + band] ⊇ [min, max] of the window
    chosen to maximise the sum (its best y is an end of its range or a neighbour sample's
    level). Ranks the candidate windows."""
    R, m = length.shape
    T = E.shape[1]
    rr, ii = np.nonzero(mask)
    net = E[rr, T // 2] - E[rr, 0]
    n = length[rr, ii]
    p_in = E[rr, ii]
    p_out = np.where(ii > 0, E[rr, np.maximum(ii - 1, 0)], E[rr, m - 1] - net)
    e = ii + n - 1
    q_in, q_out = E[rr, np.minimum(e, T - 1)], E[rr, np.minimum(e + 1, T - 1)]
    b = band[rr][:, None]
    hi, lo = w_max[rr, ii], w_min[rr, ii]
    lo_y, hi_y = (hi - band[rr])[:, None], lo[:, None]
    ys = np.stack([hi - band[rr], lo, p_out, p_out - band[rr], q_out, q_out - band[rr]], axis=-1)
    ys = np.clip(ys, lo_y, np.maximum(lo_y, hi_y))

    def frac(inside, outside, y):  # share of the step the line from inside to outside stays in [y, y + b]
        ins, out = inside[:, None], outside[:, None]
        d = out - ins
        below = (ins - y) / np.where(out < y, -d, 1.0)
        above = (y + b - ins) / np.where(out > y + b, d, 1.0)
        f = np.where(out < y, below, np.where(out > y + b, above, 1.0))
        return np.clip(f, 0.0, 1.0)

    with np.errstate(invalid="ignore", divide="ignore"):
        est = frac(p_in, p_out, ys) + frac(q_in, q_out, ys)
    out = np.full((R, m), -np.inf)
    out[rr, ii] = n - 1 + np.max(np.where(np.isfinite(est), est, 0.0), axis=-1)
    return out


def _near_longest(length: NDArray[np.int64], longest: NDArray[np.int64], reach: F64) -> NDArray[np.int64]:
    """(R, 2, CANDIDATES): grid starts whose window holds at least ``longest`` − 1 samples —
    those that can hold the longest exact interval (an interval of length Λ ≥ (longest − 1)·h
    holds ≥ longest − 1 samples, and the window from its first sample holds them all) — the
    largest linear ``reach`` first; row 1 flags which are real candidates."""
    R, m = length.shape
    ok = (length >= (longest - 1)[:, None]) & (length > 0)
    key = np.where(ok, -reach, np.inf)
    order = np.argsort(key, axis=1, kind="stable")[:, :CANDIDATES]
    valid = np.take_along_axis(ok, order, 1)
    valid[:, 0] = True  # something to refine in every row (a missing dwell is dropped later)
    return np.stack([order, valid.astype(np.int64)], axis=1)


def least_bands(psi: F64, widths: Sequence[int]) -> F64:
    """The narrowest output band (rad) in which some ``w`` consecutive samples of ψ stand, per
    row of ``psi`` ``(R, M)`` (ψ on the uniform crank grid over the turn; cyclic) and per ``w``
    of ``widths`` (1 ≤ w ≤ M): the smallest max − min of ψ over any such run, shape
    ``(R, len(widths))``; +inf for a row that does not close over the turn (an output that
    revolves, or not finite). A dwell of (w − 1)·h or more (h = 2π/M) at a band below that
    figure is impossible on the grid: the band a rest of that length needs, as sampled."""
    psi = np.asarray(psi, dtype=float)
    R, M = psi.shape
    out = np.full((R, len(widths)), np.inf)
    closed = np.all(np.isfinite(psi), axis=1) & (np.abs(psi[:, -1] - psi[:, 0]) < math.pi)
    if not closed.any():
        return out
    turns = np.concatenate([psi[closed], psi[closed]], axis=1)  # a window may run over the turn's end
    for k, w in enumerate(widths):
        if not 1 <= w <= M:
            raise ValueError(f"a run of {w} samples does not fit a turn of {M}")
        hi, lo = _sliding_extremes(turns, 0, M, w)
        out[closed, k] = (hi - lo).min(axis=1)
    return out


def _vertex_bounds(E: F64) -> tuple[F64, F64]:
    """(upper, lower): the samples, raised (lowered) at each local maximum (minimum) to the
    vertex of the parabola through it and its two neighbours
    (:func:`synth.mechanism.sample_ranges.vertex_bounds`; numba: imported on first use)."""
    from synth.mechanism.sample_ranges import vertex_bounds

    return vertex_bounds(E)


def _range_extremes(upper: F64, lower: F64, start, count) -> tuple[F64, F64]:
    """:func:`synth.mechanism.sample_ranges.range_extremes` (numba: imported on first use)."""
    from synth.mechanism.sample_ranges import range_extremes

    return range_extremes(upper, lower, start, count)


def _sliding_extremes(values: F64, first: int, count: int, width) -> tuple[F64, F64]:
    """:func:`synth.mechanism.sample_ranges.sliding_extremes` (numba: imported on first use)."""
    from synth.mechanism.sample_ranges import sliding_extremes

    return sliding_extremes(values, first, count, width)


def _eval_rewrapped(psi_at: PsiAt, at: F64, ref: F64, lead: tuple[int, ...]) -> F64:
    """Exact ψ at crank angles ``at`` (R, ...) on the branch of ``ref``; psi_at is called with
    the caller's leading shape."""
    R = at.shape[0]
    flat = at.reshape(R, -1)
    vals = np.asarray(psi_at(flat.reshape(lead + flat.shape[1:])), dtype=float).reshape(flat.shape)
    return _rewrap(vals.reshape(at.shape), ref)


def _fine_path(E, first, steps, K, phi0, h, psi_at, lead):
    """ψ on the exact path at K points per grid step over ``steps`` steps from sample ``first``
    (index into the two-turn samples E; −1 is the last sample of the previous turn): crank
    angles and values ``(R, C, steps·K + 1)``; sample points keep their sample values."""
    R = E.shape[0]
    T = E.shape[1]
    net = E[:, T // 2] - E[:, 0]
    idx = first[..., None] + np.arange(steps + 1)  # (R, ..., steps+1)
    r = np.arange(R).reshape((R,) + (1,) * (idx.ndim - 1))
    y = np.where(idx >= 0, E[r, np.clip(idx, 0, T - 1)], E[r, np.mod(idx, T // 2)] - net.reshape(r.shape))
    t = np.arange(steps * K + 1) / K  # in grid steps from ``first``
    at = phi0 + (first[..., None] + t) * h
    k, w = np.minimum(np.floor(t).astype(np.int64), steps - 1), t - np.minimum(np.floor(t), steps - 1)
    ref = (1 - w) * y[..., k] + w * y[..., k + 1]  # linear between samples: the 2π branch to evaluate on
    inner = (np.arange(t.size) % K) != 0
    vals = ref.copy()
    vals[..., inner] = _eval_rewrapped(psi_at, at[..., inner], ref[..., inner], lead)
    return at, vals


def _refine_dwell(E, s, n, band, phi0, h, psi_at, lead, upper, lower):
    """Each candidate grid window refined on the exact path (see :func:`dwell_intervals`):
    start in [φ_{s−1}, φ_s], end in [φ_{e₀}, φ_{e₀+2}] with e₀ = s + n − 2, on ``DWELL_FINE``
    points per grid step, the pair of points that maximises the length within the band.
    Shapes ``(R, C, W)``; returns what :func:`synth.mechanism.pair_search.longest_pair` returns."""
    R = E.shape[0]
    K = DWELL_FINE
    e0 = s + np.maximum(n - 2, 0)
    # samples strictly between the two regions: s+1 .. e0−1
    n_in = e0 - s - 1
    has_in = n_in >= 1
    flat = lambda x: x.reshape(R, -1)
    hi_in, lo_in = _range_extremes(upper, lower, flat(s + 1), flat(np.maximum(n_in, 1)))
    hi_in = np.where(has_in, hi_in.reshape(s.shape), -np.inf)
    lo_in = np.where(has_in, lo_in.reshape(s.shape), np.inf)
    left_at, lv = _fine_path(E, s - 1, 1, K, phi0, h, psi_at, lead)
    right_at, rv = _fine_path(E, e0, 2, K, phi0, h, psi_at, lead)
    # A window of samples within the band (start at φ_s, end at φ_{e₀}) is among the pairs.
    from synth.mechanism.pair_search import longest_pair  # numba: imported on first use

    return longest_pair(left_at, lv, right_at, rv, hi_in, lo_in, band)


def _samples_between(upper, lower, a, b, phi0, h):
    """max/min of the (vertex-bounded) samples strictly inside (a, b), ∓inf if there are none;
    a, b of shape (R, C) within the two turns of the tables."""
    R = a.shape[0]
    i0 = np.floor((a - phi0) / h).astype(np.int64) + 1
    i1 = np.ceil((b - phi0) / h).astype(np.int64) - 1
    T = upper.shape[1]
    i0 = np.clip(i0, 0, T - 1)
    count = np.minimum(i1, T - 1) - i0 + 1
    hi, lo = _range_extremes(upper, lower, i0.reshape(R, -1), np.maximum(count, 1).reshape(R, -1))
    return (np.where(count >= 1, hi.reshape(a.shape), -np.inf), np.where(count >= 1, lo.reshape(a.shape), np.inf))


def _refine_pair(start, end, level, inner_hi, inner_lo, band, step, psi_at, lead):
    """A finer pair search: start within ±``step`` of ``start``, end within ±``step`` of
    ``end``, on ``DWELL_FINE`` + 1 exact points each (``inner_hi``/``inner_lo``: extremes of
    what lies between; ``level``: a ψ inside the band, the 2π branch to evaluate on). Shapes
    ``(R, C)``."""
    t = np.linspace(-1.0, 1.0, DWELL_FINE + 1)
    ref = np.broadcast_to(level[..., None], start.shape + t.shape)
    left_at = start[..., None] + step * t
    right_at = end[..., None] + step * t
    both = _eval_rewrapped(
        psi_at, np.concatenate([left_at, right_at], axis=-1), np.concatenate([ref, ref], axis=-1), lead
    )
    lv, rv = both[..., : t.size], both[..., t.size :]
    from synth.mechanism.pair_search import longest_pair  # numba: imported on first use

    return longest_pair(left_at, lv, right_at, rv, inner_hi, inner_lo, band)


def _extend_ends(start, end, low, high, band, spacing, psi_at, lead):
    """Each end pushed outwards on the exact path while the band holds, the start first, then
    the end (which keeps the start maximal: a longer interval only adds constraints): two
    rounds of ``EXTEND_POINTS`` points, over the ``spacing`` of the last pair search and then
    over one of its parts, so that each end lies within spacing/EXTEND_POINTS² of where the
    band breaks. Shapes ``(R, C)``."""
    Q = EXTEND_POINTS
    b = band[:, None]
    q = np.arange(1, Q + 1) / Q
    for side in (-1, 1):
        step = spacing
        for _ in range(2):
            edge = start if side < 0 else end
            at = edge[..., None] + side * step * q
            ref = np.broadcast_to((0.5 * (low + high))[..., None], at.shape)
            v = _eval_rewrapped(psi_at, at, ref, lead)
            cmax = np.maximum(np.maximum.accumulate(v, axis=-1), high[..., None])
            cmin = np.minimum(np.minimum.accumulate(v, axis=-1), low[..., None])
            k = np.sum((cmax - cmin) <= b[..., None], axis=-1)  # leading points within the band
            moved = k > 0
            kk = np.maximum(k - 1, 0)[..., None]
            edge = np.where(moved, np.take_along_axis(at, kk, -1)[..., 0], edge)
            high = np.where(moved, np.take_along_axis(cmax, kk, -1)[..., 0], high)
            low = np.where(moved, np.take_along_axis(cmin, kk, -1)[..., 0], low)
            if side < 0:
                start = edge
            else:
                end = edge
            step = step / Q
    return start, end, low, high


def output_deviation(
    phi: ArrayLike,
    psi: ArrayLike,
    center: ArrayLike,
    length: ArrayLike,
    *,
    psi_at: PsiAt | None = None,
    dpsi1: ArrayLike | None = None,
) -> tuple[F64, F64]:
    """Smallest peak-to-peak of ψ over a crank window of the requested length around a dwell.

    The window [s, s + length] slides over every position that contains the crank angle
    ``center`` (s ∈ [center − length, center]); the result is the minimum over positions of
    max ψ − min ψ in the window — the output's deviation from rest during a dwell of the
    requested length.

    Parameters
    ----------
    phi : (M,) float
        Uniform full-turn crank grid (:func:`~synth.mechanism.sixbar.crank_grid`), rad.
    psi : (..., M) float
        Output angle unwrapped along the last axis, rad.
    center : float or (...,) float
        Crank angle (rad) the window must contain, e.g. the middle of a found dwell.
    length : float or (...,) float
        Requested dwell length (rad), in (0, 2π − 2h].
    psi_at : callable, optional
        Exact ψ(φ) (see :func:`dwell_intervals`); the best grid placement is then refined on
        the exact path in two stages (2h/``DWELL_FINE`` … then h/(4·``DWELL_FINE``²)·…, about
        0.004° on the 0.5° grid), with the window ends evaluated exactly.
    dpsi1 : (..., M) float, optional
        ψ′, to pick the branch of the turn-closing step.

    Returns
    -------
    deviation : (...,) float
        Rad, ≥ 0.
    window_start : (...,) float
        Crank angle s of the best window (rad, in [φ₀, φ₀ + 2π)).
    """
    phi0, h, m = grid_step(phi)
    psi = np.asarray(psi, dtype=float)
    lead = psi.shape[:-1]
    P = psi.reshape(-1, m)
    R = P.shape[0]
    c = np.broadcast_to(np.asarray(center, float), lead).reshape(R)
    L = np.broadcast_to(np.asarray(length, float), lead).reshape(R)
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(L))):
        raise ValueError("center and length must be finite")
    if np.any(L <= 0) or np.any(L > _TWO_PI - 2 * h):
        raise ValueError("window length must be in (0, 2*pi - 2 grid steps]")
    d1 = None if dpsi1 is None else np.asarray(dpsi1, float).reshape(R, m)
    net = _net_change(P, d1, h)
    rows = np.arange(R)
    nL = np.floor(L / h + 1e-9).astype(np.int64)  # samples i..i+nL lie in [φ_i, φ_i + L]
    # Grid placements: sample starts with φ_i in [c − L, c], i counted from φ₀ (may be < 0).
    i_lo = np.ceil((c - L - phi0) / h - 1e-9).astype(np.int64)
    i_hi = np.floor((c - phi0) / h + 1e-9).astype(np.int64)
    span = i_hi - i_lo + 1
    J = int(span.max())
    # Only a slab of ψ matters: from sample i_lo − 1 to the end of the last window plus one,
    # continued over turn boundaries by the net change.
    W = J + int(nL.max()) + 4
    g = (i_lo - 1)[:, None] + np.arange(W)[None, :]
    slab = P[rows[:, None], np.mod(g, m)] + np.floor_divide(g, m) * net[:, None]
    # the window from start i_lo + j (slab offset 1 + j) holds nL + 1 samples
    hi, lo = _sliding_extremes(slab, 1, J, nL + 1)
    valid = np.arange(J)[None, :] < span[:, None]
    grid_range = np.where(valid, hi - lo, np.inf)
    jbest = np.argmin(grid_range, axis=1)
    dev = grid_range[rows, jbest]
    s_best = phi0 + (i_lo + jbest) * h
    compiled = _compiled_rows(psi_at, R)
    if compiled is not None:  # the same stages in one compiled pass (synth.mechanism.dwell_ends_kernel)
        from synth.mechanism.dwell_ends_kernel import refine_deviation_windows  # numba: imported on first use

        dev, s_best = refine_deviation_windows(
            psi_at.params,
            psi_at.rpr,
            compiled,
            slab,
            i_lo,
            jbest + 1,
            nL,
            L,
            c,
            dev,
            s_best,
            phi0,
            h,
            psi_at.pin_eps,
            2 * min(_fine_count(h), DWELL_FINE),
            DWELL_FINE,
        )
    elif psi_at is not None:
        dev, s_best = _refine_window(slab, i_lo, jbest + 1, nL, L, c, dev, s_best, phi0, h, psi_at, lead)
    s_best = phi0 + np.mod(s_best - phi0, _TWO_PI)
    return dev.reshape(lead), s_best.reshape(lead)


def _refine_window(slab, i_lo, k, nL, L, c, dev, s_best, phi0, h, psi_at, lead):
    """Window placement refined on the exact path around the best grid start, which sits at
    slab offset ``k`` (slab offset 0 is sample i_lo − 1)."""
    R = slab.shape[0]
    K2 = 2 * min(_fine_count(h), DWELL_FINE)  # as synth.mechanism.dwell_ends_kernel is given it
    t = np.arange(K2 + 1) / K2
    r = np.arange(R)[:, None]
    s_lo = phi0 + (i_lo - 2 + k) * h  # one step before the best grid start
    f = s_lo[:, None] + 2 * h * t[None, :]  # candidate starts (R, K2+1)
    g = f + L[:, None]  # their ends
    allowed = (f >= (c - L)[:, None] - 1e-12) & (f <= c[:, None] + 1e-12)

    def ref_at(x):  # linear interpolation of the samples: the 2π branch to evaluate on
        idx = (x - phi0) / h - (i_lo - 1)[:, None]
        j = np.clip(np.floor(idx).astype(np.int64), 0, slab.shape[1] - 2)
        w = idx - j
        return (1 - w) * slab[r, j] + w * slab[r, j + 1]

    at = np.concatenate([f, g], axis=1)
    vals = _eval_rewrapped(psi_at, at, ref_at(at), lead)
    fv, gv = vals[:, : K2 + 1], vals[:, K2 + 1 :]
    # Samples strictly between the start region [φ_{i−1}, φ_{i+1}] and the end region
    # [φ_{i−1} + L, φ_{i+1} + L]: i+2 .. i−1+nL, i.e. slab offsets k+2 .. k−1+nL.
    n_in = nL - 2
    has_in = n_in >= 1
    hi_in, lo_in = _range_extremes(slab, slab, (k + 2)[:, None], np.maximum(n_in, 1)[:, None])
    hi_in = np.where(has_in, hi_in[:, 0], -np.inf)
    lo_in = np.where(has_in, lo_in[:, 0], np.inf)
    sf_max = np.maximum.accumulate(fv[:, ::-1], axis=1)[:, ::-1]
    sf_min = np.minimum.accumulate(fv[:, ::-1], axis=1)[:, ::-1]
    pg_max = np.maximum.accumulate(gv, axis=1)
    pg_min = np.minimum.accumulate(gv, axis=1)
    top = np.maximum(np.maximum(sf_max, pg_max), hi_in[:, None])
    bot = np.minimum(np.minimum(sf_min, pg_min), lo_in[:, None])
    rng = np.where(allowed, top - bot, np.inf)
    j = np.argmin(rng, axis=1)
    fine = rng[r[:, 0], j]
    # The fine placements contain the grid one; where the window is shorter than two steps
    # the start and end regions overlap and the split above does not hold: keep the grid.
    refined = (fine < np.inf) & (nL >= 2)
    # Again around the best fine start, ±one fine step on DWELL_FINE + 1 points (~0.004° on
    # the 0.5° grid): between the two end regions lie the stage's own points (suffix of the
    # starts beyond j + 1, prefix of the ends before j − 1) and the samples.
    rr = r[:, 0]
    d = 2 * h / K2
    f_best = f[rr, j]
    t3 = np.linspace(-1.0, 1.0, DWELL_FINE + 1)
    f3 = f_best[:, None] + d * t3[None, :]
    g3 = f3 + L[:, None]
    allowed3 = (f3 >= (c - L)[:, None] - 1e-12) & (f3 <= c[:, None] + 1e-12)
    at3 = np.concatenate([f3, g3], axis=1)
    vals3 = _eval_rewrapped(psi_at, at3, ref_at(at3), lead)
    fv3, gv3 = vals3[:, : t3.size], vals3[:, t3.size :]
    a_off = (f_best + d - phi0) / h - (i_lo - 1)
    b_off = (f_best - d + L - phi0) / h - (i_lo - 1)
    i0 = np.floor(a_off).astype(np.int64) + 1
    cnt = np.ceil(b_off).astype(np.int64) - 1 - i0 + 1
    shi, slo = _range_extremes(slab, slab, i0[:, None], np.maximum(cnt, 1)[:, None])
    mid_hi = np.where(cnt >= 1, shi[:, 0], -np.inf)
    mid_lo = np.where(cnt >= 1, slo[:, 0], np.inf)
    nxt, prv = np.minimum(j + 1, K2), np.maximum(j - 1, 0)
    mid_hi = np.maximum(mid_hi, np.where(j + 1 <= K2, sf_max[rr, nxt], -np.inf))
    mid_lo = np.minimum(mid_lo, np.where(j + 1 <= K2, sf_min[rr, nxt], np.inf))
    mid_hi = np.maximum(mid_hi, np.where(j >= 1, pg_max[rr, prv], -np.inf))
    mid_lo = np.minimum(mid_lo, np.where(j >= 1, pg_min[rr, prv], np.inf))
    top3 = np.maximum(
        np.maximum(np.maximum.accumulate(fv3[:, ::-1], axis=1)[:, ::-1], np.maximum.accumulate(gv3, axis=1)),
        mid_hi[:, None],
    )
    bot3 = np.minimum(
        np.minimum(np.minimum.accumulate(fv3[:, ::-1], axis=1)[:, ::-1], np.minimum.accumulate(gv3, axis=1)),
        mid_lo[:, None],
    )
    rng3 = np.where(allowed3, top3 - bot3, np.inf)
    j3 = np.argmin(rng3, axis=1)
    fine3 = rng3[rr, j3]
    finer = refined & (fine3 < fine) & (nL >= 4)
    fine = np.where(finer, fine3, fine)
    f_best = np.where(finer, f3[rr, j3], f_best)
    return np.where(refined, fine, dev), np.where(refined, f_best, s_best)
