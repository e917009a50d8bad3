"""Output dyads fitted to a dwell segment of a coupler curve (docs/curvature.md §4).

* **RPR** for a straight segment: the slot pivot D on the segment's line, beyond the stretch the
  coupler point covers during the dwell, at the distance that gives the requested swing of
  ψ = arg(P − D) over the turn (:func:`fit_rpr`); for a double Ball point, D at the
  intersection of the two lines (:func:`rpr_double`).
* **RRR** for a circular segment (centre C₀, radius ρ): rod |PQ| = ρ, Q at C₀ during the dwell,
  rocker D–Q with |DQ| = |D − C₀|; D = C₀ + L·e^{iα} placed to give the requested swing with
  the best minimum transmission angle (:func:`fit_rrr`).

Inputs are in crank-normalised units (a = 1) and radians; the caller scales by the user's
crank length afterwards. Paths are the exact coupler-point samples over one crank turn on a
uniform grid (:func:`synth.mechanism.sixbar.crank_grid`). Every function is vectorised over a leading
batch of segments (``(...,)`` segment parameters against ``(..., M)`` paths); results are struct
of arrays with one trailing axis of candidates, and ``found`` masks the valid ones. The swing is
solved to ``SWING_TOL`` on the path samples with the extremes refined between samples
(parabola through three samples); :func:`synth.mechanism.sixbar.simulate` then gives the exact figures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinematics.loop import line_intersection
from kinematics.status import Status
from synth.mechanism.output_range import grid_step
from synth.mechanism.sixbar import OutputDyad
from synth.types import C128, F64

__all__ = [
    "DoubleRprPivot",
    "RprFit",
    "RrrFit",
    "RrrTerms",
    "SWING_MAX_ITER",
    "SWING_TOL",
    "fit_rpr",
    "fit_rrr",
    "pivots_around",
    "rpr_double",
]


#: |swing − requested| (rad) below which a fitted dyad counts as achieving the swing.
SWING_TOL = 1e-9
_TWO_PI = 2.0 * math.pi
#: Iteration cap of the swing solve (the compiled `solve_rpr`/`solve_rrr`), with SWING_TOL.
SWING_MAX_ITER = 60
#: Samples over the turn of the first (coarse) stage of the swing solve.
_SOLVE_SAMPLES = 180


# --------------------------------------------------------------------------------------------
# Shared pieces
# --------------------------------------------------------------------------------------------


def _rows(path_z: ArrayLike, *params: ArrayLike) -> tuple[tuple[int, ...], C128, list[np.ndarray]]:
    """Flatten a batch: (leading shape, path (R, M), parameters (R,)). The leading shape is the
    broadcast of the path's leading axes and the parameters' shapes."""
    z = np.asarray(path_z, dtype=complex)
    if z.ndim < 1:
        raise ValueError("path_z must hold the coupler-point samples over the turn, shape (..., M)")
    if not np.all(np.isfinite(z)):
        raise ValueError("path_z must be finite")
    arrays = [np.asarray(x) for x in params]
    lead = np.broadcast_shapes(z.shape[:-1], *(x.shape for x in arrays))
    R = int(np.prod(lead, dtype=np.int64))
    out = []
    for arr in arrays:
        if not np.all(np.isfinite(arr)):
            raise ValueError("segment parameters must be finite")
        out.append(np.broadcast_to(arr, lead).reshape(R))
    return lead, np.broadcast_to(z, lead + z.shape[-1:]).reshape(R, -1), out


def _mid_sample(phi0: float, h: float, m: int, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """The sample nearest to the middle of the crank interval [start, end] (cyclic; end may pass
    2π), per row (R,)."""
    if np.any(end - start < 0):
        raise ValueError("dwell interval must have end >= start (radians, end may pass 2*pi)")
    return np.mod(np.rint((0.5 * (start + end) - phi0) / h).astype(np.int64), m)


def _dwell_mask(phi0: float, h: float, m: int, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Samples inside the crank interval [start, end] (cyclic; end may pass 2π), per row
    (R, M); an interval shorter than a step keeps its :func:`_mid_sample`."""
    mid = _mid_sample(phi0, h, m, start, end)
    phi = phi0 + h * np.arange(m)
    span = end - start
    rel = np.mod(phi[None, :] - start[:, None], _TWO_PI)
    mask = (rel <= span[:, None] + 1e-12) | (span[:, None] >= _TWO_PI)
    mask[np.arange(mask.shape[0]), mid] = True
    return mask


def _solve_two_stage(solve, path, lo, hi, u0, target, active):
    """S(u) = target solved by safeguarded Newton on [lo, hi] for every dyad (Numerical
    Recipes' ``rtsafe``, compiled: :func:`synth.mechanism.dyad_kernel.solve_rrr`, ``solve_rpr``), on
    every STRIDE-th sample first (cheap iterations), then polished on the full path from there
    (Newton needs one or two more steps). ``solve(path, lo, hi, u0, target, active,
    check_far)`` runs it over the flat dyads; with ``check_far`` the far end ``hi`` is
    evaluated first: a dyad that falls short of the swing even there has no root (and
    bisection would only crawl towards it). Returns (u, S, converged) of ``u0``'s shape, S = 0
    where not converged."""
    shape = np.shape(u0)

    def flat(x, dtype=float):
        return np.ascontiguousarray(np.broadcast_to(x, shape), dtype=dtype).ravel()

    lo, hi, target, u, active = flat(lo), flat(hi), flat(target), flat(u0), flat(active, np.bool_)
    stride = max(1, path.shape[-1] // _SOLVE_SAMPLES)
    if stride > 1:
        u, _, active = solve(path[:, ::stride], lo, hi, u, target, active, True)
    u, S, converged = solve(path, lo, hi, u, target, active, stride == 1)
    return u.reshape(shape), S.reshape(shape), converged.reshape(shape)


# --------------------------------------------------------------------------------------------
# RPR
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class RprFit:
    """Slot pivots fitted to straight segments, struct of arrays of shape ``(..., 2)``.

    Candidate 0 lies behind the start of the stretch (D at t < stretch), candidate 1 beyond
    its end (t > stretch), t measured along the line direction from ``line_point``.

    Attributes
    ----------
    pivot : complex128
        Slot pivot D (fixed frame, crank units); a placeholder on the line where not found.
    position : float64
        Signed position t of D along the line (crank units).
    swing : float64
        Swing of ψ = arg(P − D) over the turn on the path samples (rad).
    clearance : float64
        min |P − D| over the turn (crank units).
    found : bool
        The pivot achieves the swing to ``SWING_TOL``, the output does not revolve and the
        path keeps the requested clearance from D.
    """

    pivot: C128
    position: F64
    swing: F64
    clearance: F64
    found: NDArray[np.bool_]

    def dyads(self, index: tuple[int, ...] = ()) -> list[OutputDyad]:
        """The found pivots of one segment (``index`` into the leading shape) as RPR dyads."""
        return [
            OutputDyad.rpr(complex(self.pivot[index + (j,)]))
            for j in range(self.found.shape[-1])
            if self.found[index + (j,)]
        ]


def fit_rpr(
    line_point: ArrayLike,
    line_direction: ArrayLike,
    phi: ArrayLike,
    path_z: ArrayLike,
    interval: tuple[ArrayLike, ArrayLike],
    swing: ArrayLike,
    *,
    clearance: float = 0.1,
) -> RprFit:
    """Slot pivots on a straight segment's line that give the requested output swing.

    Parameters
    ----------
    line_point : complex, (...,)
        A point P₀ of the fitted line (fixed frame, crank units).
    line_direction : float, (...,)
        Direction angle δ of the line (rad).
    phi : (M,) float
        Uniform full-turn crank grid of the path samples (:func:`synth.mechanism.sixbar.crank_grid`).
    path_z : complex, (..., M)
        Coupler-point path over the turn.
    interval : (start, end)
        Dwell crank interval (rad, counter-clockwise, end may pass 2π), each float or (...,).
    swing : float or (...,)
        Requested swing of ψ over the turn (rad), in (0, π).
    clearance : float
        Smallest distance (crank units) D must keep from the stretch's ends and from the whole
        path (the pin and its block must not run over the pivot).

    Returns
    -------
    RprFit
        Shape ``(..., 2)``: one candidate per side of the stretch.

    Notes
    -----
    In the line's frame (t along δ, n across), D = t_D on the axis and
    ψ = δ + arg(P − D); the stretch [t_lo, t_hi] is the projection of the dwell samples. On
    the side σ = ±1, t_D = t_end + σ/u with u ∈ (0, 1/clearance]: the swing S(u) rises from
    0 at u = 0 (D at infinity, S ≈ u·W with W the path's width across the line, which gives
    the first guess) and is solved by safeguarded Newton, with
    ∂ψ/∂t_D = Im(−1/(P − D)) = n/|P − D|² at the extreme samples (envelope theorem).
    The angle is measured with its cut along the line beyond D, away from the stretch; a path
    that crosses that ray (the output would revolve or swing past π) counts as too large a
    swing.
    """
    phi0, h, m = grid_step(phi)
    start, end = interval
    lead, z, (P0, delta, s0, s1, target) = _rows(path_z, line_point, line_direction, start, end, swing)
    if z.shape[1] != m:
        raise ValueError(f"path_z has {z.shape[1]} samples, the crank grid {m}")
    P0 = P0.astype(complex)
    target = target.astype(float)
    if np.any(target <= 0) or np.any(target >= math.pi):
        raise ValueError("RPR swing must be in (0, pi) radians")
    if not clearance > 0:
        raise ValueError("clearance must be > 0")
    R = z.shape[0]
    e = np.exp(1j * delta.astype(float))
    w = (z - P0[:, None]) * np.conj(e)[:, None]
    t, n = w.real, w.imag
    mask = _dwell_mask(phi0, h, m, s0.astype(float), s1.astype(float))
    t_lo = np.where(mask, t, np.inf).min(axis=1)
    t_hi = np.where(mask, t, -np.inf).max(axis=1)
    sigma = np.array([-1.0, 1.0])
    t_end = np.stack([t_lo, t_hi], axis=1) + sigma * clearance  # (R, 2)
    width = n.max(axis=1) - n.min(axis=1)

    # Flat rows (segment, side).
    row_of = np.repeat(np.arange(R), 2)
    side = np.tile(sigma, R)
    t_end_f = t_end.ravel()

    def solve(path_tn, lo, hi, u0, target, active, check_far):
        from synth.mechanism.dyad_kernel import solve_rpr  # numba: imported on first use

        # the swing and ∂S/∂u, ∂ψ/∂t_D = Im(−1/(P − D)) at the extreme samples
        t_s, n_s = np.ascontiguousarray(path_tn.real), np.ascontiguousarray(path_tn.imag)
        return solve_rpr(
            t_s, n_s, row_of, side, t_end_f, lo, hi, u0, target, active, check_far, SWING_TOL, SWING_MAX_ITER
        )

    target2 = np.broadcast_to(target[:, None], (R, 2))
    u0 = target2 / np.maximum(width, 1e-12)[:, None]
    u_max = np.full((R, 2), 1.0 / clearance)
    u, S, conv = _solve_two_stage(solve, w, np.zeros((R, 2)), u_max, u0, target2, np.ones((R, 2), bool))
    tD = t_end + sigma / u
    D = P0[:, None] + tD * e[:, None]
    dist = np.abs(z[:, None, :] - D[..., None]).min(axis=-1)
    found = conv & (dist >= clearance)
    shape = lead + (2,)
    return RprFit(D.reshape(shape), tD.reshape(shape), S.reshape(shape), dist.reshape(shape), found.reshape(shape))


@dataclass(frozen=True, slots=True)
class DoubleRprPivot:
    """Slot pivot at the intersection of the two lines of a double Ball point, ``(...,)``.

    Attributes
    ----------
    pivot : complex128
        Intersection D of the two lines (placeholder: the midpoint of the two line points
        where there is none).
    status : uint16
        ``Status.AT_INFINITY`` where the lines are (nearly) parallel or meet farther than
        ``max_distance`` from the line points: no pivot.
    """

    pivot: C128
    status: NDArray[np.uint16]

    @property
    def found(self) -> NDArray[np.bool_]:
        return self.status == 0

    def dyad(self, index: tuple[int, ...] = ()) -> OutputDyad | None:
        """The RPR dyad of one double Ball point, or None where there is no pivot."""
        return OutputDyad.rpr(complex(self.pivot[index])) if self.found[index] else None


def rpr_double(
    line1: tuple[ArrayLike, ArrayLike], line2: tuple[ArrayLike, ArrayLike], *, max_distance: float = 1e3
) -> DoubleRprPivot:
    """Slot pivot of a double Ball point: the intersection of its two straight-line fits.

    Parameters
    ----------
    line1, line2 : (point, direction)
        Each line as a point (complex, crank units) and a direction angle (rad), arrays
        broadcast together.
    max_distance : float
        An intersection farther than this (crank units) from either line point counts as
        none (a slot pivot a thousand cranks away is no mechanism).

    Notes
    -----
    P₁ + t₁e₁ = P₂ + t₂e₂ (:func:`kinematics.loop.line_intersection`); |sin(δ₁ − δ₂)| below
    ``kinematics.loop.PARALLEL_EPS`` is parallel. With D there, ψ = arg(P − D) is constant along both
    straight stretches: two dwells per turn (docs/curvature.md §4).
    """
    p1, d1 = (np.asarray(x) for x in line1)
    p2, d2 = (np.asarray(x) for x in line2)
    p1, p2 = p1.astype(complex), p2.astype(complex)
    d1, d2 = d1.astype(float), d2.astype(float)
    for x in (p1, p2, d1, d2):
        if not np.all(np.isfinite(x)):
            raise ValueError("line points and directions must be finite")
    e1 = np.exp(1j * d1)
    hit = line_intersection(p1, e1, p2, np.exp(1j * d2))
    D = p1 + hit.t1 * e1
    far = (np.abs(D - p1) > max_distance) | (np.abs(D - p2) > max_distance)
    none = hit.parallel | far
    D = np.where(none, 0.5 * (p1 + p2), D)
    status = np.where(none, np.uint16(Status.AT_INFINITY), np.uint16(0)).astype(np.uint16)
    return DoubleRprPivot(D, status)


#: Output pivots around a fitted one (:func:`pivots_around`): distances as fractions of the
#: dyad's reach, nearest first, each in ``AROUND_DIRECTIONS`` directions.
AROUND_STEPS = (0.02, 0.05, 0.1, 0.2)
AROUND_DIRECTIONS = 8
#: The reach a pivot's distance is scaled by is at least this (crank lengths): a pivot close
#: to the stretch still moves by a visible amount.
AROUND_MIN_REACH = 0.5


def pivots_around(pivot: ArrayLike, reach: ArrayLike) -> C128:
    """Output pivots around a fitted ``pivot`` (...,): at distances ``AROUND_STEPS`` × ``reach``
    (at least ``AROUND_MIN_REACH``), in ``AROUND_DIRECTIONS`` directions each, nearest first,
    shape (..., steps × directions). The reach is the dyad's own length scale: an RPR's distance
    from its pivot to the stretch, a double line's mean distance from the crossing to its two
    stretches, an RRR's rocker.

    Off the fitted pivot, a slot no longer lies along the stretch (an RRR's moving pivot no
    longer rests at the arc's centre): the output creeps during the stretch, slower the nearer
    the pivot, so a dwell at a given output band shortens — how a dwell shorter than the fitted
    one is met (the family of every pivot, docs/complete-query.md §1)."""
    X = np.asarray(pivot, complex)
    reach = np.maximum(np.asarray(reach, float), AROUND_MIN_REACH)
    steps = np.repeat(np.asarray(AROUND_STEPS, float), AROUND_DIRECTIONS)
    turns = np.exp(2j * math.pi * np.tile(np.arange(AROUND_DIRECTIONS), len(AROUND_STEPS)) / AROUND_DIRECTIONS)
    return X[..., None] + reach[..., None] * steps * turns


# --------------------------------------------------------------------------------------------
# RRR
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class RrrFit:
    """RRR dyads fitted to circular segments, struct of arrays ``(..., keep)``, best first.

    Attributes
    ----------
    pivot : complex128
        Fixed pivot D = C₀ + L·e^{iα} (crank units).
    rocker : float64
        Rocker length L = |D − C₀| (crank units).
    rod : float64
        Rod length ρ (the segment's radius).
    branch : int8
        Dyad branch (:class:`synth.mechanism.sixbar.OutputDyad`): the one that puts Q at C₀ during the dwell.
    direction : float64
        α (rad), the direction from C₀ to D.
    swing : float64
        Swing of ψ over the turn on the path samples (rad).
    transmission : float64
        Minimum over the path samples of the folded rod–rocker transmission angle (rad).
    found : bool
        Achieves the swing to ``SWING_TOL`` with transmission ≥ the requested minimum over
        the whole turn on one branch (so it assembles everywhere and never toggles).

    The other fields of an entry that is not ``found`` mean nothing (for a row with no
    feasible rocker direction at all: pivot C₀, rod ρ, the rest 0).
    """

    pivot: C128
    rocker: F64
    rod: F64
    branch: NDArray[np.int8]
    direction: F64
    swing: F64
    transmission: F64
    found: NDArray[np.bool_]

    def dyads(self, index: tuple[int, ...] = ()) -> list[OutputDyad]:
        """The found dyads of one segment (``index`` into the leading shape), best first."""
        out = []
        for j in range(self.found.shape[-1]):
            k = index + (j,)
            if self.found[k]:
                out.append(
                    OutputDyad.rrr(
                        complex(self.pivot[k]), float(self.rocker[k]), float(self.rod[k]), int(self.branch[k])
                    )
                )
        return out


def fit_rrr(
    circle_center: ArrayLike,
    radius: ArrayLike,
    phi: ArrayLike,
    path_z: ArrayLike,
    interval: tuple[ArrayLike, ArrayLike],
    swing: ArrayLike,
    min_transmission: float,
    *,
    directions: int = 24,
    keep: int = 3,
) -> RrrFit:
    """RRR output dyads on a circular segment: swing as requested, best transmission angle.

    Parameters
    ----------
    circle_center : complex, (...,)
        Centre C₀ of the fitted arc (fixed frame, crank units): Q rests there during the dwell.
    radius : float, (...,)
        Arc radius ρ = rod length |PQ| (> 0).
    phi : (M,) float
        Uniform full-turn crank grid (:func:`synth.mechanism.sixbar.crank_grid`).
    path_z : complex, (..., M)
        Coupler-point path over the turn.
    interval : (start, end)
        Dwell crank interval (rad, end may pass 2π).
    swing : float or (...,)
        Requested output swing (rad), in (0, π).
    min_transmission : float
        Smallest acceptable folded transmission angle at Q over the turn (rad, in (0, π/2)).
    directions : int
        Rocker directions α of the coarse scan (then refined around the best ones).
    keep : int
        Candidates returned per segment (distinct local optima of α, best first; fewer are
        ``found`` where the scan has fewer feasible optima).

    Returns
    -------
    RrrFit
        Shape ``(..., keep)``.

    Notes
    -----
    With w = P − C₀ = (p + iq)·e^{iα} in the rocker's frame and u = 1/L, the law of cosines at
    Q gives the transmission angle in closed form, affine in u:

    .. math:: \\cos μ = (ρ² + L² − |P − D|²)/(2ρL) = A\\,u + B,\\quad
              A = (ρ² − |w|²)/(2ρ),\\quad B = p/ρ,

    so the u for which |cos μ| ≤ cos μ_min at every sample (which also guarantees assembly,
    and no toggle, hence one branch) is an interval found by linear bounds, and the minimum
    transmission angle at any u is arccos max|A u + B|. At u → 0 the rocker becomes a
    slider across e^{iα} through C₀: Q = C₀ + i·e^{iα}·s with s = q + branch·√(ρ² − p²), so the
    swing is ≈ u·(max s − min s). That estimate ranks a coarse set of directions and a finer
    set around the best ones (all closed form, on ``_RANK_SAMPLES`` samples); for the chosen
    directions the swing equation S(u) = swing is solved on the samples by safeguarded Newton
    (coarse samples first, then the full path), with
    ∂ψ/∂L = −Re((e^{iα} + e^{iψ})e^{−iχ})/(L sin(χ − ψ)) from differentiating the dyad loop
    P + ρe^{iχ} = C₀ + L e^{iα} + L e^{iψ} with respect to L. The ratio of the solved u to the
    estimate then corrects the estimate for a second, narrower scan and solve; the better of
    the two is kept. The direction found is within about a degree of transmission angle of
    the best (measured against a 720-direction scan). The branch puts Q to the left of P → D
    iff −q > 0 at the middle of the dwell (Q = C₀ there).

    The minimum transmission angle is checked on the samples; :func:`synth.mechanism.sixbar.simulate`
    gives it between them (they agree to ~0.01° at 720 samples).
    """
    phi0, h, m = grid_step(phi)
    start, end = interval
    lead, z, (C0, rho, s0, s1, target) = _rows(path_z, circle_center, radius, start, end, swing)
    if z.shape[1] != m:
        raise ValueError(f"path_z has {z.shape[1]} samples, the crank grid {m}")
    C0 = C0.astype(complex)
    rho = rho.astype(float)
    target = target.astype(float)
    if np.any(rho <= 0):
        raise ValueError("arc radius must be > 0")
    if np.any(target <= 0) or np.any(target >= math.pi):
        raise ValueError("RRR swing must be in (0, pi) radians")
    if not (0 < min_transmission < 0.5 * math.pi):
        raise ValueError("min_transmission must be in (0, pi/2) radians")
    if int(directions) < 4 or int(keep) < 1:
        raise ValueError("need directions >= 4 and keep >= 1")
    R = z.shape[0]
    # only the middle sample: where Q rests, which puts the rocker's branch
    mid = _mid_sample(phi0, h, m, s0.astype(float), s1.astype(float))
    w = z - C0[:, None]  # (R, M)
    cm = math.cos(min_transmission)
    q_mid_w = w[np.arange(R), mid]
    K = int(directions)
    n_keep = min(int(keep), K)
    # The rows are worked through in blocks (cache blocking: each block's rows × directions ×
    # samples temporaries stay in the CPU cache; every step works row by row, so the numbers
    # do not depend on the blocks). A row with no feasible direction in the coarse scan finds
    # nothing (its solves are inactive), so only the others are scanned finely and solved:
    # on the atlas, 2–9 % of the arcs' rows.
    blocks = range(0, R, _CHUNK_ROWS)
    coarse = [
        _rrr_coarse_scan(
            w[k : k + _CHUNK_ROWS],
            rho[k : k + _CHUNK_ROWS],
            cm,
            q_mid_w[k : k + _CHUNK_ROWS],
            target[k : k + _CHUNK_ROWS],
            m,
            K,
            n_keep,
        )
        for k in blocks
    ]
    centre = np.concatenate([c for c, _ in coarse]) if R else np.zeros((0, n_keep))
    peak_ok = np.concatenate([p for _, p in coarse]) if R else np.zeros((0, n_keep), bool)
    live = np.flatnonzero(peak_ok.any(axis=1))
    # rows (and slots) that find nothing: pivot C₀, every other figure 0
    out = [
        np.repeat(C0[:, None], n_keep, axis=1),
        np.zeros((R, n_keep)),
        np.repeat(rho[:, None], n_keep, axis=1),
        np.zeros((R, n_keep), np.int8),
        np.zeros((R, n_keep)),
        np.zeros((R, n_keep)),
        np.zeros((R, n_keep)),
        np.zeros((R, n_keep), bool),
    ]
    for k in range(0, live.size, _CHUNK_ROWS):
        rows = live[k : k + _CHUNK_ROWS]
        for field, value in zip(
            out,
            _rrr_fine_fit(
                C0[rows],
                w[rows],
                rho[rows],
                min_transmission,
                q_mid_w[rows],
                target[rows],
                m,
                K,
                centre[rows],
                peak_ok[rows],
            ),
        ):
            field[rows] = value
    shape = lead + (n_keep,)
    return RrrFit(*(x.reshape(shape) for x in out))


def _rrr_coarse_scan(
    w: C128, rho: F64, cm: float, q_mid_w: C128, target: F64, m: int, K: int, n_keep: int
) -> tuple[F64, NDArray[np.bool_]]:
    """:func:`fit_rrr`'s coarse scan of ``K`` rocker directions for rows ``w = P − C₀``:
    the ``n_keep`` best local maxima of the estimated transmission angle per row (R, n_keep)
    and which of them are feasible peaks."""
    coarse_terms = RrrTerms(w[:, :: max(1, m // _RANK_SAMPLES)], rho, cm, q_mid_w)
    R = w.shape[0]
    coarse = np.broadcast_to(np.arange(K) * (_TWO_PI / K), (R, K))
    mu_c = coarse_terms.estimate(coarse, target)[-1]
    # Local maxima of the cyclic coarse scan, best first.
    is_peak = (mu_c >= np.roll(mu_c, 1, axis=1)) & (mu_c >= np.roll(mu_c, -1, axis=1)) & (mu_c > 0)
    order = np.argsort(np.where(is_peak, -mu_c, np.inf), axis=1, kind="stable")[:, :n_keep]
    return coarse[np.arange(R)[:, None], order], np.take_along_axis(is_peak, order, 1)


def _rrr_fine_fit(
    C0: C128,
    w: C128,
    rho: F64,
    min_transmission: float,
    q_mid_w: C128,
    target: F64,
    m: int,
    K: int,
    centre: F64,
    peak_ok: NDArray[np.bool_],
) -> tuple[np.ndarray, ...]:
    """:func:`fit_rrr` after the coarse scan (``centre``, ``peak_ok`` from
    :func:`_rrr_coarse_scan`) for rows ``w = P − C₀``: the fine scans around the coarse peaks,
    the swing solves and the choice among them, as the fields of :class:`RrrFit` (R, n_keep)."""
    cm = math.cos(min_transmission)
    # The directions are ranked on about _RANK_SAMPLES samples (a ranking needs no more); the
    # chosen ones are then bounded and solved on the full path.
    full = RrrTerms(w, rho, cm, q_mid_w)
    coarse_terms = RrrTerms(w[:, :: max(1, m // _RANK_SAMPLES)], rho, cm, q_mid_w)
    R, n_keep = centre.shape
    step = _TWO_PI / K

    def scan(centre, half_width, ratio, count):
        """Best direction of a closed-form scan of ±half_width around each centre, with the
        slider-limit u scaled by ``ratio`` (u ≈ ratio·u_est near a solved direction)."""
        offs = np.linspace(-half_width, half_width, count)
        fine = centre[..., None] + offs  # (R, keep, F)
        r_ = np.broadcast_to(ratio[..., None], fine.shape).reshape(R, -1)
        mu_f = coarse_terms.estimate(fine.reshape(R, -1), target, r_)[-1].reshape(fine.shape)
        return np.take_along_axis(fine, np.argmax(mu_f, axis=-1)[..., None], -1)[..., 0]

    def solve(alpha, active):
        branch, u_lo, u_hi, u_est, mu_est = full.estimate(alpha, target)
        u, S, conv = _solve_rrr(w, rho, alpha, branch, u_lo, u_hi, u_est, target, active & (mu_est > 0))
        mu = full.transmission(alpha, u)
        found = conv & (mu >= min_transmission - 1e-12) & (u > 0)
        ratio = np.where(conv & (u_est > 0), u / np.where(u_est > 0, u_est, 1.0), 1.0)
        return alpha, branch, u, S, np.where(found, mu, -1.0), found, ratio

    # Pass 1 ranks on the slider-limit estimate; the solved u over that estimate is a smooth
    # function of α, so pass 2 rescans a narrower neighbourhood with the estimate corrected by
    # it and keeps whichever solved direction transmits better.
    first = solve(scan(centre, step, np.ones(centre.shape), _FINE // 2 + 1), peak_ok)
    second = solve(scan(first[0], 0.5 * step, first[-1], _FINE), peak_ok)
    better = second[4] > first[4]
    alpha, branch, u, S, mu, found, _ = (np.where(better, y, x) for x, y in zip(first, second))
    # Two peaks whose refinements met on one direction are one candidate: keep the better.
    gap = np.abs(np.angle(np.exp(1j * (alpha[:, :, None] - alpha[:, None, :]))))
    worse = (mu[:, :, None] < mu[:, None, :]) | (
        (mu[:, :, None] == mu[:, None, :]) & (np.arange(n_keep)[:, None] > np.arange(n_keep)[None, :])
    )
    duplicate = np.any((gap < 0.25 * step) & worse & found[:, None, :], axis=2)
    found = found & ~duplicate
    mu = np.where(found, mu, -1.0)
    L = 1.0 / np.where(u > 0, u, 1.0)
    D = C0[:, None] + L * np.exp(1j * alpha)
    # Best first among the found ones.
    rank = np.argsort(np.where(found, -mu, np.inf), axis=1, kind="stable")
    take = lambda x: np.take_along_axis(x, rank, 1)
    return (
        take(D),
        take(L),
        np.broadcast_to(rho[:, None], (R, n_keep)).copy(),
        take(branch).astype(np.int8),
        take(np.mod(alpha, _TWO_PI)),
        take(S),
        take(np.where(found, mu, 0.0)),
        take(found),
    )


#: Rows fitted at a time by :func:`fit_rrr` (cache blocking; the result does not depend on it).
_CHUNK_ROWS = 128
#: Samples over the turn on which the rocker directions are ranked (closed-form estimates).
_RANK_SAMPLES = 120
#: Directions of the second fine scan around a coarse peak (±half a coarse step; the first,
#: ±one step, takes half as many).
_FINE = 17


class RrrTerms:
    """Per-sample terms of the closed-form RRR relations for one set of path samples.

    With w = P − C₀, p + iq = w·e^{−iα}: cos μ = A·u + B, A = (ρ² − |w|²)/(2ρ), B = p/ρ.
    |A u + B| ≤ cm ⇔ u ∈ [−B/A − cm/|A|, −B/A + cm/|A|] (A ≠ 0; for A → 0 the interval
    grows to the whole line when |B| < cm and leaves u ≥ 0 otherwise, which a tiny |A| gives
    by itself).
    """

    def __init__(self, w: C128, rho: F64, cm: float, w_mid: C128):
        self.wx, self.wy = w.real[:, None, :], w.imag[:, None, :]
        self.rho = rho[:, None, None]
        A = (rho[:, None] ** 2 - (w.real**2 + w.imag**2)) / (2 * rho[:, None])
        self.A = A[:, None, :]
        tiny = 1e-280
        inv_a = 1.0 / np.where(np.abs(A) < tiny, tiny, A)
        self.inv_a_rho = (inv_a / rho[:, None])[:, None, :]  # B/A = p·inv_a/ρ
        self.half = (cm * np.abs(inv_a))[:, None, :]
        self.w_mid = w_mid
        # the compiled ranking's inputs: the samples' terms (R, S) and the radii (R,), contiguous
        self.flat = (
            *(np.ascontiguousarray(x[:, 0, :]) for x in (self.wx, self.wy, self.A, self.inv_a_rho, self.half)),
            np.ascontiguousarray(rho, dtype=float),
        )

    def _pq(self, alpha):
        c, s = np.cos(alpha)[..., None], np.sin(alpha)[..., None]
        return self.wx * c + self.wy * s, self.wy * c - self.wx * s

    def estimate(self, alpha: F64, target: F64, ratio: F64 | float = 1.0):
        """For directions α (R, J): branch, transmission u-interval, slider-limit u and the
        minimum transmission angle at ``ratio`` times it (−1 where no feasible u); compiled
        (:mod:`synth.mechanism.dyad_kernel`, the same numbers)."""
        from synth.mechanism.dyad_kernel import direction_estimates  # numba: imported on first use

        alpha = np.asarray(alpha, dtype=float)
        q_mid = (self.w_mid[:, None] * np.exp(-1j * alpha)).imag
        branch = np.where(q_mid > 0, -1, 1)
        ratio = np.ascontiguousarray(np.broadcast_to(np.asarray(ratio, dtype=float), alpha.shape))
        u_lo, u_hi, u_est, cos_max, feasible = direction_estimates(
            *self.flat,
            np.ascontiguousarray(np.cos(alpha)),
            np.ascontiguousarray(np.sin(alpha)),
            branch.astype(float),
            np.ascontiguousarray(target, dtype=float),
            ratio,
        )
        mu = np.arccos(np.minimum(cos_max, 1.0))
        return branch, u_lo, u_hi, u_est, np.where(feasible, mu, -1.0)

    def transmission(self, alpha: F64, u: F64) -> F64:
        """Minimum folded transmission angle over the samples at directions α, u = 1/L."""
        p, _ = self._pq(alpha)
        cos_max = np.abs(self.A * u[..., None] + p / self.rho).max(axis=-1)
        return np.arccos(np.minimum(cos_max, 1.0))


def _solve_rrr(w, rho, alpha, branch, u_lo, u_hi, u_est, target, active):
    """Solve S(u) = target for RRR dyads in the rows × candidates (R, J) at directions α: the
    dyad loop P + ρ·e^{iχ} = D + L·e^{iψ} (P relative to C₀, D = L·e^{iα}) on the samples, S
    the rocker's swing and ∂S/∂u from its two extremes (compiled, the whole safeguarded Newton:
    :func:`synth.mechanism.dyad_kernel.solve_rrr`)."""
    from synth.mechanism.dyad_kernel import solve_rrr  # numba: imported on first use

    R, J = alpha.shape
    row_of = np.repeat(np.arange(R), J)
    e_f = np.exp(1j * alpha).ravel()
    ex, ey = np.ascontiguousarray(e_f.real), np.ascontiguousarray(e_f.imag)
    br_f = branch.ravel().astype(float)
    rho_f = rho[row_of]

    def solve(wk, lo, hi, u0, target, active, check_far):
        wx, wy = np.ascontiguousarray(wk.real), np.ascontiguousarray(wk.imag)
        return solve_rrr(
            wx, wy, row_of, ex, ey, br_f, rho_f, lo, hi, u0, target, active, check_far, SWING_TOL, SWING_MAX_ITER
        )

    # Rows without a feasible u-interval get a harmless dummy bracket and stay inactive.
    act = active & (u_hi > 0) & (u_lo <= u_hi)
    lo = np.where(act, u_lo, 0.5)
    hi = np.where(act, u_hi, 1.0)
    u0 = np.where(act & (u_est > 0), u_est, 0.5 * (lo + hi))
    return _solve_two_stage(solve, w, lo, hi, u0, np.broadcast_to(target[:, None], (R, J)), act)
