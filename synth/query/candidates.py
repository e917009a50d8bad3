"""Synthesis requests and ranked candidate six-bars (pure: no database, no I/O).

A :class:`Request` is what the designer asks (angles in radians here, degrees at the CLI); a
:class:`Candidate` is a six-bar in the user's units with its figures from the exact
simulation. Ranking: non-dominated sorting (Pareto layers) on five objectives — dwell
accuracy |dwell − requested|, output deviation over the requested dwell window, the worst
transmission angle (four-bar or output, larger is better), compactness (footprint area
over crank²) and the output's peak angular acceleration (peak |ψ″|, rad/rad²) — then, inside
a layer, a score: the sum of the five objectives each scaled to a designer's unit (the dwell
tolerance, the dwell band, 45° of transmission, 100 crank², 1 rad/rad² — 39.5 rad/s² at
60 rpm).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from synth.kinds import OutputTag
from synth.mechanism.buildability import clearances
from synth.mechanism.figures import SixBarFigures, link_ratios
from synth.mechanism.sample_ranges import sliding_extremes
from synth.mechanism.sixbar import SixBar, SixBars, crank_grid, simulate
from synth.query.pareto import pareto_layers

__all__ = [
    "DEGREE_FIELDS",
    "SAMPLES",
    "Candidate",
    "Request",
    "output_may_meet",
    "rank",
    "screen",
    "within_band",
]

#: The --output choices: an output tag, or any single-dwell one.
OUTPUTS = (OutputTag.RPR.value, OutputTag.RRR.value, "any")

#: Crank samples of the exact simulation (0.5°); the figures refine beyond it.
SAMPLES = 720
#: The shortest dwell a request may ask for (rad): its deviation window must hold at least two
#: samples of the simulation's crank grid.
_SHORTEST_DWELL = math.radians(720.0 / SAMPLES)
#: The fields :meth:`Request.from_degrees` takes in degrees (the others keep their units).
DEGREE_FIELDS = frozenset({"dwell", "dwell_tol", "swing", "swing_tol", "band", "min_transmission", "step"})


@dataclass(frozen=True, slots=True, kw_only=True)
class Request:
    """A dwell request, built with keywords. Angles in radians, lengths in the user's unit
    (crank = ``crank``). The field defaults are the only definition of the request's defaults
    (``dwell query`` shows them in degrees in its ``--help``).

    ``band`` is the total width of the output band that counts as standing still; ``swing``
    (the output's whole swing, ±``swing_tol``) is required, for one dwell and for two; two
    dwells may also name the ``step`` between the rests, and are two rests only with motion
    between them (:func:`~synth.mechanism.output_range.rests_separated`, at ``swing_tol``)."""

    dwell: float
    dwell_tol: float = math.radians(2.0)
    swing: float | None = None
    swing_tol: float = math.radians(0.5)
    output: str = "any"
    dwells: int = 1
    band: float = math.radians(0.1)
    crank: float = 1.0
    min_transmission: float = math.radians(30.0)
    max_link_ratio: float = 10.0
    top: int = 10
    #: Refine the returned six-bars by a local optimisation with exact simulation in the loop
    #: (synth.query.refine), and the nearest misses when nothing meets the request.
    refine: bool = True
    #: Search every stored segment at every tolerance level (synth.query.search) instead of
    #: the sample of segments nearest the request: the complete answer, and slower.
    complete: bool = False
    #: Buildability (synth.mechanism.buildability): the RPR slider's smallest distance to its slot pivot
    #: and every joint's/output link's to a fixed pivot, in crank lengths; the output's peak
    #: angular acceleration (rad/s², None: no limit) at ``rpm`` rev/min of the crank.
    min_arm: float = 0.2
    min_clearance: float = 0.1
    rpm: float = 60.0
    max_accel: float | None = None
    #: Two dwells: the output's turn between its two rests (rad, None: any), ±``swing_tol``.
    step: float | None = None
    #: Manufacturing tolerance (the user's length unit, 0: none): each candidate also gets the
    #: 95th percentile of its output deviation over draws made within ±tolerance
    #: (synth.mechanism.tolerance), and the ranking uses it in place of the nominal deviation.
    tolerance: float = 0.0

    @classmethod
    def from_degrees(cls, **given: float | int | str | bool | None) -> Request:
        """The request of keyword fields in the command's units: the angles (``DEGREE_FIELDS``)
        in degrees, the rest as the fields have them; None takes the field's default.

        Raises
        ------
        ValueError
            A value out of its range, naming the field in backticks (:meth:`__post_init__`).
        TypeError
            A name that is not a field, or no ``dwell``.
        """
        return cls(
            **{
                name: math.radians(value) if name in DEGREE_FIELDS else value
                for name, value in given.items()
                if value is not None
            }
        )

    def __post_init__(self) -> None:
        """Every field within its range; a ValueError names the fields in backticks
        (`` `swing_tol` ``), which a command turns into its own options' names."""
        bad = ValueError
        if not (math.isfinite(self.dwell) and 0 < self.dwell < 2 * math.pi):
            raise bad(f"`dwell` must be between 0 and 360 degrees (exclusive), got {math.degrees(self.dwell):g}")
        # the deviation window must hold at least two samples of the simulation's crank grid
        if self.dwell < _SHORTEST_DWELL:
            raise bad(
                f"`dwell` must be at least {720.0 / SAMPLES:g}° (the simulation samples the turn "
                f"every {360.0 / SAMPLES:g}°), got {math.degrees(self.dwell):g}"
            )
        if not (math.isfinite(self.dwell_tol) and 0 <= self.dwell_tol < 2 * math.pi):
            raise bad(f"`dwell_tol` must be between 0 and 360 degrees, got {math.degrees(self.dwell_tol):g}")
        if self.swing is not None and not (math.isfinite(self.swing) and 0 < self.swing < math.pi):
            raise bad(f"`swing` must be between 0 and 180 degrees (exclusive), got {math.degrees(self.swing):g}")
        if not (math.isfinite(self.swing_tol) and 0 <= self.swing_tol < math.pi):
            raise bad(f"`swing_tol` must be between 0 and 180 degrees, got {math.degrees(self.swing_tol):g}")
        if self.output not in OUTPUTS:
            raise bad(f"`output` must be one of {', '.join(OUTPUTS)}, got {self.output!r}")
        if self.dwells not in (1, 2):
            raise bad(f"`dwells` must be 1 or 2, got {self.dwells}")
        if self.swing is None:
            raise bad("`swing` is required (the output's whole swing, for one dwell per turn and for two)")
        if self.dwells == 2 and self.output == OutputTag.RRR:
            raise bad("two dwells per turn come from a double Ball point with an RPR output; use `output` rpr or any")
        if self.dwells * self.dwell >= 2 * math.pi:
            raise bad(f"{self.dwells} dwell(s) of {math.degrees(self.dwell):g} degrees do not fit in one turn")
        if not (math.isfinite(self.band) and 0 < self.band < math.pi):
            raise bad(f"`band` must be between 0 and 180 degrees (exclusive), got {math.degrees(self.band):g}")
        if not (math.isfinite(self.crank) and self.crank > 0):
            raise bad(f"`crank` must be a positive length, got {self.crank:g}")
        if not (math.isfinite(self.min_transmission) and 0 <= self.min_transmission < math.pi / 2):
            raise bad(f"`min_transmission` must be in [0, 90) degrees, got {math.degrees(self.min_transmission):g}")
        if not (math.isfinite(self.max_link_ratio) and self.max_link_ratio >= 1):
            raise bad(f"`max_link_ratio` must be at least 1, got {self.max_link_ratio:g}")
        if self.top < 1:
            raise bad(f"`top` must be at least 1, got {self.top}")
        for name, value in (("min_arm", self.min_arm), ("min_clearance", self.min_clearance)):
            if not (math.isfinite(value) and value >= 0):
                raise bad(f"`{name}` must be a length in cranks >= 0, got {value:g}")
        if not (math.isfinite(self.rpm) and self.rpm > 0):
            raise bad(f"`rpm` must be > 0, got {self.rpm:g}")
        if self.step is not None and not (math.isfinite(self.step) and 0 < self.step < math.pi and self.dwells == 2):
            raise bad(
                "`step` (the turn between two rests) must be between 0 and 180 degrees (exclusive) and needs `dwells` 2"
            )
        if not (math.isfinite(self.tolerance) and self.tolerance >= 0):
            raise bad(f"`tolerance` must be a length >= 0, got {self.tolerance:g}")
        if self.step is not None and self.step - self.swing_tol > self.swing + self.swing_tol:
            raise bad(
                f"`step` {math.degrees(self.step):g} is more than `swing` {math.degrees(self.swing):g} "
                f"(± `swing_tol`): both rests lie within the output's swing"
            )
        if self.max_accel is not None and not (math.isfinite(self.max_accel) and self.max_accel > 0):
            raise bad(f"`max_accel` must be > 0 rad/s^2, got {self.max_accel:g}")


@dataclass(frozen=True, slots=True)
class Candidate:
    """A ranked six-bar: geometry in the user's units (crank = request.crank), its figures
    from the exact simulation (lengths scaled likewise), and where it came from."""

    id: str
    segment_id: int
    sixbar: SixBar
    figures: SixBarFigures
    rank: int = 0
    #: RRR: where the moving pivot Q rests during the dwell (the fitted arc's centre; for a
    #: refined six-bar, Q at the middle of its first dwell)
    dwell_position: complex | None = None
    #: A refined six-bar (synth.query.refine): the figures of the six-bar it was refined from (same
    #: units as ``figures``); None if it was not refined or refinement kept it unchanged.
    refined_from: SixBarFigures | None = None
    #: With a request's tolerance: the 95th percentile of the output deviation (rad, the
    #: largest of its dwells') over six-bars made within it (synth.mechanism.tolerance); None without a
    #: tolerance, or where more than 5 % of those six-bars do not assemble.
    toleranced_deviation: float | None = None


def screen(request: Request, sixbars: SixBars, samples: int = 720) -> np.ndarray:
    """Which six-bars may meet ``request``: a necessary test on one order-0 simulation on the
    crank grid, so that the full figures (refined dwell ends, deviation windows, footprint)
    are computed only for those that pass.

    Each test is one a six-bar meeting the request cannot fail. With h the grid step and m
    the largest |Δ²ψ|/8 of the row — a bound on how far ψ strays between two samples —:
    it assembles everywhere and rocks; its sampled transmission angles are ≥ the minimum
    (the true minimum is lower still); its sampled swing lies within the swing tolerance
    widened by 2m; some ⌊(dwell − tol)/h⌋ − 1 consecutive samples lie within the band (the
    dwell holds that many); and no ⌈(dwell + tol)/h⌉ + 2 consecutive samples lie within the
    band narrowed by 2m (that would be a longer dwell than allowed). ``samples`` must be the
    grid the figures are computed on (the query's): the link ratio, clearance and torque arm
    are then tested as the figures have them (:func:`~synth.mechanism.figures.link_ratios`,
    :func:`~synth.mechanism.buildability.clearances`), which on another grid would not be bounds.
    """
    motion = simulate(sixbars, crank_grid(samples), order=0)
    psi = motion.psi
    ok = np.all(motion.status == 0, axis=1) & (np.abs(psi[:, -1] - psi[:, 0]) < math.pi)  # rocks, not revolves
    ok &= motion.transmission_fourbar.min(axis=1) >= request.min_transmission
    ok &= motion.transmission_output.min(axis=1) >= request.min_transmission
    ok &= output_may_meet(request, psi)
    # the figures' link ratio, clearance and torque arm are read off the positions of their
    # grid — this one: exact tests, not bounds
    reach, clear, _, rpr = clearances(sixbars, motion)
    ok &= (link_ratios(sixbars, motion) <= request.max_link_ratio) & (clear >= request.min_clearance)
    return ok & (~rpr | (reach.min(axis=1) >= request.min_arm))


def within_band(psi: np.ndarray, length: int, band: np.ndarray | float) -> np.ndarray:
    """Per row of ``psi`` (n, M), on a uniform full-turn grid: some run of ``length``
    consecutive samples lies within ``band`` (cyclic: ψ of a rocker is periodic): every
    window of the turn, read from the samples followed by the first ``length`` − 1 again."""
    turn = psi.shape[1]
    hi, lo = sliding_extremes(np.concatenate([psi, psi[:, : length - 1]], axis=1), 0, turn, length)
    return np.any(hi - lo <= np.reshape(band, (-1, 1)), axis=1)


def _stray(psi: np.ndarray) -> np.ndarray:
    """Per row, the largest |Δ²ψ|/8 over the (cyclic) samples: how far ψ strays between two
    samples (the parabola through three samples departs from its chord by Δ²ψ/8)."""
    return np.abs(np.roll(psi, -1, axis=1) - 2 * psi + np.roll(psi, 1, axis=1)).max(axis=1) / 8


def output_may_meet(request: Request, psi: np.ndarray) -> np.ndarray:
    """Tests no six-bar that meets ``request`` can fail, per row of its output angle ``psi``
    (n, M) sampled exactly on the uniform grid of M crank angles over the turn (h = 2π/M,
    continuous along the turn), m the row's stray between samples (:func:`_stray`): its
    sampled swing lies within the swing tolerance widened by 2m; a dwell of at least
    dwell − tol holds ⌊(dwell − tol)/h⌋ grid samples, so some run of one fewer of them lies
    within the band; and no ⌈(dwell + tol)/h⌉ + 2 consecutive samples lie within the band
    narrowed by 2m (that would be a longer dwell than allowed)."""
    ok = np.ones(psi.shape[0], bool)
    if request.swing is not None:
        swing = psi.max(axis=1) - psi.min(axis=1)
        ok &= (swing <= request.swing + request.swing_tol) & (
            swing + 2 * _stray(psi) >= request.swing - request.swing_tol
        )
    shortest, longest = dwell_runs(request, psi.shape[1])
    if shortest >= 2:
        ok &= within_band(psi, shortest, request.band)
    if longest < psi.shape[1]:
        ok &= ~within_band(psi, longest, request.band - 2 * _stray(psi))
    return ok


def dwell_runs(request: Request, samples: int) -> tuple[int, int]:
    """The run lengths :func:`output_may_meet` tests on a grid of ``samples`` over the turn
    (h = 2π/samples): ⌊(dwell − tol)/h⌋ − 1 samples that some run within the band must hold
    (tested from 2 on), and ⌈(dwell + tol)/h⌉ + 2 that none within the narrowed band may
    (tested below ``samples``)."""
    h = 2 * math.pi / samples
    return (
        math.floor((request.dwell - request.dwell_tol) / h) - 1,
        math.ceil((request.dwell + request.dwell_tol) / h) + 2,
    )


def objectives(request: Request, figures: list[SixBarFigures]) -> np.ndarray:
    """(n, 5) objectives to minimise: dwell error (rad), output deviation (rad), −worst
    transmission (rad), footprint / crank² (dimensionless), peak |ψ″| (rad/rad²: the output's
    peak angular acceleration over ω², the same ranking at any crank speed)."""
    rows = []
    for f in figures:
        err = max(abs(d.angle - request.dwell) for d in f.dwells) if f.dwells else math.pi
        dev = max(f.deviations) if f.deviations else 0.0
        mu = min(f.transmission_fourbar, f.transmission_output)
        accel = f.build.peak_rates[1] if f.build is not None else 0.0
        rows.append((err, dev, -mu, f.footprint / request.crank**2, accel))
    return np.array(rows, dtype=float).reshape(-1, 5)


def rank(request: Request, candidates: list[Candidate]) -> list[Candidate]:
    """Candidates in rank order (Pareto layer, then score, then id), ``rank`` set from 1."""
    if not candidates:
        return []
    # Rounded: the same six-bar's figures differ in the last bits with the batch it was
    # simulated in, and a mirror pair's are equal only to rounding; ties then fall to the id,
    # so a ranking does not depend on how the six-bars were batched.
    obj = objectives(request, [c.figures for c in candidates])
    if request.tolerance > 0:  # the deviation that survives the workshop; none survives: last
        obj[:, 1] = [math.pi if c.toleranced_deviation is None else c.toleranced_deviation for c in candidates]
    obj = np.round(obj, 10)
    layer = pareto_layers(obj)
    scale = np.array([max(request.dwell_tol, math.radians(0.5)), request.band, math.radians(45.0), 100.0, 1.0])
    score = (obj + np.array([0.0, 0.0, math.pi / 2, 0.0, 0.0])) / scale
    total = np.round(score.sum(axis=1), 10)
    order = sorted(range(len(candidates)), key=lambda i: (layer[i], total[i], candidates[i].id))
    return [dataclasses.replace(candidates[i], rank=r + 1) for r, i in enumerate(order)]
