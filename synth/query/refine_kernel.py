"""The refinement's loop figures of trial six-bars, compiled: what
:func:`synth.query.refine_objective.trial_objective` judges a trial six-bar by, in one pass
over each one's crank samples.

The refinement's reach (:mod:`synth.query.refine`: a near miss's CMA-ES and the stillest
rest's) judges its trial six-bars by these figures; a search of the stillest rest
(:func:`synth.query.refine.stiller`) simulates ~35 000 per request on the loop's 360-sample
grid. The numpy path simulates them (:func:`synth.mechanism.sixbar.simulate`), then reads the
motion again for every figure — the deviation windows, the swing, the transmission angles,
|P − D|, the clearances — through a dozen whole-array temporaries: about two thirds of an
objective evaluation were that glue.
Here each six-bar is one loop over its samples that keeps what the objective needs (ψ in a
row of scratch, the extremes of the rest) and reads ψ once more for its deviation windows.

The same operations as the numpy path, from the same compiled functions: the position of a
sample from :mod:`synth.mechanism.sixbar_kernel` (its closing triangles, coupler point, slot,
transmission cosine and the order-0 unwrap of ψ), the clearances by
:func:`synth.mechanism.clearance_kernel.clearance_rows` on the joints of every ``every``-th
sample (kept in a row of scratch), the deviation windows as
:func:`~synth.mechanism.output_range.output_deviation` places them on the grid, their extremes
by :func:`synth.mechanism.sample_ranges.sliding_rows`. Two differences, neither changing a
value: a six-bar's folded transmission angle is taken once from the largest and smallest
cosine over the turn (the fold is monotone on each side of 0: the same minimum without an
arccosine per sample), and a six-bar stops at its first flagged sample (the objective rejects
it whole). ``tests/synth/test_refine_kernel.py`` holds the objective from these figures to the
numpy path's on trial rows around real six-bars, failures included.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from synth.mechanism.clearance_kernel import clearance_rows
from synth.mechanism.sample_ranges import sliding_rows
from synth.mechanism.sixbar_kernel import (
    closing_point,
    coupler_point,
    coupler_rocker_cos,
    fold_transmission,
    phasor_step,
    pin_size,
    slot_phasor,
)
from synth.parallel_rows import one_signature, over_rows

__all__ = ["FIGURES", "trial_figures"]

#: The columns of :func:`trial_figures`' ``figures``: the swing max ψ − min ψ (rad), the
#: smallest transmission angle of either loop (rad), the longest and shortest |P − D| over the
#: turn (length) and the clearance on every ``every``-th sample (length).
FIGURES = ("swing", "transmission", "reach", "arm", "clearance")

_TWO_PI = 2.0 * math.pi

# the position's functions inlined into the loop (numba IR): their order-1 rate factors, never
# read here, are then dropped
_closing_point = numba.njit(inline="always", error_model="numpy")(closing_point.py_func)
_coupler_point = numba.njit(inline="always", error_model="numpy")(coupler_point.py_func)
_slot_phasor = numba.njit(inline="always", error_model="numpy")(slot_phasor.py_func)
_HALF_PI = 0.5 * math.pi  # an RPR output's transmission angle (synth.mechanism.sixbar.RPR_TRANSMISSION)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _window_deviation(psi, net, phi0, h, centre, length, slab, width, hi, lo):
    """One row's grid deviation of :func:`~synth.mechanism.output_range.output_deviation`: the
    least range of ψ over the windows of ``length`` (rad) that contain ``centre`` (rad), ψ
    continued over the turn by its ``net`` change; inf where no sample starts one."""
    m = psi.shape[0]
    n_len = math.floor(length / h + 1e-9)  # samples i..i+n_len lie in [φ_i, φ_i + length]
    i_lo = math.ceil((centre - length - phi0) / h - 1e-9)
    i_hi = math.floor((centre - phi0) / h + 1e-9)
    span = i_hi - i_lo + 1
    if span < 1:
        return math.inf
    turns = i_lo // m  # sample i_lo + k is ψ[at] + turns·net, at its index in the turn
    at = i_lo - turns * m
    for k in range(span + n_len):
        slab[0, k] = psi[at] + turns * net
        at += 1
        if at == m:
            at, turns = 0, turns + 1
    width[0] = n_len + 1
    sliding_rows(slab, 0, span, width, hi, lo)
    best = math.inf
    for j in range(span):
        best = min(best, hi[0, j] - lo[0, j])
    return best


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _trial_rows(params, rpr, phi, pin_eps, every, centres, lengths, good, deviation, figures):
    """Fill ``good`` (N,), ``deviation`` (N, C, W) and ``figures`` (N, 5: :data:`FIGURES`) of
    the six-bars of ``params`` (N, 12; :func:`synth.mechanism.sixbar.kernel_inputs`' rows) on
    the full-turn grid ``phi`` (M,). A row that is flagged at a sample or whose output revolves
    gets ``good`` False and zeros."""
    n, m = params.shape[0], phi.shape[0]
    h = _TWO_PI / m
    phi0 = phi[0]
    cos_phi, sin_phi = np.empty(m), np.empty(m)
    for j in range(m):
        cos_phi[j], sin_phi[j] = math.cos(phi[j]), math.sin(phi[j])
    psi = np.empty(m)
    # the clearances' samples (every ``every``-th) and the row, as clearance_rows reads them
    held = (m + every - 1) // every
    at_a, at_b = np.empty((1, held), np.complex128), np.empty((1, held), np.complex128)
    at_p, at_q = np.empty((1, held), np.complex128), np.empty((1, held), np.complex128)
    at_psi, at_reach, smallest = np.empty((1, held)), np.empty((1, held)), np.empty((1, 16))
    ground, pivot, kind = np.empty(1), np.empty(1, np.complex128), np.empty(1, np.bool_)
    slab, hi, lo = np.empty((1, 2 * m + 8)), np.empty((1, 2 * m + 8)), np.empty((1, 2 * m + 8))
    width = np.empty(1, np.int64)
    for i in range(n):
        a, b, c, d, br, u, v, dx, dy, rocker, rod, dyad_branch = params[i]  # kernel_inputs' columns
        size = pin_size(a, b, c, d, dx, dy)
        slotted = rpr[i]
        flagged = 0
        base0 = acc = 0.0
        px, py = 1.0, 0.0
        fb_hi, fb_lo, out_hi, out_lo = -np.inf, np.inf, -np.inf, np.inf
        reach_hi, reach_lo = -np.inf, np.inf
        next_clearance = 0
        for j in range(m):
            ct, st, _, _, fb, _, _, ax, ay, _, _, zx, zy = _coupler_point(a, b, c, d, br, u, v, cos_phi[j], sin_phi[j])
            if slotted:
                ex, ey, dyad, _, _ = _slot_phasor(zx, zy, dx, dy, pin_eps, size)
                qx = qy = 0.0
            else:
                cx, cy, ex, ey, dyad, _, _ = _closing_point(dx - zx, dy - zy, rod, rocker, dyad_branch)
                qx, qy = dx + rocker * ex, dy + rocker * ey
                cos_out = cx * ex + cy * ey
                out_hi, out_lo = max(out_hi, cos_out), min(out_lo, cos_out)
            flagged |= fb | dyad
            if flagged:  # rejected whole: the rest of its figures are never read
                break
            cos_fb = coupler_rocker_cos(ax, ay, ct, st, b, c, d)
            fb_hi, fb_lo = max(fb_hi, cos_fb), min(fb_lo, cos_fb)
            if j == 0:
                base0 = math.atan2(ey, ex)
                psi[j] = base0
            else:
                acc += phasor_step(ex, ey, px, py)
                psi[j] = acc + base0
            px, py = ex, ey
            # |P − D| squared: its extremes' roots at the end, not a hypot per sample
            reach2 = (zx - dx) * (zx - dx) + (zy - dy) * (zy - dy)
            reach_hi, reach_lo = max(reach_hi, reach2), min(reach_lo, reach2)
            if j == next_clearance:
                k = j // every  # once every ``every`` samples
                next_clearance += every
                at_a[0, k], at_b[0, k] = complex(ax, ay), complex(ax + b * ct, ay + b * st)
                at_p[0, k], at_q[0, k] = complex(zx, zy), complex(qx, qy)
                at_psi[0, k] = psi[j]
        if flagged or not abs(psi[m - 1] - psi[0]) < math.pi:
            good[i] = False
            deviation[i] = 0.0
            figures[i] = 0.0
            continue
        good[i] = True
        ground[0], pivot[0], kind[0] = d, complex(dx, dy), slotted
        clearance_rows(at_a, at_b, at_p, at_q, at_psi, ground, pivot, kind, 1, at_reach, smallest)
        clearance = math.inf
        for p in range(16):
            clearance = min(clearance, smallest[0, p])
        mu = min(fold_transmission(fb_hi), fold_transmission(fb_lo))
        mu = min(mu, _HALF_PI) if slotted else min(mu, min(fold_transmission(out_hi), fold_transmission(out_lo)))
        top, bottom = psi[0], psi[0]
        for j in range(1, m):
            top, bottom = max(top, psi[j]), min(bottom, psi[j])
        # ψ(φ₀ + 2π) − ψ(φ₀): the turn closed on the step's nearest branch (output_range._net_change)
        closing = 0.0 + (((psi[0] - psi[m - 1] - 0.0) + math.pi) % _TWO_PI - math.pi)
        net = psi[m - 1] + closing - psi[0]
        for k in range(centres.shape[1]):
            for w in range(lengths.shape[1]):
                deviation[i, k, w] = _window_deviation(
                    psi, net, phi0, h, centres[i, k], lengths[i, w], slab, width, hi, lo
                )
        figures[i, 0], figures[i, 1], figures[i, 2] = top - bottom, mu, math.sqrt(reach_hi)
        figures[i, 3], figures[i, 4] = math.sqrt(reach_lo), clearance


def trial_figures(
    params: np.ndarray,
    rpr: np.ndarray,
    phi: np.ndarray,
    pin_eps: float,
    centres: np.ndarray,
    lengths: np.ndarray,
    every: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The loop figures of ``N`` trial six-bars.

    Parameters
    ----------
    params : (N, 12) float
        :func:`synth.mechanism.sixbar.kernel_inputs`' rows (crank-normalised lengths, rad).
    rpr : (N,) bool
        Which rows are RPR.
    phi : (M,) float
        The full-turn crank grid (rad, :func:`~synth.mechanism.sixbar.crank_grid`).
    pin_eps : float
        :data:`synth.mechanism.sixbar.PIN_ON_PIVOT_EPS`.
    centres : (N, C) float
        Crank angles (rad) each row's deviation windows must contain.
    lengths : (N, W) float
        Window lengths (rad), in (0, 2π − 2h].
    every : int
        The clearances on every ``every``-th sample.

    Returns
    -------
    good : (N,) bool
        No sample flagged (:class:`~kinematics.status.Status`) and an output that does not
        revolve (|ψ(φ_{M−1}) − ψ(φ₀)| < π).
    deviation : (N, C, W) float
        :func:`~synth.mechanism.output_range.output_deviation` on the grid (rad) per centre
        and length; 0 where not ``good``.
    figures : (N, 5) float
        :data:`FIGURES`; 0 where not ``good``.
    """
    n, m = params.shape[0], phi.shape[0]
    params = np.ascontiguousarray(params, dtype=float)
    rpr = np.ascontiguousarray(rpr, dtype=np.bool_)
    phi = np.ascontiguousarray(phi, dtype=float)
    centres = np.ascontiguousarray(centres, dtype=float)
    lengths = np.ascontiguousarray(lengths, dtype=float)
    good = np.empty(n, np.bool_)
    deviation = np.empty((n, centres.shape[1], lengths.shape[1]))
    figures = np.empty((n, len(FIGURES)))
    args = (params, rpr, phi, float(pin_eps), int(every), centres, lengths, good, deviation, figures)
    # row blocks of these are C-contiguous too: one compile, whichever split
    one_signature(_trial_rows, args, read_only=(0, 1, 2, 5, 6))

    def block(lo: int, hi: int) -> None:
        _trial_rows(
            params[lo:hi],
            rpr[lo:hi],
            phi,
            float(pin_eps),
            int(every),
            centres[lo:hi],
            lengths[lo:hi],
            good[lo:hi],
            deviation[lo:hi],
            figures[lo:hi],
        )

    over_rows(n, block, 80 * n * m)  # ~80 ns a sample
    return good, deviation, figures
