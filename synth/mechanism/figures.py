"""Figures of whole six-bars: what a user is shown about a mechanism (:class:`SixBarFigures`),
all from its exact simulation (:func:`~synth.mechanism.sixbar.simulate`), never from the curvature
approximation.

:func:`sixbar_figures` simulates each six-bar on the crank grid and reads off the dwell(s)
within an output band and their output deviation over a requested dwell length (refined on
the exact path beyond the grid, :mod:`synth.mechanism.output_range`), the output swing and net turns,
the minimum transmission angles (sample minimum refined by a parabola), the link ratio, the
convex-hull footprint (shapely) and bounding box of the pivots and joint paths, the status
flags met over the turn and the buildability figures (:mod:`synth.mechanism.buildability`).
:func:`figures_with_dwell_bounds` gives the same figures but the dwell, and bounds on the dwell
from the grid alone (what a no-match diagnosis decides most six-bars by). Angles in radians,
lengths in the unit of the links, areas in length².
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from kinematics.fourbar import FourBarMotion
from kinematics.loop import sampled_extreme
from kinematics.status import Status
from synth.mechanism.buildability import Buildability, buildability, clearances
from synth.mechanism.link_ratio import link_ratio, segment_links
from synth.mechanism.output_range import (
    REST_LEAVE,
    Dwell,
    dwell_angle_bounds,
    dwell_intervals,
    output_deviation,
    output_swing,
    rests_separated,
)
from synth.mechanism.sixbar import ExactOutput, SixBar, SixBarMotion, SixBars, as_batch, crank_grid, simulate
from synth.types import C128, F64

__all__ = ["DwellBoundFigures", "SixBarFigures", "figures_with_dwell_bounds", "footprints", "sixbar_figures"]


@dataclass(frozen=True, slots=True)
class SixBarFigures:
    """What a user is shown about one six-bar, all from its exact simulation.

    Attributes
    ----------
    dwells : tuple of Dwell
        The longest (and, for a double dwell, the longest separated from it: two rests with
        motion between them, :func:`~synth.mechanism.output_range.rests_separated`) crank interval(s)
        on which the output stays within the band; (start, end, angle), rad.
    deviations : tuple of float
        Per dwell, the output deviation (peak-to-peak of ψ, rad) over a window of the
        requested dwell length placed around it (:func:`~synth.mechanism.output_range.output_deviation`); empty if no
        length was requested.
    swing : float
        max ψ − min ψ over the turn (rad).
    turns : int
        Net output revolutions per crank turn: ≠ 0 means the output revolves (not a rocker:
        reject).
    transmission_fourbar, transmission_output : float
        Minimum over the turn of the folded transmission angles (rad, [0, π/2]); 0 where the
        mechanism does not assemble.
    link_ratio : float
        Longest over shortest link length (:mod:`synth.mechanism.link_ratio`): crank a, the coupler as
        the ternary plate it is (b, |AP|, |BP|), rocker c, ground d and the dyad's links — RRR
        rocker L and rod ρ; RPR the slot length the rocker needs, max |P − D|.
    footprint : float
        Area of the convex hull of the fixed pivots A0, B0, D and the paths of A, B, P and (RRR)
        Q over the turn (length²).
    bounds : (xmin, ymin, xmax, ymax)
        Bounding box of the same points.
    status : int
        :class:`Status` flags met anywhere on the turn (OK = 0).
    build : Buildability or None
        Torque arm, slot used, clearance and output rate peaks (:mod:`synth.mechanism.buildability`).
    gaps : tuple of (float, float)
        Two dwells: from the end of each to the start of the other, the crank's turn (rad) and
        how far the output gets outside both rests' bands (rad); empty otherwise.
    """

    dwells: tuple[Dwell, ...]
    deviations: tuple[float, ...]
    swing: float
    turns: int
    transmission_fourbar: float
    transmission_output: float
    link_ratio: float
    footprint: float
    bounds: tuple[float, float, float, float]
    status: int
    build: Buildability | None = None
    gaps: tuple[tuple[float, float], ...] = ()

    def rests_apart(self, tol: float) -> bool:
        """Two dwells that are two rests: the crank turns at least 5° and the output leaves
        both bands by at least ``tol`` (rad, the swing tolerance) between them, each way round
        (:func:`~synth.mechanism.output_range.rests_separated`, the rule's one statement)."""
        if len(self.dwells) < 2 or len(self.gaps) < 2:
            return False
        return bool(rests_separated([g for g, _ in self.gaps], [x for _, x in self.gaps], tol))

    @property
    def revolving(self) -> bool:
        return self.turns != 0

    @property
    def step(self) -> float | None:
        """The output's turn between its two rests (rad, ≥ 0), or None with fewer than two dwells."""
        if len(self.dwells) < 2:
            return None
        return abs(self.dwells[1].rest - self.dwells[0].rest)

    @property
    def assembled(self) -> bool:
        return not (self.status & Status.NOT_ASSEMBLABLE)

    @property
    def acceptable(self) -> bool:
        """Assembles over the whole turn without a toggle and the output is a rocker."""
        return self.status == 0 and self.turns == 0


def sixbar_figures(
    sixbar: SixBar | SixBars,
    *,
    band: float,
    dwell_length: float | None = None,
    dwells: int = 1,
    samples: int = 720,
    motion: SixBarMotion | None = None,
    footprint: bool = True,
    leave: float = REST_LEAVE,
) -> SixBarFigures | list[SixBarFigures]:
    """Figures of one six-bar (or a batch, vectorised) from its exact simulation.

    Parameters
    ----------
    sixbar : SixBar or SixBars
    band : float
        Total width (rad) of the output band that counts as a dwell.
    dwell_length : float, optional
        Requested dwell length (rad) for the output deviation(s).
    dwells : {1, 2}
        Number of dwells per turn sought (2 for a double Ball point RPR).
    samples : int
        Crank samples over the turn (720 = 0.5°); the ends and extremes are refined beyond it.
    motion : SixBarMotion, optional
        A simulation of ``sixbar`` on ``crank_grid(samples)`` with order 2, if already at hand.
    footprint : bool
        Compute the convex-hull footprint (shapely); False leaves it 0 (bounds are kept).
    leave : float
        Two dwells: how far (rad) the output must get outside both rests' bands between them
        for them to count as two (the request's swing tolerance;
        :func:`~synth.mechanism.output_range.rests_separated`).

    Returns
    -------
    SixBarFigures, or a list of them (one per row) for a batch.
    """
    if dwells not in (1, 2):
        raise ValueError(f"dwells must be 1 or 2, not {dwells!r}")
    batch, single, phi, motion, psi_at = _simulated(sixbar, samples, motion)
    N = len(batch)
    psi, dpsi = motion.psi, motion.dpsi
    found = dwell_intervals(phi, psi, band, count=dwells, psi_at=psi_at, dpsi1=dpsi[0], leave=leave)
    if dwell_length is not None:
        centre = 0.5 * (found.start + found.end)  # (N, C)
        dev, _ = output_deviation(
            phi,
            np.repeat(psi[:, None, :], dwells, axis=1),
            centre,
            dwell_length,
            psi_at=psi_at,
            dpsi1=np.repeat(dpsi[0][:, None, :], dwells, axis=1),
        )
    else:
        dev = np.zeros((N, 0))
    both = found.found.all(axis=1)
    out = [
        dataclasses.replace(
            f,
            dwells=tuple(found.dwells((k,))),
            deviations=tuple(float(x) for x, ok in zip(dev[k], found.found[k]) if ok),
            gaps=tuple(zip(found.gap[k].tolist(), found.leave[k].tolist())) if both[k] and dwells == 2 else (),
        )
        for k, f in enumerate(_figures_but_dwells(batch, phi, motion, psi_at, footprint))
    ]
    return out[0] if single else out


@dataclass(frozen=True, slots=True)
class DwellBoundFigures:
    """Per row of a batch of six-bars, as arrays of shape ``(N,)``: the figures a request's
    limits are checked on, each exactly as :func:`sixbar_figures` computes it, and bounds on
    the single dwell's angle from the grid (:func:`figures_with_dwell_bounds`).

    Attributes
    ----------
    swing, turns, transmission_fourbar, transmission_output, link_ratio, status :
        As in :class:`SixBarFigures` (rad, count, rad, rad, ratio, flags).
    rpr : bool
        Which rows are RPR (their torque arm is defined).
    arm : float
        RPR: :attr:`Buildability.arm`, the smallest |P − D| (length); the RRR rows' entries
        mean nothing.
    clearance : float
        :attr:`Buildability.clearance` (length).
    peak_accel : float
        max |ψ″| over the turn (rad/rad², :attr:`Buildability.peak_rates` [1]); zeros unless
        asked for.
    dwell_low, dwell_high : float
        Bounds on the dwell's angle (rad, :func:`~synth.mechanism.output_range.dwell_angle_bounds`).
    """

    swing: F64
    turns: np.ndarray
    transmission_fourbar: F64
    transmission_output: F64
    link_ratio: F64
    status: np.ndarray
    rpr: np.ndarray
    arm: F64
    clearance: F64
    peak_accel: F64
    dwell_low: F64
    dwell_high: F64

    @property
    def acceptable(self) -> np.ndarray:
        """:attr:`SixBarFigures.acceptable` per row."""
        return (self.status == 0) & (self.turns == 0)


def figures_with_dwell_bounds(
    sixbars: SixBars, *, band: float, samples: int = 720, accel: bool = False
) -> DwellBoundFigures:
    """What :func:`sixbar_figures` gives for a single dwell without refining the dwell's ends,
    as arrays: the figures a request's limits are checked on — each exactly as
    :func:`sixbar_figures` computes it; the peak output acceleration only with ``accel`` —
    and bounds (low, high) on the dwell's angle (rad,
    :func:`~synth.mechanism.output_range.dwell_angle_bounds`). Enough to decide most constraints of
    a six-bar far from a request at a fraction of the cost (the no-match diagnosis); no
    object per row, no bounding box, footprint or jerk."""
    batch, _, phi, motion, psi_at = _simulated(sixbars, samples, None)
    low, high = dwell_angle_bounds(phi, motion.psi, band, dpsi1=motion.dpsi[0])
    swing, turns, mu_fb, mu_out, status, ratio = _limit_figures(batch, phi, motion, psi_at)
    reach, clearance, _, rpr = clearances(batch, motion)
    return DwellBoundFigures(
        swing=swing,
        turns=turns,
        transmission_fourbar=mu_fb,
        transmission_output=mu_out,
        link_ratio=ratio,
        status=status,
        rpr=rpr,
        arm=reach.min(axis=1),
        clearance=clearance,
        peak_accel=np.abs(motion.dpsi[1]).max(axis=1) if accel else np.zeros(len(batch)),
        dwell_low=low,
        dwell_high=high,
    )


def _simulated(sixbar: SixBar | SixBars, samples: int, motion: SixBarMotion | None):
    """The batch, whether one six-bar was given, the crank grid, the order-2 motion on it
    (``motion`` checked, or simulated) and the exact ψ(φ) evaluator."""
    batch, single = as_batch(sixbar)
    phi = crank_grid(samples)
    N = len(batch)
    if motion is None:
        motion = simulate(batch, phi, order=2)
    elif single:
        motion = _as_batch_motion(motion)
    if motion.psi.shape != (N, samples) or len(motion.dpsi) < 2:
        raise ValueError("motion must be an order-2 simulation of these six-bars on crank_grid(samples)")

    return batch, single, phi, motion, ExactOutput(batch)


def _limit_figures(batch: SixBars, phi: F64, motion: SixBarMotion, psi_at) -> tuple[F64, ...]:
    """Per row, the band-free figures a request's limits read besides the buildability's:
    swing and turns (:func:`output_swing`), the smallest transmission angles of the four-bar
    and the output (refined between samples; 0 where the loop does not assemble), the status
    flags over the turn and the link ratio."""
    swing, turns = output_swing(phi, motion.psi, dpsi=motion.dpsi, psi_at=psi_at)
    assembled = np.all(motion.assembled, axis=1)
    mu_fb = np.where(assembled, _refined_min(motion.transmission_fourbar), 0.0)
    mu_out = np.where(assembled, _refined_min(motion.transmission_output), 0.0)
    status = np.bitwise_or.reduce(motion.status, axis=1)
    return swing, turns, mu_fb, mu_out, status, link_ratios(batch, motion)


def _figures_but_dwells(batch: SixBars, phi: F64, motion: SixBarMotion, psi_at, footprint: bool) -> list[SixBarFigures]:
    """Per row, the figures that do not depend on the dwell band (dwells, deviations empty)."""
    N = len(batch)
    swing, turns, mu_fb, mu_out, status, ratio = _limit_figures(batch, phi, motion, psi_at)
    boxes = _bounding_boxes(batch, motion)
    area = _footprints(batch, motion) if footprint else np.zeros(N)
    build = buildability(batch, motion)
    return [
        SixBarFigures(
            dwells=(),
            deviations=(),
            swing=sw,
            turns=tu,
            transmission_fourbar=m1,
            transmission_output=m2,
            link_ratio=lr,
            footprint=ar,
            bounds=tuple(box),
            status=st,
            build=bu,
        )
        for sw, tu, m1, m2, lr, ar, box, st, bu in zip(
            swing.tolist(),
            turns.tolist(),
            mu_fb.tolist(),
            mu_out.tolist(),
            ratio.tolist(),
            area.tolist(),
            boxes,
            status.tolist(),
            build,
        )
    ]


def link_ratios(batch: SixBars, motion: SixBarMotion) -> F64:
    """Per row, the figures' ``link_ratio`` (:mod:`synth.mechanism.link_ratio`): longest over shortest
    of the crank, coupler plate (b, |AP|, |BP|), rocker, ground and the output dyad's links —
    an RRR's rocker and rod, an RPR's slot as its longest reach |P − D| over ``motion``'s
    samples (any order: positions only)."""
    return link_ratios_at(batch, np.max(np.abs(motion.z[0] - motion.pivot), axis=1))


def link_ratios_at(batch: SixBars, reach: F64) -> F64:
    """:func:`link_ratios` with each row's longest reach |P − D| over the turn given (length,
    (N,)): what an RPR's slot is as long as."""
    fixed = segment_links(batch.a, batch.b, batch.c, batch.d, batch.u, batch.v)
    dyad = np.stack([np.where(batch.rpr, reach, batch.rocker), np.where(batch.rpr, reach, batch.rod)], axis=1)
    return link_ratio(np.concatenate([fixed, dyad], axis=1))


def footprints(sixbars: SixBars, samples: int = 720) -> F64:
    """The footprint :func:`sixbar_figures` reports (convex-hull area, length²), alone: for
    figures computed without it."""
    return _footprints(sixbars, simulate(sixbars, crank_grid(samples), order=0))


def _outline(batch: SixBars, motion: SixBarMotion, every: int = 1) -> C128:
    """Per row, the fixed pivots A0, B0, D and every ``every``-th sample of the paths of A, B,
    P and (RRR) Q: what the footprint and bounds are taken over."""
    return np.concatenate(_outline_parts(batch, motion, every), axis=1)


def _outline_parts(batch: SixBars, motion: SixBarMotion, every: int = 1) -> list[C128]:
    """The parts of :func:`_outline`, each ``(N, k)``: the fixed pivots, then the four paths."""
    N = len(batch)
    fixed = np.stack([np.zeros(N, complex), batch.d.astype(complex), batch.pivot], axis=1)
    paths = [
        motion.fourbar.A,
        motion.fourbar.B,
        motion.z[0],
        np.where(batch.rpr[:, None], motion.z[0], motion.moving_pivot),
    ]
    return [fixed] + [np.broadcast_to(p, motion.psi.shape)[:, ::every] for p in paths]


def _bounding_boxes(batch: SixBars, motion: SixBarMotion) -> list[list[float]]:
    """Per row, (xmin, ymin, xmax, ymax) of :func:`_outline`: the same extremes, part by part
    (no concatenated copy of every path)."""
    parts = _outline_parts(batch, motion)
    low = [np.minimum.reduce([getattr(p, axis).min(axis=1) for p in parts]) for axis in ("real", "imag")]
    high = [np.maximum.reduce([getattr(p, axis).max(axis=1) for p in parts]) for axis in ("real", "imag")]
    return np.stack(low + high, axis=1).tolist()


def _footprints(batch: SixBars, motion: SixBarMotion) -> F64:
    # Every other sample: the hull of a path sampled at 1° misses at most the sagitta of a
    # 1° chord (~4e-5 of the area for a circle), and halves the GEOS time.
    return _hull_areas(_outline(batch, motion, every=2))


def _as_batch_motion(motion: SixBarMotion) -> SixBarMotion:
    """A single six-bar's motion (shape (M,)) viewed as a batch of one (shape (1, M))."""
    if motion.psi.ndim == 2:
        return motion
    fb = motion.fourbar
    fb1 = FourBarMotion(
        *(np.asarray(x)[None] if np.ndim(x) else np.asarray(x) for x in (fb.a, fb.b, fb.c, fb.d, fb.phi, fb.branch)),
        fb.e_theta[None],
        tuple(x[None] for x in fb.dtheta),
        tuple(x[None] for x in fb.dgamma),
        fb.status[None],
    )
    return SixBarMotion(
        np.asarray(motion.phi)[None],
        fb1,
        tuple(x[None] for x in motion.z),
        np.asarray(motion.pivot).reshape(1, 1),
        motion.moving_pivot[None],
        motion.psi[None],
        tuple(x[None] for x in motion.dpsi),
        motion.transmission_fourbar[None],
        motion.transmission_output[None],
        motion.status[None],
    )


def _refined_min(x: F64) -> F64:
    """Row minimum of a smooth periodic sample sequence, refined by the parabola through the
    minimum sample and its two cyclic neighbours (never above the sample minimum)."""
    value, _ = sampled_extreme(x, -1)
    return np.clip(value, 0.0, None)


def _hull_areas(points: C128) -> F64:
    """Convex hull area of each row of points (shapely, vectorised in GEOS). Each row is
    passed as one line string: same hull as the point set, and GEOS builds line strings from
    a coordinate array some hundred times faster than multipoints."""
    import shapely

    coords = np.stack([points.real, points.imag], axis=-1)
    return np.asarray(shapely.area(shapely.convex_hull(shapely.linestrings(coords))), dtype=float)
