"""The refinement's objective and its acceptance (pure): the cost :mod:`synth.query.refine`'s
searches minimise over trial six-bars — the output deviation over the requested dwell in
bands, plus ``PENALTY`` × the sum of the request's constraint excesses, each zero inside a
margin — what each six-bar is held to in the loop (:func:`hold_bounds`), and the test a
refined six-bar must pass to replace the one it came from (:func:`better_or_equal`). The
formulas are in :mod:`synth.query.refine`'s docstring.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from synth.mechanism.buildability import clearances
from synth.mechanism.figures import SixBarFigures, link_ratios_at
from synth.mechanism.output_range import output_deviation
from synth.mechanism.sixbar import PIN_ON_PIVOT_EPS, SixBars, kernel_inputs, simulate
from synth.query.candidates import Request, objectives
from synth.query.evaluate import meets

__all__ = [
    "CLEARANCE_EVERY",
    "PENALTY",
    "WORST",
    "better_or_equal",
    "hold_bounds",
    "request_bounds",
    "trial_batch",
    "trial_objective",
]

#: The loop's clearance and torque arm on every 3rd sample (3°; the margins and the check cover it).
CLEARANCE_EVERY = 3
#: Weight of the constraint excesses against the deviation (in bands).
PENALTY = 1000.0
#: The objective of a trial six-bar that does not assemble over the turn, toggles or revolves:
#: worse than any other (a search stops a candidate whose start is this bad).
WORST = 1e12
#: Margins: the grid's figures must meet the request by this much (fractions of the band, the
#: swing tolerance, degrees of transmission, percent of limits).
_BAND_MARGIN = 0.03
_TRANSMISSION_MARGIN = math.radians(0.25)


def trial_batch(p: np.ndarray, branch: np.ndarray, rpr: np.ndarray, dyad_branch: np.ndarray) -> SixBars:
    """Rows of dimension vectors (R, 9) as a batch (no validation: the box keeps lengths > 0)."""
    n = p.shape[0]
    return SixBars(
        np.ones(n),
        p[:, 0],
        p[:, 1],
        p[:, 2],
        branch.astype(float),
        p[:, 3],
        p[:, 4],
        rpr,
        p[:, 5] + 1j * p[:, 6],
        np.where(rpr, 0.0, p[:, 7]),
        np.where(rpr, 0.0, p[:, 8]),
        dyad_branch.astype(float),
    )


def trial_objective(
    request: Request,
    p: np.ndarray,
    branch,
    rpr,
    dyad_branch,
    centres: np.ndarray,
    bounds: np.ndarray,
    phi: np.ndarray,
    *,
    stillest: bool = False,
    compiled: bool = False,
) -> np.ndarray:
    """(R,) objective of the dimension rows ``p`` (R, 9) whose dwells should sit around crank
    angles ``centres`` (R, C) rad, held to ``bounds`` (R, 4: :func:`hold_bounds`) (see the module
    docstring); lower is better. ``stillest``: no band holds the dwell — the deviation over the
    requested dwell is minimised for itself (in units of ``request.band``) under every other
    constraint, for a search of the tightest band (:mod:`synth.query.band_search`).
    ``compiled``: the loop figures from :mod:`synth.query.refine_kernel` (one pass per six-bar,
    the same figures to ~1e-13) where no limit caps the peak acceleration, which needs ψ″
    (the numpy path, the reference, takes that case and any with ``compiled`` False)."""
    batch = trial_batch(p, branch, rpr, dyad_branch)
    # trial six-bars may degenerate (a link ratio over a zero-length reach): such a row's
    # objective is not finite and is set to the worst below, so the arithmetic stays quiet
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _objective_rows(request, batch, rpr, centres, bounds, phi, stillest, compiled)


def hold_bounds(request: Request, before: Sequence[SixBarFigures]) -> np.ndarray:
    """(K, 4) what the loop holds each six-bar to: the half-width (rad) of the dwell's window
    about the requested dwell, the smallest worst transmission angle (rad), the largest peak
    |ψ″| (rad/rad², inf: none) and the band's margin (a fraction) on that window's ends. For a
    six-bar that meets the request, no worse than it is on the ranking's objectives (its dwell
    error, transmission, peak acceleration; the footprint is left to the check) with no band
    margin (its dwell error may be far below the grid's step: the check decides): a change
    that trades them for deviation would be refused by the check (:func:`better_or_equal`).
    For a miss, the request's: half the dwell tolerance, its minimum transmission, its
    ``max_accel``, ``_BAND_MARGIN``."""
    w = 2 * math.pi * request.rpm / 60
    cap = math.inf if request.max_accel is None else request.max_accel / (w * w)
    out = np.empty((len(before), 4))
    for k, f in enumerate(before):
        if meets(request, f):
            error = max(abs(d.angle - request.dwell) for d in f.dwells[: request.dwells])
            out[k] = (
                min(0.5 * request.dwell_tol, error),
                min(f.transmission_fourbar, f.transmission_output),
                min(cap, f.build.peak_rates[1]) if f.build is not None else cap,
                0.0,
            )
        else:
            out[k] = request_bounds(request, 1)[0]
    return out


def request_bounds(request: Request, n: int) -> np.ndarray:
    """(n, 4) the bounds of :func:`hold_bounds` for six-bars held to the request alone: half the
    dwell tolerance, its minimum transmission, its ``max_accel`` (rad/rad², inf: none) and
    ``_BAND_MARGIN``."""
    w = 2 * math.pi * request.rpm / 60
    cap = math.inf if request.max_accel is None else request.max_accel / (w * w)
    return np.tile([0.5 * request.dwell_tol, request.min_transmission, cap, _BAND_MARGIN], (n, 1))


@dataclass(frozen=True, slots=True)
class _LoopFigures:
    """What the objective reads of R trial six-bars on the loop's grid (either path).

    Attributes
    ----------
    good : (R,) bool
        Assembles at every sample, no toggle, an output that does not revolve.
    deviation : (R, C, W) float
        The grid deviation (rad) per dwell centre and window length.
    swing, transmission : (R,) float
        max ψ − min ψ and the smallest folded transmission angle of either loop (rad).
    reach, arm : (R,) float
        Longest and shortest |P − D| over the turn (crank lengths).
    clearance : (R,) float
        Clearance on every ``CLEARANCE_EVERY``-th sample (crank lengths).
    peak : (R,) float or None
        max |ψ″| (rad/rad²), where a limit caps it.
    """

    good: np.ndarray
    deviation: np.ndarray
    swing: np.ndarray
    transmission: np.ndarray
    reach: np.ndarray
    arm: np.ndarray
    clearance: np.ndarray
    peak: np.ndarray | None = None


def _window_lengths(request: Request, margin: np.ndarray, h: float, stillest: bool) -> np.ndarray:
    """(R, W) the windows' lengths (rad): the requested dwell alone (``stillest``), else also
    its bounds D − margin and D + margin (within the grid's longest window)."""
    longest = 2 * math.pi - 2 * h
    dwell = np.full(len(margin), min(request.dwell, longest))
    if stillest:  # the band follows the rest: the deviation over the dwell alone is wanted
        return dwell[:, None]
    # the dwell's bounds too: g(D − margin) and g(D + margin) against the band
    return np.stack(
        [np.clip(request.dwell - margin, 2 * h, longest), dwell, np.minimum(request.dwell + margin, longest)], axis=1
    )


def _numpy_figures(
    batch: SixBars, centres: np.ndarray, lengths: np.ndarray, phi: np.ndarray, order: int
) -> _LoopFigures:
    """:class:`_LoopFigures` from :func:`~synth.mechanism.sixbar.simulate` and the figures'
    own functions: the reference, and the path of a capped peak acceleration (``order`` 2)."""
    motion = simulate(batch, phi, order=order)
    psi = motion.psi
    R, M = psi.shape
    C, W = centres.shape[1], lengths.shape[1]
    dev, _ = output_deviation(
        phi,
        np.broadcast_to(psi[:, None, None, :], (R, C, W, M)),
        np.broadcast_to(centres[:, :, None], (R, C, W)),
        np.broadcast_to(lengths[:, None, :], (R, C, W)),
    )
    reach = np.abs(motion.z[0] - batch.pivot[:, None])
    return _LoopFigures(
        np.all(motion.status == 0, axis=1) & (np.abs(psi[:, -1] - psi[:, 0]) < math.pi),
        dev,
        psi.max(axis=1) - psi.min(axis=1),
        np.minimum(motion.transmission_fourbar.min(axis=1), motion.transmission_output.min(axis=1)),
        reach.max(axis=1),
        reach.min(axis=1),
        clearances(batch, motion, every=CLEARANCE_EVERY)[1],
        np.abs(motion.dpsi[1]).max(axis=1) if order == 2 else None,
    )


def _compiled_figures(batch: SixBars, centres: np.ndarray, lengths: np.ndarray, phi: np.ndarray) -> _LoopFigures:
    """:class:`_LoopFigures` (no peak acceleration) in one compiled pass per six-bar
    (:mod:`synth.query.refine_kernel`): the same figures as :func:`_numpy_figures`."""
    from synth.query.refine_kernel import trial_figures  # numba: imported on first use

    params, rpr = kernel_inputs(batch)
    good, dev, figures = trial_figures(params, rpr, phi, PIN_ON_PIVOT_EPS, centres, lengths, CLEARANCE_EVERY)
    return _LoopFigures(good, dev, *figures.T)


def _objective_rows(
    request: Request,
    batch: SixBars,
    rpr: np.ndarray,
    centres: np.ndarray,
    bounds: np.ndarray,
    phi: np.ndarray,
    stillest: bool = False,
    compiled: bool = False,
) -> np.ndarray:
    margin, mu_floor, accel_cap, band_margin = bounds.T
    capped = np.isfinite(accel_cap)
    order = 2 if capped.any() else 0
    h = 2 * math.pi / phi.shape[-1]
    lengths = _window_lengths(request, margin, h, stillest)
    if compiled and order == 0:
        loop = _compiled_figures(batch, centres, lengths, phi)
    else:
        loop = _numpy_figures(batch, centres, lengths, phi, order)
    dev = loop.deviation
    W = lengths.shape[1]
    band = request.band
    longest = 2 * math.pi - 2 * h
    objective = dev[:, :, W // 2].max(axis=1) / band
    if stillest:
        excess = np.zeros(len(batch))
    else:
        excess = np.maximum(0.0, dev[:, :, 0] - (band * (1 - band_margin))[:, None]).sum(axis=1) / band
        excess += np.where(
            request.dwell + margin < longest,
            np.maximum(0.0, (band * (1 + band_margin))[:, None] - dev[:, :, 2]).sum(axis=1) / band,
            0.0,
        )
    if request.swing is not None:
        unit = max(request.swing_tol, math.radians(0.01))
        excess += np.maximum(0.0, np.abs(loop.swing - request.swing) - 0.5 * request.swing_tol) / unit
    excess += np.maximum(0.0, mu_floor + _TRANSMISSION_MARGIN - loop.transmission) / math.radians(1.0)
    ratio = link_ratios_at(batch, loop.reach)  # the figures' own formula, on the loop's grid
    excess += np.maximum(0.0, ratio / request.max_link_ratio - 0.999) / 0.01
    excess += np.where(rpr, np.maximum(0.0, request.min_arm * 1.02 + 1e-3 - loop.arm), 0.0) / 0.01
    excess += np.maximum(0.0, request.min_clearance * 1.02 + 1e-3 - loop.clearance) / 0.01
    if loop.peak is not None:
        excess += np.where(capped, np.maximum(0.0, loop.peak / np.where(capped, accel_cap, 1.0) - 0.99) / 0.01, 0.0)
    f = objective + PENALTY * excess
    return np.where(loop.good & np.isfinite(f), f, WORST)


def better_or_equal(request: Request, new: SixBarFigures, old: SixBarFigures) -> bool:
    """Whether figures ``new`` may replace ``old`` in a ranking for ``request``: no worse on
    any of the ranking's objectives (:func:`~synth.query.candidates.objectives`: dwell error,
    output deviation, worst transmission angle, footprint, peak output acceleration) and
    better on one, both rounded as :func:`~synth.query.candidates.rank` rounds them (so that the
    last bits of a simulation do not decide). Both in the same units (e.g. crank lengths)."""
    obj = np.round(objectives(request, [new, old]), 10)
    return bool(np.all(obj[0] <= obj[1]) and np.any(obj[0] < obj[1]))
