"""Necessary conditions on a six-bar's dwell and swing from its segment's stored data.

The derivation is in ``docs/complete-query.md``; in short (crank a = 1, β the output band in
rad, ρ_max the request's longest/shortest link ratio, m = :func:`~synth.mechanism.link_ratio.segment_shortest`
the shortest link the segment fixes: min(1, b, c, d, |AP|, |BP|), the coupler plate's sides
included):

* **The ratio.** The link ratio (:mod:`synth.mechanism.link_ratio`) counts the dyad's links (RPR reach,
  RRR rocker and rod) with the segment's, so a six-bar within ρ_max has every link ≤ ρ_max ×
  its shortest link ≤ ρ_max·m. Counting the plate's sides makes the ratio of a six-bar only
  larger (more links: the longest can only grow, the shortest only shrink), so every six-bar
  within the limit now was within it before, and m ≤ m₄ = min(1, b, c, d): a bound taken with
  m is at least as tight as one with m₄ and still necessary. Passing m₄ stays necessary too
  (looser).
* **RPR** (slot pivot D anywhere, on or off the line): while ψ = arg(P − D) stays within β,
  P stays within r·sin(β/2) of the line through D at the band's mid angle, r = max|P − D|
  ≤ ρ_max·m (the slot reach is a link of the ratio). So the minimum-zone line half-width of
  the path over the dwell is ≤ ε*_RPR = ρ_max·m·sin(β/2).
* **RRR** (rocker pivot D anywhere, rocker L, rod ρ): while arg(Q − D) stays within β, Q stays
  within 2L·sin(β/4) of the arc's mid point Q_m, so |P − Q_m| ∈ [ρ − δ, ρ + δ],
  δ = 2L·sin(β/4) ≤ 2ρ_max·m·sin(β/4) = ε*_RRR (L ≤ ρ_max·m: the rocker is a link of the
  ratio): a minimum-zone annulus half-width bound.

The segment's **deviation profile** L(ε) — the longest crank interval containing the
generating angle on which the path's minimum-zone half-width is ≤ ε — then bounds the dwell
(containing the generating angle) of every such six-bar: dwell ≤ L(ε*) ≤ L(ε_k) for the
smallest stored level ε_k ≥ ε* (L is non-decreasing in ε).

Swing (the output rocks, no revolution): RPR, the whole coupler curve lies in a circular sector
of angle S (the swing) and radius ρ_max·m about D (the reach is a link), so its convex hull's
minimum width W ≤ ρ_max·m·sin S (S ≤ π/2), i.e. S ≥ arcsin(W/(ρ_max·m)). RRR, the curve lies
within ρ of an arc of angle S and radius L ≤ ρ_max·m: its diameter Δ ≤ 2L·sin(S/2) + 2ρ
(S ≤ π).

The RPR reach in the ratio is the largest |P − D| on the figures' crank samples, which may
fall short of the continuous maximum by the sagitta of one sample step (~1e-5 of the reach at
0.5°); the deviation profile's slack of two grid steps and more covers it.

Pure: arrays in, arrays out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from kinematics.fourbar import fourbar_motion
from synth.kinds import OutputTag, SegmentKind
from synth.segment_search.minimum_zone import minimum_zone_fit, path_deviation
from synth.types import C128, F64

__all__ = [
    "PROFILE_LEVELS",
    "STAIRCASE_SLACK",
    "DeviationProfile",
    "curve_extent",
    "deviation_profile",
    "deviation_profiles",
    "dwell_bound",
    "minimum_zone_halfwidth",
    "path_tolerance",
    "rpr_min_swing",
    "rrr_min_swing",
]


#: Default profile levels: half-widths (crank lengths) 1e-5 … 1e-1, four per decade.
PROFILE_LEVELS = tuple(float(x) for x in np.logspace(-5, -1, 17))
#: Lawson iterations of each re-linearised minimum-zone fit (synth.segment_search.minimum_zone.minimum_zone_fit).
_ITERATIONS = 12
#: Re-linearisations of each fit (the circle's start is a three-point circle, not the optimum).
_RELINEARISE = 3
#: Extra grid steps added by the staircase walk (the fitter's non-monotonicity, measured ≤ 2).
STAIRCASE_SLACK = 3
#: Fitted circles larger than this (crank lengths) are not trusted (cancellation in |z − c| − r).
_MAX_RADIUS = 1e6


@dataclass(frozen=True, slots=True)
class DeviationProfile:
    """L(ε) of one segment (or a batch), struct of arrays.

    Attributes
    ----------
    levels : (K,) float
        Half-widths ε (crank lengths), increasing.
    length : (..., K) float
        Upper estimate of the longest crank interval (rad) containing the generating angle on
        which the path's minimum-zone half-width is ≤ ε (grid result + two grid steps: the
        true longest interval is never longer, up to the fitter's optimality gap).
    step : float
        Crank grid step of the search (rad).
    """

    levels: F64
    length: F64
    step: float


def _path(b, c, d, branch, uv, phi) -> C128:
    uv = np.asarray(uv, complex)
    return fourbar_motion(1.0, b, c, d, phi, branch, order=0).coupler_point(uv.real, uv.imag)[0]


def _start_geometry(z: C128, kind: int):
    """A line through the ends' chord (lines), the circle through the ends and the middle
    sample (arcs; a near-straight triple gets a far centre), as starting points of the fit."""
    z0, zm, z1 = z[:, 0], z[:, z.shape[1] // 2], z[:, -1]
    chord = z1 - z0
    direction = chord / np.maximum(np.abs(chord), 1e-300)
    direction = np.where(np.abs(chord) > 0, direction, 1.0)
    if kind == SegmentKind.LINE.code:
        return 0.5 * (z0 + z1), direction, np.zeros(z.shape[0])
    # circumcentre of z0, zm, z1
    a, bb = zm - z0, z1 - z0
    den = 2 * np.imag(np.conj(a) * bb)
    num = -1j * (np.abs(a) ** 2 * bb - np.abs(bb) ** 2 * a)
    flat = np.abs(den) < 1e-12 * np.maximum(np.abs(bb) ** 2, 1e-300)
    centre = np.where(flat, 0.5 * (z0 + z1) + 1j * direction * 1e6, z0 + num / np.where(flat, 1.0, den))
    return centre, direction, np.abs(z0 - centre)


def _least_squares_circle(z: C128):
    """Algebraic (Kåsa) least-squares circle of each row: |z|² ≈ 2·Re(conj(c)·z) + k."""
    zc = z - z.mean(axis=1, keepdims=True)  # centred for conditioning
    cols = np.stack([2 * zc.real, 2 * zc.imag, np.ones(zc.shape)], axis=-1)  # (n, s, 3)
    M = np.einsum("nsi,nsj->nij", cols, cols) + 1e-12 * np.eye(3)
    rhs = np.einsum("nsi,ns->ni", cols, np.abs(zc) ** 2)
    x = np.linalg.solve(M, rhs[..., None])[..., 0]
    centre = x[:, 0] + 1j * x[:, 1]
    radius = np.sqrt(np.maximum(x[:, 2] + np.abs(centre) ** 2, 0.0))
    return centre + z.mean(axis=1), radius


def minimum_zone_halfwidth(z: C128, kind: int) -> F64:
    """Half-width of the minimum-zone line (``kind`` 0: exact) or of an (approximately)
    minimum-zone annulus (1) of each row of path samples ``z`` (n, samples).

    Line: half the samples' minimum width, which is attained across one edge of their convex
    hull, so it is the smallest spread of the samples' projections on the normals of all
    sample pairs (exact; O(samples³) per row). Annulus: ``synth.segment_search.segments``' fitter, the peak
    |deviation| on the samples from the fitted circle (an upper estimate of the optimum); the
    fit is linearised about its start, so it is re-linearised and started twice (from the
    three-point circle and from the algebraic least-squares circle), and the smallest peak —
    or the line's, the limit of circles — is kept."""
    if kind == SegmentKind.LINE.code:
        return _minimum_width(z) / 2
    starts = [_start_geometry(z, kind)]
    if kind == SegmentKind.ARC.code:
        point, direction, _ = starts[0]
        centre, radius = _least_squares_circle(z)
        ok = np.isfinite(centre) & np.isfinite(radius) & (radius > 0)
        starts.append((np.where(ok, centre, starts[0][0]), direction, np.where(ok, radius, starts[0][2])))
    best = _minimum_width(z) / 2  # a line is the limit of circles: its half-width bounds the annulus's
    for point, direction, radius in starts:
        for _ in range(_RELINEARISE):
            point, direction, radius = minimum_zone_fit(z, kind, point, direction, radius, _ITERATIONS)
            h = np.abs(path_deviation(z, kind, point[:, None], direction[:, None], radius[:, None])).max(axis=1)
            # |z − c| − r loses every digit for a huge radius (a fit running off to a line):
            # such a circle proves nothing, the line above stands for it
            valid = np.isfinite(h) & (np.abs(radius) < _MAX_RADIUS) & np.isfinite(point)
            best = np.minimum(best, np.where(valid, h, np.inf))
    return best


def _minimum_width(z: C128) -> F64:
    """Per row of points ``z`` (n, s), the minimum width over all directions (0 for s < 3)."""
    n, m = z.shape
    if m < 3:
        return np.zeros(n)
    i, j = np.triu_indices(m, 1)
    out = np.empty(n)
    rows = max(1, (1 << 21) // (i.size * m))  # bounded temporaries
    for k in range(0, n, rows):
        zk = z[k : k + rows]
        edge = zk[:, j] - zk[:, i]  # (r, pairs)
        length = np.abs(edge)
        normal = np.where(length > 0, 1j * edge / np.where(length > 0, length, 1.0), 1j)
        proj = (zk[:, None, :] * np.conj(normal)[:, :, None]).real  # (r, pairs, s)
        out[k : k + rows] = (proj.max(axis=2) - proj.min(axis=2)).min(axis=1)
    return out


def deviation_profile(
    b: float,
    c: float,
    d: float,
    branch: int,
    uv: complex,
    phi_gen: float,
    kind: int,
    *,
    levels: ArrayLike = PROFILE_LEVELS,
    step: float = math.radians(1.0),
    reach: float = math.pi,
    samples: int = 21,
) -> DeviationProfile:
    """The deviation profile L(ε) of one segment on its exact path.

    Parameters
    ----------
    b, c, d, branch : four-bar proportions (crank 1) and assembly branch.
    uv : complex
        Coupler point in the coupler frame.
    phi_gen : float
        Generating crank angle (rad): every interval considered contains it.
    kind : {0, 1}
        0 line (RPR, also each stretch of a double line), 1 arc (RRR).
    levels : (K,) float
        Half-widths ε (crank lengths).
    step : float
        Grid step (rad) of the interval ends: intervals [φ_g − i·h, φ_g + j·h], i, j ≥ 0,
        i + j ≤ 2·reach/h. The result adds 2h (an interval between grid ends is at most that
        much longer than the grid interval it contains).
    reach : float
        Largest one-sided extent searched (rad); L is capped at 2π.
    samples : int
        Path samples per interval given to the fit (evenly spread, ends included).

    Notes
    -----
    The half-width w(I) of a minimum-zone fit is non-decreasing under inclusion, so the grid
    interval inside the true longest interval passes whenever the fit is optimal; the fit on
    ``samples`` points is a lower estimate of the continuous one (fewer constraints) and an
    upper estimate of the optimum on those points (Lawson is approximate). All intervals are
    fitted in one vectorised batch and every level is read from the same widths.
    """
    lv = np.sort(np.asarray(levels, float).ravel())
    k = int(math.floor(reach / step))
    i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
    keep = (i + j >= 1) & ((i + j) * step <= 2 * math.pi)
    i, j = i[keep], j[keep]
    spread = np.linspace(0.0, 1.0, samples)
    phi = phi_gen - i[:, None] * step + (i + j)[:, None] * step * spread
    z = _path(b, c, d, branch, uv, phi)
    w = np.empty(i.size)
    chunk = 8192
    for s in range(0, i.size, chunk):
        w[s : s + chunk] = minimum_zone_halfwidth(z[s : s + chunk], kind)
    span = (i + j) * step
    ok = w[:, None] <= lv[None, :]
    longest = np.where(ok, span[:, None], 0.0).max(axis=0)
    length = np.minimum(longest + 2 * step, 2 * math.pi)
    return DeviationProfile(lv, length, float(step))


def deviation_profiles(
    b: ArrayLike,
    c: ArrayLike,
    d: ArrayLike,
    branch: ArrayLike,
    uv: ArrayLike,
    phi_gen: ArrayLike,
    kind: int,
    *,
    levels: ArrayLike = PROFILE_LEVELS,
    step: float = math.radians(1.0),
    reach: float = math.pi,
    samples: int = 21,
) -> DeviationProfile:
    """:func:`deviation_profile` for a batch of segments of one ``kind`` (arguments (S,)), by
    a staircase walk instead of every interval: O(n) fits per segment and level, n = reach/h.

    For one level the feasible ends (i, j) form a down-set (w is monotone under inclusion), so
    max(i + j) is found by walking i up while (i, j) passes and j down while it fails. Every
    segment and level walks at once (one batched fit per step). Returns ``length`` (S, K).
    The approximate fitter is not exactly monotone, so the walk can stop a step or two early
    (measured: up to 2 steps below the exhaustive search): ``STAIRCASE_SLACK`` extra steps
    are added on top of the 2 of the grid; the test checks it is never below the exhaustive
    search."""
    b, c, d, br, uv, g = (np.atleast_1d(np.asarray(x)).ravel() for x in (b, c, d, branch, uv, phi_gen))
    lv = np.sort(np.asarray(levels, float).ravel())
    S, K = b.size, lv.size
    n = int(math.floor(reach / step))
    i = np.zeros((S, K), np.int64)
    j = np.full((S, K), n, np.int64)
    best = np.zeros((S, K), np.int64)
    seg = np.broadcast_to(np.arange(S)[:, None], (S, K))
    level = np.broadcast_to(lv, (S, K))
    spread = np.linspace(0.0, 1.0, samples)
    active = np.ones((S, K), bool)
    while np.any(active):
        r = np.flatnonzero(active.ravel())
        ii, jj, ss = i.ravel()[r], j.ravel()[r], seg.ravel()[r]
        phi = g[ss, None] - ii[:, None] * step + (ii + jj)[:, None] * step * spread
        z = _path(b[ss, None], c[ss, None], d[ss, None], br[ss, None], uv[ss, None], phi)
        passes = (minimum_zone_halfwidth(z, kind) <= level.ravel()[r]) | (ii + jj == 0)
        flat_best, flat_i, flat_j = best.ravel(), i.ravel(), j.ravel()
        flat_best[r] = np.where(passes, np.maximum(flat_best[r], ii + jj), flat_best[r])
        flat_i[r] = ii + passes
        flat_j[r] = jj - ~passes
        best, i, j = flat_best.reshape(S, K), flat_i.reshape(S, K), flat_j.reshape(S, K)
        active = (i <= n) & (j >= 0)
    length = np.minimum((best + 2 + STAIRCASE_SLACK) * step, 2 * math.pi)
    return DeviationProfile(lv, length, float(step))


def path_tolerance(kind: str, band: ArrayLike, max_link_ratio: ArrayLike, shortest: ArrayLike) -> F64:
    """ε*: the largest path half-width (crank lengths) a dyad of ``kind`` within the ratio can
    turn into an output band ``band`` (rad, total width).

    ``kind`` "rpr": ρ_max·m·sin(β/2); "rrr": 2ρ_max·m·sin(β/4). ``shortest`` = m, the
    shortest link the segment fixes (:func:`~synth.mechanism.link_ratio.segment_shortest`, the coupler
    plate's sides included): the dyad's reach or rocker, a link of the ratio, is at most
    ρ_max·m in any six-bar within ``max_link_ratio``. Any upper bound on m (e.g. the
    four-bar's min(1, b, c, d)) keeps ε* an upper bound, looser."""
    beta = np.asarray(band, float)
    reach = np.asarray(max_link_ratio, float) * np.asarray(shortest, float)
    if kind == OutputTag.RPR:
        return reach * np.sin(beta / 2)
    if kind == OutputTag.RRR:
        return 2 * reach * np.sin(beta / 4)
    raise ValueError(f"kind must be 'rpr' or 'rrr', not {kind!r}")


def dwell_bound(profile_levels: ArrayLike, profile_length: ArrayLike, eps_star: ArrayLike) -> F64:
    """Upper bound (rad) on the dwell containing the generating angle: L(ε_k) at the smallest
    stored level ε_k ≥ ε* (2π where ε* exceeds every level). Broadcasts over segments:
    ``profile_length`` (..., K), ``eps_star`` (...)."""
    lv = np.asarray(profile_levels, float)
    L = np.asarray(profile_length, float)
    e = np.asarray(eps_star, float)
    idx = np.searchsorted(lv, e, side="left")  # first level ≥ ε*
    padded = np.concatenate([L, np.full(L.shape[:-1] + (1,), 2 * math.pi)], axis=-1)
    return np.take_along_axis(padded, np.broadcast_to(idx, padded.shape[:-1])[..., None], axis=-1)[..., 0]


def curve_extent(b, c, d, branch, uv, *, samples: int = 720) -> tuple[F64, F64]:
    """(minimum width of the convex hull, diameter) of the coupler curve (crank lengths).

    Both on ``samples`` crank samples: a lower estimate of the curve's (its hull contains the
    samples' hull), which keeps the swing conditions necessary."""
    phi = np.linspace(0.0, 2 * math.pi, samples, endpoint=False)
    b, c, d, br, uv = (np.atleast_1d(np.asarray(x)) for x in (b, c, d, branch, uv))
    z = _path(b[:, None], c[:, None], d[:, None], br[:, None], uv[:, None], phi)
    width = np.empty(z.shape[0])
    diam = np.empty(z.shape[0])
    for r in range(z.shape[0]):
        hull = _hull(z[r])
        edges = np.roll(hull, -1) - hull
        e = edges / np.maximum(np.abs(edges), 1e-300)
        # width across each hull edge: max distance of the hull from its line (rotating calipers)
        dist = np.abs(np.imag(np.conj(e)[:, None] * (hull[None, :] - hull[:, None])))
        width[r] = dist.max(axis=1).min() if hull.size > 2 else 0.0
        diam[r] = np.abs(hull[:, None] - hull[None, :]).max()
    return width, diam


def _hull(z: C128) -> C128:
    """Convex hull (counter-clockwise) of points ``z``: Andrew's monotone chain."""
    pts = sorted(set(zip(z.real.tolist(), z.imag.tolist())))
    if len(pts) < 3:
        return np.array([complex(x, y) for x, y in pts])

    def half(seq):
        out: list = []
        for p in seq:
            while (
                len(out) >= 2
                and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1]) - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0]))
                <= 0
            ):
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array([complex(x, y) for x, y in lower[:-1] + upper[:-1]])


def rpr_min_swing(width: ArrayLike, max_link_ratio: ArrayLike, shortest: ArrayLike) -> F64:
    """Smallest swing (rad) an RPR output of reach ≤ ρ_max·m can make on a curve of hull
    width ``width``: arcsin(W/(ρ_max·m)) (π/2 where W exceeds the reach: then the swing
    exceeds π/2 or the output cannot follow). ``shortest`` = m as in :func:`path_tolerance`:
    the reach is a link of the ratio."""
    ratio = np.asarray(width, float) / (np.asarray(max_link_ratio, float) * np.asarray(shortest, float))
    return np.arcsin(np.minimum(ratio, 1.0))


def rrr_min_swing(diameter: ArrayLike, rod: ArrayLike, max_link_ratio: ArrayLike, shortest: ArrayLike) -> F64:
    """Smallest swing (rad) of an RRR output with rod ρ and rocker ≤ ρ_max·m on a curve of
    diameter Δ: 2·arcsin((Δ − 2ρ)/(2ρ_max·m)) clipped to [0, π]. ``shortest`` = m as in
    :func:`path_tolerance`: the rocker is a link of the ratio."""
    x = (np.asarray(diameter, float) - 2 * np.asarray(rod, float)) / (
        2 * np.asarray(max_link_ratio, float) * np.asarray(shortest, float)
    )
    return 2 * np.arcsin(np.clip(x, 0.0, 1.0))
