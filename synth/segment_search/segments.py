"""Dwell segments of coupler curves: candidates from curvature theory, measured on the exact path.

Candidates (docs/curvature.md §2) for each linkage (crank a = 1):

* **line**: Ball's point at every crank step (four-point contact with its tangent line);
* **arc**: the circle point on each scan ray through the pole at every crank step (four
  infinitesimally close positions on its osculating circle, centred at the conjugate centre
  point);
* **double_line**: every double Ball point (Ball's point at two crank angles), both stretches.

Each candidate is measured on its exact path z(φ) = A(φ) + e^{iθ(φ)}·p (docs/curvature.md §3): at
every tolerance level ε (band half-width, crank lengths) its **dwell interval** is the largest
crank interval around the generating angle on which z stays within ε of a line (or circle)
*fitted to that interval* — an approximately minimum-zone fit (a Lawson-iterated Chebyshev fit,
linearised about the current geometry), which for a path deviating like Δφ⁴ from its osculating
circle gives dwells about 8^{1/4} ≈ 1.7× longer than the osculating circle does. The interval
ends are refined by bisection on the exact path to ``END_TOLERANCE``.

Only what can pass is evaluated (the build's cost is dominated by candidates that cannot):

1. every candidate whose deviation from its osculating line/circle exceeds ``prune_factor``·ε_max
   at both crank offsets ±min_dwell/2 is dropped: any interval of length ≥ min_dwell around
   the generating angle contains one of them (two path points per candidate);
2. the survivors' osculating runs give a score; only local maxima over neighbouring crank steps
   (and rays) are kept — neighbours are near-duplicates;
3. near-duplicates — segments of one linkage whose coupler points and intervals nearly
   coincide — are removed, first on the osculating runs within ε_max (those are never
   measured), then again on the measured dwells;
4. the rest are fitted and measured at the widest band ε_max, which alone decides what is
   kept (minimum dwell, near-duplicates); only the kept ones are measured at the narrower
   bands.

Pure: arrays in, a frozen struct of arrays out, skipped cases counted by reason.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinematics.fourbar import fourbar_motion
from kinematics.loop import line_intersection
from kinematics.status import Status
from synth.curvature.ball import ball_point
from synth.curvature.double_ball import double_ball_points
from synth.curvature.line_scan import line_scan
from synth.curvature.pole import pole
from synth.kinds import SegmentKind
from synth.segment_search.minimum_zone import path_deviation
from synth.types import C128, F64

__all__ = ["END_TOLERANCE", "FoundSegments", "SegmentSearch", "find_segments"]

I64 = NDArray[np.int64]

#: Two stretches of a double Ball point whose lines meet at |sin| below this are one straight
#: stretch seen twice, not two dwells (the "crossing" of two such lines is rounding): dropped.
DOUBLE_LINE_MIN_SIN = 1e-6
#: Interval ends are bisected on the exact path until their bracket is below this (rad): 0.001°.
END_TOLERANCE = math.radians(1e-3)
#: Path samples a minimum-zone fit uses, spread evenly over its interval (ends included).
FIT_SAMPLES = 21
_FIT_SPREAD = np.linspace(0.0, 1.0, FIT_SAMPLES)
#: A fit is accepted when its sampled (and parabola-interpolated) band is this much inside
#: ε, so that the band holds between samples too.
_BAND_MARGIN = 1e-3
#: Margin on the predicted length of the next fit's interval (see ``_measure``).
_GROWTH_SAFETY = 0.98
#: Linkages per block of the candidate search (bounds the memory of the pruning stage).
_BLOCK = 8


@dataclass(frozen=True, slots=True)
class SegmentSearch:
    """How candidates are generated and measured (angles in degrees, lengths in crank lengths).

    ``prune_factor`` is the slack between the osculating deviation and the band when pruning
    (a minimum-zone band is at best ~8× narrower than the osculating deviation of a Δφ⁴
    stretch; 10 leaves room for asymmetric stretches). ``fine_per_step`` path samples per
    crank step locate the interval ends before bisection.
    """

    crank_step_deg: float = 2.0
    rays: int = 36
    tolerances: tuple[float, ...] = (1e-4, 1e-3, 1e-2)
    min_dwell_deg: float = 20.0
    prune_factor: float = 10.0
    fine_per_step: int = 2
    lawson_iterations: int = 10
    window_tries: int = 5
    double_ball_samples: int = 1024
    merge_reach: int = 1

    @classmethod
    def from_spec(cls, spec: Any) -> SegmentSearch:
        """The search an :class:`atlas.sweep.SweepSpec` asks for."""
        return cls(
            crank_step_deg=float(spec.crank_step_deg),
            rays=int(spec.rays),
            tolerances=tuple(float(t) for t in spec.tolerances),
            min_dwell_deg=float(spec.min_dwell_deg),
        )

    @property
    def steps(self) -> int:
        """Crank steps per turn (the step is rounded so that they tile the turn)."""
        return max(8, round(360.0 / self.crank_step_deg))


@dataclass(frozen=True, slots=True)
class FoundSegments:
    """Measured segments of a batch of linkages, struct of arrays (one row per segment).

    ``linkage`` indexes the input batch; ``kind`` is a :attr:`SegmentKind.code <synth.kinds.SegmentKind.code>`. Per segment: the
    generating angle(s) (rad), scan ray angle (arcs; 0 otherwise), coupler point ``uv``, the
    osculating geometry — line ``point`` + unit ``direction`` (lines; for double lines also
    ``point2``/``direction2`` and their ``intersection``) or circle ``center`` + ``radius``
    (arcs). Per segment, level and part (``[:, level, part]``): ``has_dwell``, the interval
    ``phi_start`` < ``phi_end`` (rad, ``phi_start`` in [0, 2π)) on which the path stays within
    the level's tolerance of its fitted geometry, which is ``fit_point`` + ``fit_direction``
    (lines) or ``fit_point`` + ``fit_radius`` (arcs). (No deviation reached inside the interval
    and no transmission range: nothing stores them, and the build computed them for nothing —
    ~80 ms of a ``standard`` shard's 1.3 s.) Per segment and level (``[:, level]``), arcs only: ``excursion``,
    the path's largest distance from that level's circle over the whole turn (crank lengths,
    on the fine grid; 0 for lines and where there is no dwell): it sets the RRR rocker a
    swing needs (:mod:`synth.segment_search.dwell_key`).
    """

    linkage: I64
    kind: I64
    phi_gen: F64
    phi_gen2: F64
    ray: F64
    uv: C128
    point: C128
    direction: C128
    point2: C128
    direction2: C128
    intersection: C128
    center: C128
    radius: F64
    tolerances: tuple[float, ...]
    has_dwell: NDArray[np.bool_]
    phi_start: F64
    phi_end: F64
    fit_point: C128
    fit_direction: C128
    fit_radius: F64
    excursion: F64
    skipped: dict[str, int] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.linkage.size)


# --------------------------------------------------------------------------------------------
# stage 1–2: candidates on the crank grid, pruned and reduced to local bests


@dataclass(frozen=True, slots=True)
class _Candidates:
    """Flat candidate list: linkage index, kind, fine-grid centre index, generating angle, ray,
    coupler point, osculating geometry, half-window (fine samples) for the measurement, and
    the partner index of a double Ball point's other stretch (−1 otherwise)."""

    linkage: I64
    kind: I64
    center: I64
    phi: F64
    ray: F64
    uv: C128
    point: C128
    direction: C128
    radius: F64
    window: I64
    partner: I64
    osc_start: F64
    osc_end: F64


def _local_best(score: F64, cyclic_axes: tuple[int, ...], reach: int = 1) -> NDArray[np.bool_]:
    """Cells ≥ every neighbour within ``reach`` cells along each of the last axes (ties go to
    the first cell in index order). ``score`` = −inf marks pruned cells, never kept."""
    keep = score > -np.inf
    ndim = score.ndim
    axes = tuple(range(1, ndim))
    for shift in np.ndindex(*(2 * reach + 1,) * len(axes)):
        offs = tuple(s - reach for s in shift)
        if not any(offs):
            continue
        moved = score
        valid = np.ones(score.shape, bool)
        for ax, off in zip(axes, offs):
            if off == 0:
                continue
            moved = np.roll(moved, -off, axis=ax)  # neighbour at index + off
            if ax not in cyclic_axes:
                edge = [slice(None)] * ndim
                edge[ax] = slice(-off, None) if off > 0 else slice(0, -off)
                v = np.ones(score.shape, bool)
                v[tuple(edge)] = False
                valid &= v
        later = next(o for o in offs if o) > 0  # neighbour comes after this cell in index order
        beats = (moved > score) if later else (moved >= score)
        keep &= ~(beats & valid)
    return keep


def _grid_candidates(b: F64, c: F64, d: F64, br: I64, search: SegmentSearch, skipped: Counter) -> _Candidates:
    m = search.steps
    step = 2 * np.pi / m
    phi = np.arange(m) * step
    alpha = np.arange(search.rays) * (np.pi / search.rays)
    eps_max = search.tolerances[-1]
    band = search.prune_factor * eps_max
    half = max(1, int(math.floor(math.radians(search.min_dwell_deg) / 2 / step)))
    # stage 2 looks up to half a turn each way (a dwell longer than that is not a dwell)
    reach = m // 2
    min_extent = math.radians(search.min_dwell_deg) / step - 2.0  # samples (sampling slack)
    fine = search.fine_per_step
    out: list[tuple] = []
    from synth.segment_search.osculating_runs import osculating_runs, osculating_scores  # numba: imported on first use

    for lo in range(0, b.size, _BLOCK):
        s = slice(lo, lo + _BLOCK)
        n = b[s].size
        motion = fourbar_motion(
            1.0, b[s, None, None], c[s, None, None], d[s, None, None], phi[:, None], br[s, None, None]
        )
        pl = pole(motion)
        A = np.broadcast_to(motion.A, motion.shape)[..., 0]  # (n, m): A does not depend on the linkage
        E = motion.e_theta[..., 0]
        ball = ball_point(pl)
        pairs = line_scan(pl, alpha)
        for flags in (ball.status[..., 0], pairs.status):
            for f in Status:
                cnt = int(np.count_nonzero(flags & f))
                if cnt:
                    skipped[f"candidate skipped: {f.name.lower().replace('_', ' ')}"] += cnt
        # --- lines: Ball points, grid (n, m)
        kinds = [
            (
                SegmentKind.LINE.code,
                ball.uv[..., 0],
                ball.point[..., 0],
                ball.tangent[..., 0],
                np.zeros((n, m)),
                ball.status[..., 0] == 0,
                np.zeros((n, m)),
            ),
            (
                SegmentKind.ARC.code,
                pairs.circle_point_uv,
                pairs.center_point,
                np.ones_like(pairs.center_point),
                pairs.radius,
                pairs.status == 0,
                np.broadcast_to(alpha, pairs.radius.shape),
            ),
        ]
        for kind, uv, point, direction, radius, ok, ray in kinds:
            shape = uv.shape  # (n, m) or (n, m, K)
            grid = [np.asarray(x).reshape(n, m, -1) for x in (uv, point, direction, radius, ok)]
            alive, score = osculating_scores(A, E, *grid, kind, half, band)
            alive, score = alive.reshape(shape), score.reshape(shape)
            skipped["candidate pruned: cannot reach the minimum dwell"] += int(np.count_nonzero(ok & ~alive))
            best = _local_best(score, cyclic_axes=(1, 2), reach=search.merge_reach)
            skipped["candidate merged: a neighbour is better"] += int(np.count_nonzero(alive & ~best))
            # the local bests' osculating runs within the pruning band: the minimum-dwell check
            # and the window the measurement needs; within the widest band: a first guess of the
            # interval, good enough to tell near-duplicates apart before measuring them
            cell = np.flatnonzero(best)
            ci = np.unravel_index(cell, shape)
            left, right, in_left, in_right = osculating_runs(
                A, E, ci[0], ci[1], uv[ci], point[ci], direction[ci], radius[ci], kind, reach, band, eps_max
            )
            whole = (left == reach) & (right == reach)
            long_enough = (left + right >= min_extent) & ~whole
            skipped["candidate skipped: path within tolerance over the whole turn"] += int(np.count_nonzero(whole))
            skipped["candidate pruned: cannot reach the minimum dwell"] += int(np.count_nonzero(~long_enough & ~whole))
            window = (np.maximum(left, right) + 2) * fine
            osc_start = (ci[1] - in_left) * step
            osc_end = (ci[1] + in_right) * step
            best.flat[cell[~long_enough]] = False
            window, osc_start, osc_end = window[long_enough], osc_start[long_enough], osc_end[long_enough]
            cell = np.flatnonzero(best)
            ci = np.unravel_index(cell, shape)
            out.append(
                (
                    ci[0] + lo,
                    np.full(cell.size, kind),
                    ci[1] * fine,
                    phi[ci[1]],
                    ray[ci],
                    uv[ci],
                    point[ci],
                    direction[ci],
                    radius[ci],
                    window,
                    osc_start,
                    osc_end,
                )
            )
    if not out:
        empty = (
            (np.zeros(0, np.int64),) * 3
            + (np.zeros(0),) * 2
            + (np.zeros(0, complex),) * 3
            + (np.zeros(0), np.zeros(0, np.int64))
        )
        return _Candidates(*empty, partner=np.zeros(0, np.int64), osc_start=np.zeros(0), osc_end=np.zeros(0))
    cols = [np.concatenate([o[k] for o in out]) for k in range(12)]
    return _Candidates(
        *cols[:10], partner=np.full(cols[0].size, -1, dtype=np.int64), osc_start=cols[10], osc_end=cols[11]
    )


def _double_candidates(b: F64, c: F64, d: F64, br: I64, search: SegmentSearch, skipped: Counter) -> _Candidates:
    found = double_ball_points(1.0, b, c, d, br, samples=search.double_ball_samples)
    k = len(found)
    for name, counts in (("false crossing", found.false_crossings), ("unconverged", found.unconverged)):
        if int(counts.sum()):
            skipped[f"double Ball point skipped: {name}"] += int(counts.sum())
    fine_step = 2 * np.pi / (search.steps * search.fine_per_step)
    window = np.full(2 * k, search.steps * search.fine_per_step // 2, dtype=np.int64)
    phi = np.r_[found.phi1, found.phi2]
    return _Candidates(
        linkage=np.r_[found.linkage_index, found.linkage_index].astype(np.int64),
        kind=np.full(2 * k, SegmentKind.LINE.code, dtype=np.int64),
        center=np.rint(phi / fine_step).astype(np.int64),
        phi=phi,
        ray=np.zeros(2 * k),
        uv=np.r_[found.uv, found.uv],
        point=np.r_[found.point1, found.point2],
        direction=np.r_[found.tangent1, found.tangent2],
        radius=np.zeros(2 * k),
        window=window,
        partner=np.r_[np.arange(k, 2 * k), np.arange(k)].astype(np.int64),
        osc_start=phi,
        osc_end=phi,
    )


# --------------------------------------------------------------------------------------------
# stage 3: dwell intervals on the exact path, measured with minimum-zone fits (synth.segment_search.minimum_zone)


def _measure(A: C128, E: C128, cand: _Candidates, rows: I64, width: I64, search: SegmentSearch, levels: list[int]):
    """Fit and measure candidates ``rows`` with half-windows ``width`` (fine samples) at
    ``levels`` (:func:`synth.segment_search.dwell_measure.measure_dwells`: the first level starts from the
    candidate's osculating line/circle, each further level from the previous level's fit).
    Returns per (candidate, level of ``levels``): run bounds [lo, hi] in window samples (hi <
    lo: no dwell), truncated (the run reached the window's edge), and the fitted geometry."""
    from synth.segment_search.dwell_measure import measure_dwells  # numba: imported on first use

    lo, hi, truncated, p, dr, r = measure_dwells(
        np.ascontiguousarray(A[0]),
        np.ascontiguousarray(E),
        cand.linkage[rows],
        cand.center[rows],
        cand.uv[rows],
        cand.kind[rows],
        np.asarray(width, np.int64),
        cand.point[rows],
        cand.direction[rows],
        cand.radius[rows],
        np.array([search.tolerances[level] for level in levels]),
        search.window_tries,
        search.lawson_iterations,
        _FIT_SPREAD,
        _BAND_MARGIN,
        _GROWTH_SAFETY,
    )
    return lo, hi, truncated, (p, dr, r)


def _bisect_ends(b, c, d, br, cand: _Candidates, rows: I64, phi_in: F64, phi_out: F64, geom, band: F64) -> F64:
    """Refine the crossing of |deviation| = band between ``phi_in`` (inside) and ``phi_out``
    (outside) on the exact path, to ``END_TOLERANCE``. Returns the last inside angle."""
    link = cand.linkage[rows]
    kind, uv = cand.kind[rows], cand.uv[rows]
    point, direction, radius = geom
    lo, hi = phi_in.copy(), phi_out.copy()
    steps = max(1, math.ceil(math.log2(max(np.max(np.abs(hi - lo), initial=0.0), END_TOLERANCE) / END_TOLERANCE)))
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        motion = fourbar_motion(1.0, b[link], c[link], d[link], mid, br[link], order=0)
        z = motion.coupler_point(uv.real, uv.imag)[0]
        inside = np.abs(path_deviation(z, kind, point, direction, radius)) <= band
        lo = np.where(inside, mid, lo)
        hi = np.where(inside, hi, mid)
    return lo


def find_segments(b: F64, c: F64, d: F64, branch: I64, search: SegmentSearch) -> FoundSegments:
    """Find and measure the dwell segments of a batch of crank-normalised linkages.

    ``b, c, d, branch``: shape (N,), linkages that assemble over the whole turn (crank-rockers
    or double-cranks). Returns segments grouped by linkage, then kind, then generating angle.
    """
    b, c, d = (np.asarray(x, float).ravel() for x in (b, c, d))
    br = np.asarray(branch, np.int64).ravel()
    skipped: Counter[str] = Counter()
    grid = _grid_candidates(b, c, d, br, search, skipped)
    double = _double_candidates(b, c, d, br, search, skipped) if b.size else grid
    if b.size:
        shift = len(grid.linkage)
        cand = _Candidates(
            **{
                f: np.r_[getattr(grid, f), getattr(double, f)]
                for f in _Candidates.__dataclass_fields__
                if f != "partner"
            },
            partner=np.r_[grid.partner, np.where(double.partner >= 0, double.partner + shift, -1)],
        )
    else:
        cand = grid
    n_cand = len(cand.linkage)
    levels = len(search.tolerances)
    mf = search.steps * search.fine_per_step
    fine_step = 2 * np.pi / mf
    phi_f = np.arange(mf) * fine_step
    motion = fourbar_motion(1.0, b[:, None], c[:, None], d[:, None], phi_f, br[:, None], order=0)
    A, E = np.broadcast_to(motion.A, motion.shape), motion.e_theta

    m = _Measured.empty(n_cand, levels)
    top = levels - 1
    # The widest band first, for every candidate: it alone decides which segments are kept
    # (minimum dwell, near-duplicates), so the narrower bands are measured for those only.
    window = np.minimum(cand.window, mf // 2 - 1)
    # Near-duplicates judged on their osculating runs are not measured at all (the same rule
    # is applied again to the measured dwells below): about a third of the work.
    early = _near_duplicates(
        cand, cand.osc_end - cand.osc_start, cand.osc_start, cand.osc_end, np.ones(n_cand, bool), search.tolerances[-1]
    )
    skipped["candidate merged: a near-duplicate follows the path longer"] += int(np.count_nonzero(early))
    every = np.flatnonzero(~early)
    _measure_rows(m, A, E, cand, every, window[every], [top], search)
    whole = m.truncated[:, top] & m.has[:, top]
    skipped["candidate skipped: path within tolerance over the whole turn"] += int(np.count_nonzero(whole))
    _refine_ends(m, b, c, d, br, cand, np.flatnonzero(m.has[:, top] & ~whole), top, search)

    min_dwell = math.radians(search.min_dwell_deg)
    keep = (m.dwell[:, top] >= min_dwell) & ~whole & ~early
    skipped["candidate dropped: dwell shorter than the minimum"] += int(np.count_nonzero(~keep & ~whole & ~early))
    keep = _pairs_kept(cand, keep, skipped)
    keep &= ~_near_duplicates(cand, m.dwell[:, top], m.start[:, top], m.end[:, top], keep, search.tolerances[-1])

    if top > 0:
        rows = np.flatnonzero(keep)
        narrower = list(range(top))
        _measure_rows(m, A, E, cand, rows, m.width[rows], narrower, search)
        for level in narrower:
            _refine_ends(m, b, c, d, br, cand, rows[m.has[rows, level] & ~m.truncated[rows, level]], level, search)
    # a narrower band whose run still reached the widest window's edge: no dwell stored there
    np.logical_and(m.has, ~m.truncated, out=m.has)
    return _assemble(
        A, E, cand, keep, search, m.start, np.where(m.has, m.dwell, 0.0), m.point, m.direction, m.radius, skipped
    )


@dataclass(frozen=True, slots=True)
class _Measured:
    """Per candidate and level: the run found on the fine grid (offsets from the centre), the
    fitted geometry, the exact interval [start, end] (rad) and the half-window used."""

    has: NDArray[np.bool_]
    lo: I64
    hi: I64
    truncated: NDArray[np.bool_]
    point: C128
    direction: C128
    radius: F64
    start: F64
    end: F64
    width: I64

    @classmethod
    def empty(cls, n: int, levels: int) -> _Measured:
        shape = (n, levels)
        return cls(
            np.zeros(shape, bool),
            np.zeros(shape, np.int64),
            np.full(shape, -1, np.int64),
            np.zeros(shape, bool),
            np.zeros(shape, complex),
            np.ones(shape, complex),
            np.zeros(shape),
            np.zeros(shape),
            np.zeros(shape),
            np.zeros(n, np.int64),
        )

    @property
    def dwell(self) -> F64:
        return np.where(self.has, self.end - self.start, 0.0)


def _measure_rows(
    m: _Measured, A: C128, E: C128, cand: _Candidates, rows: I64, window: I64, levels: list[int], search: SegmentSearch
) -> None:
    """Measure candidates ``rows`` at ``levels`` into ``m``, each in the narrowest window class
    that holds its ``window``; a run cut short by its window is measured again in the widest."""
    mf = A.shape[1]
    classes = np.asarray(_window_classes(mf))
    widest = int(classes[-1])
    cols = np.asarray(levels)

    def run(sel: I64, width: I64) -> None:
        lo, hi, truncated, (p, dr, r) = _measure(A, E, cand, sel, width, search, levels)
        m.lo[sel[:, None], cols], m.hi[sel[:, None], cols] = (
            lo - width[:, None],
            hi - width[:, None],
        )  # offsets from the centre
        m.truncated[sel[:, None], cols] = truncated
        m.has[sel[:, None], cols] = hi >= lo
        m.point[sel[:, None], cols], m.direction[sel[:, None], cols], m.radius[sel[:, None], cols] = p, dr, r
        m.width[sel] = width

    if rows.size:
        run(rows, classes[np.minimum(np.searchsorted(classes, window), classes.size - 1)])
    cut = rows[(m.truncated[rows[:, None], cols] & m.has[rows[:, None], cols]).any(axis=1) & (m.width[rows] < widest)]
    if cut.size:
        run(cut, np.full(cut.size, widest, np.int64))


def _refine_ends(m: _Measured, b, c, d, br, cand: _Candidates, rows: I64, level: int, search: SegmentSearch) -> None:
    """Exact ends of the runs of ``rows`` at ``level``: bisection between the last inside and
    the first outside fine sample."""
    if not rows.size:
        return
    fine_step = 2 * np.pi / (search.steps * search.fine_per_step)
    g = (m.point[rows, level], m.direction[rows, level], m.radius[rows, level])
    band = np.full(rows.size, search.tolerances[level])
    base = cand.center[rows] * fine_step
    inside = base + m.lo[rows, level] * fine_step
    m.start[rows, level] = _bisect_ends(b, c, d, br, cand, rows, inside, inside - fine_step, g, band)
    inside = base + m.hi[rows, level] * fine_step
    m.end[rows, level] = _bisect_ends(b, c, d, br, cand, rows, inside, inside + fine_step, g, band)


def _pairs_kept(cand: _Candidates, keep: NDArray[np.bool_], skipped: Counter) -> NDArray[np.bool_]:
    """``keep`` with the double Ball points that lost one stretch dropped (both are needed)."""
    dbl = cand.partner >= 0
    kept = keep & np.where(dbl, keep[np.maximum(cand.partner, 0)], True)
    skipped["double Ball point dropped: one stretch shorter than the minimum"] += int(
        np.count_nonzero(dbl & keep & ~kept)
    )
    return kept


def _window_classes(mf: int) -> list[int]:
    widths = [16, 32, 64, 128]
    return [w for w in widths if w < mf // 2 - 1] + [mf // 2 - 1]


def _near_duplicates(
    cand: _Candidates, dwell: F64, start: F64, end: F64, keep: NDArray[np.bool_], eps: float
) -> NDArray[np.bool_]:
    """Segments of one linkage and kind whose coupler points lie within 50 tolerances of each
    other and whose widest intervals overlap by more than half: all but the longest."""
    drop = np.zeros(keep.size, bool)
    single = keep & (cand.partner < 0)
    idx = np.flatnonzero(single)
    if idx.size < 2:
        return drop
    from synth.segment_search.near_duplicates import duplicates  # numba: imported on first use

    order = idx[np.lexsort((-dwell[idx], cand.kind[idx], cand.linkage[idx]))]
    group = cand.linkage[order] * 2 + cand.kind[order]
    bounds = np.r_[0, np.flatnonzero(np.diff(group)) + 1, order.size]
    drop[order[duplicates(cand.uv[order], start[order], end[order], dwell[order], bounds, 50 * eps)]] = True
    return drop


def _arc_excursion(A, E, cand, first, kind, has, gp, gr) -> F64:
    """(S, levels): per arc segment (candidate ``first``) and level with a dwell, the path's
    largest distance from that level's fitted circle (``gp``, ``gr``) over the whole fine grid;
    0 elsewhere. In blocks of segments: a block's paths are (block, fine grid) samples."""
    out = np.zeros(has.shape)
    arcs = np.flatnonzero(kind == SegmentKind.ARC.code)
    for k in range(0, arcs.size, _EXCURSION_BLOCK):
        at = arcs[k : k + _EXCURSION_BLOCK]
        r = first[at]
        z = A[cand.linkage[r]] + E[cand.linkage[r]] * cand.uv[r][:, None]
        for level in range(has.shape[1]):
            far = np.abs(
                path_deviation(z, SegmentKind.ARC.code, gp[r, level][:, None], 1.0, gr[r, level][:, None])
            ).max(axis=1)
            out[at, level] = np.where(has[at, level], far, 0.0)
    return out


#: Arc segments whose whole-turn paths are held at once by :func:`_arc_excursion`.
_EXCURSION_BLOCK = 512


def _assemble(A, E, cand, keep, search, start, dwell, gp, gd, gr, skipped) -> FoundSegments:
    first = np.flatnonzero(keep & ((cand.partner < 0) | (np.arange(keep.size) < cand.partner)))
    partner = np.where(cand.partner[first] >= 0, cand.partner[first], first)
    kind = np.where(cand.partner[first] >= 0, SegmentKind.DOUBLE_LINE.code, cand.kind[first])
    # canonical order: linkage, kind, generating angle, ray
    order = np.lexsort((cand.ray[first], cand.phi[first], kind, cand.linkage[first]))
    first, partner, kind = first[order], partner[order], kind[order]
    two = np.stack([first, partner], axis=1)  # (S, 2): part 0 and part 1 (same for single)
    has = (dwell[two] > 0).transpose(0, 2, 1)  # (S, levels, 2)
    is_double = kind == SegmentKind.DOUBLE_LINE.code
    has[~is_double, :, 1] = False
    twopi = 2 * np.pi
    s = np.mod(start[two], twopi).transpose(0, 2, 1)
    e = s + dwell[two].transpose(0, 2, 1)
    excursion = _arc_excursion(A, E, cand, first, kind, has[:, :, 0], gp, gr)
    a_dbl = is_double
    p1, p2 = cand.point[two[:, 0]], cand.point[two[:, 1]]
    t1, t2 = cand.direction[two[:, 0]], cand.direction[two[:, 1]]
    hit = line_intersection(p1, t1, p2, t2, parallel_eps=DOUBLE_LINE_MIN_SIN)
    parallel = a_dbl & hit.parallel
    inter = np.where(a_dbl & ~parallel, p1 + hit.t1 * t1, 0.0)
    far = a_dbl & (parallel | (np.abs(inter) > 1e6))
    if np.any(far):
        skipped["double Ball point dropped: its lines are parallel"] += int(np.count_nonzero(far))
    sel = ~far
    return FoundSegments(
        linkage=cand.linkage[first][sel],
        kind=kind[sel],
        phi_gen=cand.phi[first][sel],
        phi_gen2=np.where(a_dbl, cand.phi[partner], 0.0)[sel],
        ray=cand.ray[first][sel],
        uv=cand.uv[first][sel],
        point=np.where(kind == SegmentKind.ARC.code, 0, p1)[sel],
        direction=np.where(kind == SegmentKind.ARC.code, 1, t1)[sel],
        point2=np.where(a_dbl, p2, 0)[sel],
        direction2=np.where(a_dbl, t2, 1)[sel],
        intersection=inter[sel],
        center=np.where(kind == SegmentKind.ARC.code, cand.point[first], 0)[sel],
        radius=np.where(kind == SegmentKind.ARC.code, cand.radius[first], 0.0)[sel],
        tolerances=tuple(search.tolerances),
        has_dwell=has[sel],
        phi_start=s[sel],
        phi_end=e[sel],
        fit_point=gp[two].transpose(0, 2, 1)[sel],
        fit_direction=gd[two].transpose(0, 2, 1)[sel],
        fit_radius=gr[two].transpose(0, 2, 1)[sel],
        excursion=excursion[sel],
        skipped=dict(sorted((k, v) for k, v in skipped.items() if v)),
    )
