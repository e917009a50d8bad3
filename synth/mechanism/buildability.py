"""Can a designer build it? Figures of a six-bar's motion that decide whether its parts collide
or its slider loses its grip, and how hard its output is driven — from the exact simulation.

* **Torque arm** (RPR): the smallest distance from the slider (the coupler point P) to the slot
  pivot D over the turn. Near zero the block runs over its own pivot: it cannot be built, and
  the slot's torque on the output needs an unbounded force. The slot length used is the range
  of |P − D|.
* **Clearance**: the smallest distance over the turn between a moving joint (A, B, P, and Q of
  an RRR) and a fixed pivot it is not pinned to (A0, B0, D), and between an output link (RRR
  rod P–Q and rocker D–Q; RPR slot from D to its far end) and a fixed pivot off that link.
  Pairs whose distance is a link length (A–A0, B–B0, Q–D) and the slider–slot pivot pair (the
  torque arm) are left out.
* **Output rates**: the peaks over the turn of |ψ′|, |ψ″| and |ψ‴| (per radian of crank, to the
  power of the order). At a crank speed ω they are the peak angular velocity ψ′ω, acceleration
  ψ″ω² and jerk ψ‴ω³ of the output (constant crank speed). ψ′ and ψ″ are the simulation's closed
  forms; ψ‴ is the spectral derivative of ψ″ over the periodic turn (exact for a trigonometric
  polynomial; checked against central differences of ψ″ in the tests).

All lengths in the six-bar's unit; batches of N six-bars on the same crank grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from synth.mechanism.sixbar import SixBarMotion, SixBars

__all__ = ["CLEARANCE_PAIRS", "Buildability", "buildability", "clearances", "output_rates"]


@dataclass(frozen=True, slots=True)
class Buildability:
    """Buildability figures of one six-bar (see the module docstring).

    Attributes
    ----------
    arm : float or None
        RPR: smallest |P − D| over the turn (length); None for an RRR.
    slot : (float, float) or None
        RPR: smallest and largest |P − D| — the stretch of the slot the slider uses.
    clearance : float
        Smallest joint/link-to-fixed-pivot distance over the turn (length).
    clearance_between : str
        The pair that sets it, e.g. ``"rod P-Q / A0"`` or ``"joint Q / B0"``.
    peak_rates : (float, float, float)
        max |ψ′| (rad/rad), max |ψ″| (rad/rad²), max |ψ‴| (rad/rad³) over the turn.
    """

    arm: float | None
    slot: tuple[float, float] | None
    clearance: float
    clearance_between: str
    peak_rates: tuple[float, float, float]

    def scaled(self, scale: float) -> Buildability:
        """The figures of the six-bar scaled by ``scale`` (lengths; rates are unchanged)."""
        return Buildability(
            None if self.arm is None else self.arm * scale,
            None if self.slot is None else (self.slot[0] * scale, self.slot[1] * scale),
            self.clearance * scale,
            self.clearance_between,
            self.peak_rates,
        )

    def dynamics(self, rpm: float) -> tuple[float, float, float]:
        """Peak output angular velocity (rad/s), acceleration (rad/s²) and jerk (rad/s³) at a
        constant crank speed of ``rpm`` rev/min."""
        w = 2.0 * math.pi * rpm / 60.0
        d1, d2, d3 = self.peak_rates
        return d1 * w, d2 * w * w, d3 * w**3


def output_rates(dpsi2: np.ndarray) -> np.ndarray:
    """ψ‴ (rad/rad³) from ψ″ sampled on a uniform periodic crank grid (last axis): the spectral
    derivative (FFT), the Nyquist term dropped (its derivative is not real)."""
    n = dpsi2.shape[-1]
    k = np.fft.rfftfreq(n, d=1.0 / n)  # integer wave numbers: the period is 2π
    spectrum = np.fft.rfft(dpsi2, axis=-1) * (1j * k)
    if n % 2 == 0:
        spectrum[..., -1] = 0.0
    return np.fft.irfft(spectrum, n=n, axis=-1)


#: The pairs :func:`clearances` measures, in the order of its ``which`` index.
CLEARANCE_PAIRS = (
    "joint A / B0",
    "joint A / D",
    "joint B / A0",
    "joint B / D",
    "joint P / A0",
    "joint P / B0",
    "joint P / D",
    "joint Q / A0",
    "joint Q / B0",
    "rod P-Q / A0",
    "rod P-Q / B0",
    "rod P-Q / D",
    "rocker D-Q / A0",
    "rocker D-Q / B0",
    "slot / A0",
    "slot / B0",
)


def clearances(
    batch: SixBars, motion: SixBarMotion, every: int = 1
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Torque arm, clearance and slot use of every six-bar of ``batch`` as arrays, from
    ``motion`` (any order, a uniform crank grid over the whole turn, shape (N, M)), on every
    ``every``-th sample (1: all; more is a cheaper estimate, as in synth.query.refine's loop).

    Returns
    -------
    reach : (N, M) float
        |P − D| at every sample (length; every ``every``-th): an RPR's torque arm is its row minimum.
    clearance : (N,) float
        Smallest joint/link-to-fixed-pivot distance over the samples (length).
    which : (N,) int
        Index into :data:`CLEARANCE_PAIRS` of the pair that sets it.
    rpr : (N,) bool
        Which rows are RPR (their arm is defined).
    """
    from synth.mechanism.clearance_kernel import pair_clearances  # numba: imported on first use

    n, m = motion.psi.shape
    A, B, P, Q = (
        np.broadcast_to(x, (n, m)) for x in (motion.fourbar.A, motion.fourbar.B, motion.z[0], motion.moving_pivot)
    )
    # the pairs in the order of CLEARANCE_PAIRS: joints to pivots they are not pinned to,
    # output links to pivots off them; a dyad kind's pairs on its rows only (inf elsewhere)
    smallest, reach = pair_clearances(A, B, P, Q, motion.psi, batch.d, batch.pivot, batch.rpr, every)
    which = smallest.argmin(axis=1)
    return reach, smallest[np.arange(n), which], which, batch.rpr


def buildability(batch: SixBars, motion: SixBarMotion) -> list[Buildability]:
    """The figures of every six-bar of ``batch`` from ``motion`` (an order-2 simulation on a
    uniform crank grid over the whole turn, shape (N, M))."""
    reach, clearance, which, rpr = clearances(batch, motion)
    names = CLEARANCE_PAIRS

    d1, d2 = motion.dpsi[0], motion.dpsi[1]
    d3 = output_rates(d2)
    peaks = np.stack([np.abs(d1).max(axis=1), np.abs(d2).max(axis=1), np.abs(d3).max(axis=1)], axis=1).tolist()
    # reductions for the whole batch, then Python floats row by row (a per-row ``min`` costs more
    # than the kernel for a batch of a hundred)
    arm, far = reach.min(axis=1).tolist(), reach.max(axis=1).tolist()
    return [
        Buildability(
            arm=arm[k] if slotted else None,
            slot=(arm[k], far[k]) if slotted else None,
            clearance=c,
            clearance_between=names[w],
            peak_rates=tuple(peaks[k]),
        )
        for k, (c, w, slotted) in enumerate(zip(clearance.tolist(), which.tolist(), rpr.tolist()))
    ]
