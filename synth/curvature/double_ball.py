"""Double Ball points: coupler points that are Ball's point at two crank angles.

The coupler curve of a double Ball point has two nearly straight stretches; a slotted-rocker
(RPR) output pivoted where the two tangent lines meet dwells twice per turn. They are the
self-intersections of the Ball-point track p_B(φ) drawn in the coupler frame over the turn.

Search: sample the track densely, cut it where it leaves the plane (the pole at infinity,
θ′ = 0, sends Ball's point to infinity along an asymptote) or the loop cannot be evaluated,
extend each cut end geometrically towards the asymptote until it leaves the search disc,
sample geometrically finer around the rocker dead-centres (γ′ = 0, where the track passes
through B and a true crossing can sit next to the false one) and towards the ends of a
limited crank range (where the track speeds up before a toggle), find
the polyline's self-crossings (segment pairs with overlapping closed bounding boxes, found for
the whole batch at once by a sort-and-sweep, then an exact intersection test), refine each
(φ₁, φ₂) by Newton's method on p_B(φ₁) − p_B(φ₂) = 0 with the analytic derivative p_B′ (which
needs θ⁗, derived here), reject false crossings and deduplicate.

The crossing search takes the whole batch at once: a sort-and-sweep over each linkage's
segment boxes (:mod:`synth.curvature.double_ball_kernel`, compiled, imported on first use) finds the
same candidate pairs a shapely ``STRtree`` per linkage did (closed boxes that touch or
overlap), and the exact test runs on all pairs together.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinematics.fourbar import FourBarMotion, check_lengths, fourbar_motion
from kinematics.status import AssemblyError, Branch, Status, check_on_degenerate
from synth.curvature.ball import ball_point_offset_rate
from synth.curvature.pole import loop_condition
from synth.types import C128, F64, MAX_CONDITION, U16

__all__ = ["DoubleBallPoints", "double_ball_points", "theta4"]

I64 = NDArray[np.int64]

TWO_PI = 2.0 * np.pi
#: Newton stops when both crank-angle corrections are below this (rad); quadratic convergence
#: leaves the final error far below it.
ANGLE_TOL = 1e-12
#: A refined crossing within this distance (× linkage size) of the joint B is the rocker
#: dead-centre artefact: Ball's point is the pole = B at both dead-centres, and B's path is a
#: circle, so it is never a double Ball point.
DEAD_CENTRE_TOL = 1e-8
#: Newton iterations before a candidate counts as unconverged.
_MAX_NEWTON = 40
#: Geometric samples added on each side of (the step halves each time): a zero of θ′ (down to
#: ~1e-15 rad: far out along the asymptote), a zero of γ′ (rocker dead-centre) and an end of
#: the usable crank range (toggle side of a rocker crank), both down to ~1e-10 rad (finer
#: steps are below the rounding of the track there and only add noise-level zigzags).
_SAMPLE_DEPTH = {"theta": 40, "gamma": 24, "edge": 24}
#: Seeds whose two crank angles differ by less than this (rad) are one pass of the track
#: crossing itself in rounding noise, not two passes: dropped before refinement.
_SAME_PASS = 1e-6
#: Speed of the Ball-point track |dp_B/dφ| (per radian, relative to the linkage size) below
#: which it counts as standing still: rounding noise, 1e-16–1e-13 on kites; a moving track's
#: slowest samples (near a cusp) are far above it at 4096 samples a turn.
STILL_SPEED = 1e-9


@dataclass(frozen=True, slots=True)
class DoubleBallPoints:
    """All double Ball points of a batch of linkages: flat arrays plus ``linkage_index``.

    Attributes
    ----------
    linkage_index : int64, (K,)
        Which input linkage each point belongs to.
    uv : complex128, (K,)
        Coupler-frame position (origin A, x-axis along A→B).
    phi1, phi2 : float64, (K,)
        The two crank angles (rad), 0 ≤ φ₁ < φ₂ < 2π, refined to ``ANGLE_TOL``.
    point1, point2 : complex128, (K,)
        Fixed-frame position of the point at φ₁ and at φ₂.
    tangent1, tangent2 : complex128, (K,)
        Unit direction of its path at φ₁ and φ₂: with ``point1``/``point2`` the two tangent
        lines of the nearly straight stretches.
    false_crossings : int64, (N,)
        Per linkage: track crossings rejected as rocker dead-centre artefacts (at B).
    unconverged : int64, (N,)
        Per linkage: crossings of the sampled track whose refinement did not converge or
        collapsed to φ₁ = φ₂ (counted, not returned).
    status : uint16, (N,)
        Per linkage: ``NOT_ASSEMBLABLE`` if the loop never closes (nothing searched).
    """

    linkage_index: I64
    uv: C128
    phi1: F64
    phi2: F64
    point1: C128
    point2: C128
    tangent1: C128
    tangent2: C128
    false_crossings: I64
    unconverged: I64
    status: U16

    def __len__(self) -> int:
        return int(self.linkage_index.size)


def theta4(motion: FourBarMotion) -> F64:
    """Fourth crank-angle derivative θ⁗ of the coupler angle (rad/rad⁴), motion's shape.

    Notes
    -----
    Differentiating the loop b·e^{iθ} − c·e^{iγ} = R(φ) a fourth time, with
    (e^{iθ})⁗ = (iθ⁗ − 4θ′θ‴ − 3θ″² − 6iθ′²θ″ + θ′⁴)e^{iθ} and R⁗ = −a·e^{iφ}, gives the
    docs/curvature.md §1 system with

    .. math::

        Q_4 = R'''' + b(4θ'θ''' + 3θ''^2 + 6iθ'^2θ'' - θ'^4)e^{iθ}
                    - c(4γ'γ''' + 3γ''^2 + 6iγ'^2γ'' - γ'^4)e^{iγ},\\qquad
        θ'''' = -\\operatorname{Re}(Q_4 e^{-iγ}) / (b\\sin(θ-γ)).

    Flagged positions of the motion (toggle, not assemblable) give 0.
    """
    t1, t2, t3 = motion.dtheta
    g1, g2, g3 = motion.dgamma
    b, c = np.asarray(motion.b, float), np.asarray(motion.c, float)
    e_th, e_ga = motion.e_theta, motion.e_gamma
    q4 = (
        -motion.A
        + b * ((4 * t1 * t3 + 3 * t2 * t2 - t1**4) + 6j * t1 * t1 * t2) * e_th
        - c * ((4 * g1 * g3 + 3 * g2 * g2 - g1**4) + 6j * g1 * g1 * g2) * e_ga
    )
    s = b * motion.sin_theta_gamma
    ok = motion.status == 0
    return np.divide(-(q4 * np.conj(e_ga)).real, s, out=np.zeros_like(s), where=ok & (s != 0))


def _track(a, b, c, d, branch, phi) -> tuple[C128, C128, F64, NDArray[np.bool_]]:
    """Ball point p_B in the coupler frame, its φ-derivative, θ′, and whether it is usable."""
    return _track_of(fourbar_motion(a, b, c, d, phi, branch, order=3))


@dataclass(frozen=True, slots=True)
class _Motion(FourBarMotion):
    """A :class:`FourBarMotion` that keeps A, e^{iγ} and sin(θ − γ) once evaluated (the plain
    properties evaluate them at every use: per track :func:`theta4` and
    :func:`synth.curvature.pole.loop_condition` evaluate A five times, e^{iγ} three times).

    Each is evaluated by FourBarMotion's own property, on the ones kept before it: the same
    float operations on the same arrays, so the same bits (where A used to be a temporary it
    is added to, and an addition rounds the same in place or not)."""

    pin: C128 | None = None
    rocker: C128 | None = None
    sin_tg: F64 | None = None

    @property
    def A(self) -> C128:
        if self.pin is None:
            object.__setattr__(self, "pin", FourBarMotion.A.fget(self))  # a cache, not a change
        return self.pin

    @property
    def e_gamma(self) -> C128:
        if self.rocker is None:
            object.__setattr__(self, "rocker", FourBarMotion.e_gamma.fget(self))
        return self.rocker

    @property
    def sin_theta_gamma(self) -> F64:
        if self.sin_tg is None:
            object.__setattr__(self, "sin_tg", FourBarMotion.sin_theta_gamma.fget(self))
        return self.sin_tg


def _track_of(m: FourBarMotion) -> tuple[C128, C128, F64, NDArray[np.bool_]]:
    """:func:`_track` from a motion already solved with ``order=3`` (the bits of a fresh solve
    of the same arrays)."""
    m = _Motion(m.a, m.b, m.c, m.d, m.phi, m.branch, m.e_theta, m.dtheta, m.dgamma, m.status)
    a, b, c, d = m.a, m.b, m.c, m.d
    t1, t2, t3 = m.dtheta
    w, dw = ball_point_offset_rate(t1, t2, t3, theta4(m))
    rot = np.conj(m.e_theta) * m.A  # a·e^{i(φ−θ)}
    p = rot * w
    dp = rot * (1j * (1.0 - t1) * w + dw)
    ok = (m.status == 0) & (loop_condition(m) <= MAX_CONDITION) & np.isfinite(p) & np.isfinite(dp) & (t1 != 0)
    # a track that stands still (a kite a = b, c = d parks the Ball point on one spot for
    # much of the turn) moves by rounding noise only: every sample of it is "near" every
    # other, which made the crossing search and its Newton seeds quadratic (15 s, 3 GB)
    size = np.maximum(np.maximum(a, b), np.maximum(c, d))
    ok &= np.abs(dp) > STILL_SPEED * size
    return np.where(ok, p, 0j), np.where(ok, dp, 0j), t1, ok


def double_ball_points(
    a: ArrayLike,
    b: ArrayLike,
    c: ArrayLike,
    d: ArrayLike,
    branch: ArrayLike = Branch.LEFT,
    *,
    samples: int = 4096,
    reach: float = 1e3,
    on_degenerate: str = "flag",
) -> DoubleBallPoints:
    """Find every double Ball point of each linkage over its whole crank turn.

    Parameters
    ----------
    a, b, c, d : array_like, scalars or shape (N,)
        Crank, coupler, rocker, ground lengths (> 0).
    branch : array_like of {+1, −1}
        Assembly branch, broadcast with the lengths.
    samples : int
        Crank samples of the track over one turn (≥ 64). Crossings of two track stretches
        closer than about the sampling resolution can be missed (see Notes).
    reach : float
        Search disc radius around the crank pin, in linkage sizes L = max(a, b, c, d); the
        track beyond it is the asymptote towards a pole at infinity.
    on_degenerate : {"flag", "raise"}
        ``"raise"`` raises :class:`AssemblyError` for a linkage that never assembles.

    Returns
    -------
    DoubleBallPoints

    Notes
    -----
    p_B(φ) = e^{i(φ−θ)}·a·ŵ(θ′, θ″, θ‴) (:func:`synth.curvature.ball.ball_point_offset`), and
    p_B′ = e^{i(φ−θ)}·a·(i(1 − θ′)ŵ + ŵ′) with ŵ′ from θ′…θ⁗ (:func:`theta4`). Newton on
    F(φ₁, φ₂) = p_B(φ₁) − p_B(φ₂) solves the real 2×2 system
    [p_B′(φ₁), −p_B′(φ₂)]·δ = −F by Cramer's rule. No finite differences are involved.

    False crossings: at both rocker dead-centres B is the pole and Ball's point coincides with
    it, so the track passes through B twice; such crossings are rejected (``DEAD_CENTRE_TOL``)
    and counted in ``false_crossings``.

    References
    ----------
    ``docs/curvature.md`` §2, "Double Ball point".
    """
    mode = check_on_degenerate(on_degenerate)
    if samples < 64:
        raise ValueError(f"samples must be >= 64, got {samples}")
    if not (np.isfinite(reach) and reach > 0):
        raise ValueError(f"reach must be a finite number > 0, got {reach!r}")
    check_lengths(a=a, b=b, c=c, d=d)
    a, b, c, d, br = (np.atleast_1d(np.asarray(x, float)).ravel() for x in np.broadcast_arrays(a, b, c, d, branch))
    if not np.all((br == 1) | (br == -1)):
        raise ValueError(f"branch must be +1 or -1, got {branch!r}")
    n_link = a.size
    size = np.maximum(np.maximum(a, b), np.maximum(c, d))
    radius = reach * size

    phi = np.linspace(0.0, TWO_PI, samples, endpoint=False)
    col = lambda x: x[:, None]  # noqa: E731
    # one solve for the track and the rocker rates: order 1 and order 3 give the same θ′, γ′
    # and status bits (the same operations; the higher orders only come after them)
    grid = fourbar_motion(col(a), col(b), col(c), col(d), phi, col(br), order=3)
    p, _, t1, moving = _track_of(grid)
    ok = moving & (np.abs(p) <= col(radius))
    never = grid.status.all(axis=1)
    status = np.where(never, np.uint16(Status.NOT_ASSEMBLABLE), np.uint16(0)).astype(np.uint16)
    if mode == "raise" and never.any():
        k = int(np.flatnonzero(never)[0])
        raise AssemblyError(f"four-bar a={a[k]:g} b={b[k]:g} c={c[k]:g} d={d[k]:g} cannot assemble at any crank angle")
    g1 = grid.dgamma[0]
    every = np.ones_like(moving)

    def rate_signs(link, angles, kind):  # kind 0: sign of θ′, 1: of γ′, from one solve
        m = fourbar_motion(a[link], b[link], c[link], d[link], angles, br[link], order=1)
        return np.sign(np.where(kind == 1, m.dgamma[0], m.dtheta[0]))

    def usable_at(link, angles, kind):
        return _track(a[link], b[link], c[link], d[link], br[link], angles)[3]

    rates = [(np.sign(t1), moving, _SAMPLE_DEPTH["theta"]), (np.sign(g1), moving, _SAMPLE_DEPTH["gamma"])]
    parts = [
        _event_samples(phi, rates, rate_signs),
        _event_samples(phi, [(moving, every, _SAMPLE_DEPTH["edge"])], usable_at),
    ]
    ext_link, ext_phi = (np.concatenate(x) for x in zip(*parts))
    ep, _, et1, eok = _track(a[ext_link], b[ext_link], c[ext_link], d[ext_link], br[ext_link], ext_phi)
    eok &= np.abs(ep) <= radius[ext_link]

    rings = _rings(phi, p, t1, ok, ext_link, ext_phi, ep, et1, eok)
    link, phi1, phi2 = _crossings(rings)
    two_passes = np.abs(np.angle(np.exp(1j * (phi1 - phi2)))) > _SAME_PASS
    link, phi1, phi2 = link[two_passes], phi1[two_passes], phi2[two_passes]

    phi1, phi2, conv, pb = _refine(a[link], b[link], c[link], d[link], br[link], phi1, phi2, TWO_PI / samples)
    phi1, phi2 = _turn(phi1), _turn(phi2)
    gap = np.abs(np.angle(np.exp(1j * (phi1 - phi2))))
    conv &= (gap > _SAME_PASS) & (np.abs(pb) <= radius[link])
    at_b = conv & (np.abs(pb - b[link]) <= DEAD_CENTRE_TOL * size[link])
    keep = conv & ~at_b
    false_crossings = _count_unique(link[at_b], phi1[at_b], phi2[at_b], n_link)
    unconverged = np.bincount(link[~conv], minlength=n_link).astype(np.int64)

    link, pb = link[keep], pb[keep]
    lo, hi = np.minimum(phi1[keep], phi2[keep]), np.maximum(phi1[keep], phi2[keep])
    first = _unique_rows(link, lo, hi)
    link, pb, lo, hi = link[first], pb[first], lo[first], hi[first]
    z1, t1_dir = _path_line(a[link], b[link], c[link], d[link], br[link], lo, pb)
    z2, t2_dir = _path_line(a[link], b[link], c[link], d[link], br[link], hi, pb)
    return DoubleBallPoints(link, pb, lo, hi, z1, z2, t1_dir, t2_dir, false_crossings, unconverged, status)


def _event_samples(phi, events, value_at) -> tuple[I64, F64]:
    """Extra crank angles approaching, geometrically from both sides, every place where the
    values of one kind of event change between neighbouring samples of the grid ``phi``.

    ``events`` gives per kind (values, usable, depth), ``values`` and ``usable`` (linkages,
    samples); ``value_at(link, angles, kind)`` evaluates the values of each element's kind
    anywhere. The changes of all kinds are located together by bisection (one evaluation per
    step: for θ′ and γ′ one four-bar solve), then samples at distances Δ/2, Δ/4, … Δ/2^depth
    are added on both sides (Δ the grid step), kind after kind. Used at three kinds of place
    (see ``_SAMPLE_DEPTH``).
    """
    nxt = np.roll(np.arange(phi.size), -1)
    found = []
    for kind, (values, usable, _) in enumerate(events):
        change = usable & usable[:, nxt] & (values != values[:, nxt])
        link, k = np.nonzero(change)
        found.append((link, k, values[link, k], np.full(link.size, kind)))
    link, k, at_lo, kind = (np.concatenate(x) for x in zip(*found))
    lo = phi[k]
    hi = np.where(k + 1 < phi.size, phi[np.minimum(k + 1, phi.size - 1)], TWO_PI)
    for _ in range(48 if link.size else 0):
        mid = 0.5 * (lo + hi)
        same = value_at(link, mid, kind) == at_lo
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    at = 0.5 * (lo + hi)
    out_link, out_phi = [], []
    for q, (_, _, depth) in enumerate(events):
        step = (phi[1] - phi[0]) * 0.5 ** np.arange(1, depth + 1)
        offsets = np.concatenate([-step, step])
        out_link.append(np.repeat(link[kind == q], offsets.size).astype(np.int64))
        out_phi.append(np.mod((at[kind == q][:, None] + offsets).ravel(), TWO_PI))
    return np.concatenate(out_link), np.concatenate(out_phi)


@dataclass(frozen=True, slots=True)
class _Rings:
    """Every linkage's track samples, grid and extra ones merged in crank-angle order, as one
    flat array of closed rings: linkage k holds positions ``start[k]:start[k + 1]`` and ``nxt``
    steps to the next sample of the same ring (from its last sample to its first)."""

    start: I64
    link: I64
    phi: F64
    p: C128
    t1: F64
    ok: NDArray[np.bool_]
    nxt: I64


def _rings(phi, p, t1, ok, ext_link, ext_phi, ep, et1, eok) -> _Rings:
    """Merge the grid samples (linkages × ``phi``) with the extra samples (flat, ``ext_link``).

    Each ring is in the order a stable sort by φ gives the linkage's grid followed by its extra
    samples: on equal φ the grid sample first, then the extra ones in their given order.
    """
    n_link, m = p.shape
    extra = np.lexsort((ext_phi, ext_link))  # stable: ties keep the given order
    el = ext_link[extra]
    count = np.bincount(el, minlength=n_link)
    start = np.zeros(n_link + 1, np.int64)
    np.cumsum(m + count, out=start[1:])
    rank = np.arange(el.size) - (np.cumsum(count) - count)[el]
    # grid samples at or before an extra one's φ come first (side="right")
    at_ext = start[el] + rank + np.searchsorted(phi, ext_phi[extra], side="right")
    is_ext = np.zeros(start[-1], bool)
    is_ext[at_ext] = True
    at_grid = np.flatnonzero(~is_ext)  # ascending: linkage-major, then φ, as the grid is

    def merged(grid_values, ext_values):
        out = np.empty(start[-1], grid_values.dtype)
        out[at_grid] = np.broadcast_to(grid_values, (n_link, m)).ravel()
        out[at_ext] = ext_values[extra]
        return out

    nxt = np.arange(1, start[-1] + 1)
    nxt[start[1:] - 1] = start[:-1]
    link = np.repeat(np.arange(n_link), np.diff(start))
    return _Rings(start, link, merged(phi, ext_phi), merged(p, ep), merged(t1, et1), merged(ok, eok), nxt)


def _groups(link: I64) -> tuple[I64, I64, I64]:
    """For positions grouped by linkage (``link`` non-decreasing): each group's first position,
    its size, and each position's group number."""
    first = np.flatnonzero(np.r_[True, link[1:] != link[:-1]]) if link.size else np.zeros(0, np.int64)
    size = np.diff(np.r_[first, link.size])
    return first, size, np.repeat(np.arange(first.size), size)


def _two_or_more(seg: I64, link: I64) -> I64:
    """``seg`` without the linkages that have fewer than two of them (nothing to cross)."""
    count = np.bincount(link[seg], minlength=1)
    return seg[count[link[seg]] >= 2]


def _segments(r: _Rings) -> I64:
    """Positions (into ``r``) of the first samples of the track segments searched for crossings,
    ascending (so grouped by linkage): both ends usable, θ′ of one sign along it, and at least
    two per linkage — none of a degenerate track.

    Degenerate tracks would make every box overlap every other one (n² candidate pairs, tens of
    GB): a track that stands still (change-point linkages: the kite a = b, c = d parks it on
    one point for much of the turn) has segments of rounding-noise length (not above 1e-15 of
    the track's extent about its mean), which cross nothing; a track folded onto a straight
    line (the rhombus a = b = c = d: every end point within 1e-9 of its extent of its principal
    axis arg(Σ z²)/2) runs over itself along its whole length and crosses itself nowhere.
    """
    seg = r.ok & r.ok[r.nxt] & (np.sign(r.t1) == np.sign(r.t1[r.nxt]))
    seg = _two_or_more(np.flatnonzero(seg), r.link)
    if seg.size == 0:
        return seg
    first, size, group = _groups(r.link[seg])
    p0 = r.p[seg]
    extent = np.maximum.reduceat(np.abs(p0 - (np.add.reduceat(p0, first) / size)[group]), first)
    seg = _two_or_more(seg[np.abs(r.p[r.nxt[seg]] - p0) > 1e-15 * extent[group]], r.link)
    if seg.size == 0:
        return seg
    first, size, group = _groups(r.link[seg])
    p0, p1 = r.p[seg], r.p[r.nxt[seg]]
    z0, z1 = (x - ((np.add.reduceat(p0, first) + np.add.reduceat(p1, first)) / (2 * size))[group] for x in (p0, p1))
    axis = np.exp(0.5j * np.angle(np.add.reduceat(z0 * z0 + z1 * z1, first)))[group]
    off = np.maximum.reduceat(np.maximum(np.abs((z0 * np.conj(axis)).imag), np.abs((z1 * np.conj(axis)).imag)), first)
    reach = np.maximum.reduceat(np.maximum(np.abs(z0), np.abs(z1)), first)
    return seg[~(off <= 1e-9 * reach)[group]]


def _crossings(r: _Rings) -> tuple[I64, F64, F64]:
    """Self-crossings of every linkage's sampled track as seeds (linkage, φ₁, φ₂).

    Seeds come grouped by linkage (ascending); within one, by the segment of φ₁ along the track
    (φ₁'s segment before φ₂'s), then by φ₂'s. Candidates are the pairs of segments, not neighbours along the track,
    whose closed bounding boxes meet (:func:`_box_pairs`); the exact test is vectorized below.
    """
    seg = _segments(r)
    link = r.link[seg]
    p0, p1 = r.p[seg], r.p[r.nxt[seg]]
    i, j = _box_pairs(p0, p1, seg, r.nxt[seg], link)
    u, v = p1[i] - p0[i], p1[j] - p0[j]
    qp = p0[j] - p0[i]
    # the temporary stays the left factor: numpy reuses a large (≥ 256 KiB) temporary right
    # factor of a complex product as its output, which rounds differently, and the bits would
    # then depend on the batch size
    cross = lambda x, y: (np.conj(x) * y).imag  # noqa: E731
    den = cross(u, v)
    with np.errstate(divide="ignore", invalid="ignore"):
        ti = cross(qp, v) / den
        tj = cross(qp, u) / den
    hit = (den != 0) & (ti >= 0) & (ti <= 1) & (tj >= 0) & (tj <= 1)
    i, j, ti, tj = i[hit], j[hit], ti[hit], tj[hit]
    order = np.lexsort((j, i))
    i, j, ti, tj = i[order], j[order], ti[order], tj[order]
    si, sj = seg[i], seg[j]
    span_i = np.mod(r.phi[r.nxt[si]] - r.phi[si], TWO_PI)
    span_j = np.mod(r.phi[r.nxt[sj]] - r.phi[sj], TWO_PI)
    return link[i].astype(np.int64), r.phi[si] + ti * span_i, r.phi[sj] + tj * span_j


def _box_pairs(p0: C128, p1: C128, start: I64, end: I64, link: I64) -> tuple[I64, I64]:
    """Pairs (i, j), i < j, of segments p0→p1 of one linkage (``link`` non-decreasing) whose
    closed bounding boxes meet (touching counts, as in a GEOS ``STRtree`` query) and that are
    not neighbours along the track (``end`` of one is the ``start`` sample of the other);
    grouped by linkage, in no particular order within one."""
    from synth.curvature.double_ball_kernel import box_sweep  # numba: imported on first use

    first, size, _ = _groups(link)
    # every linkage's segments in order of their smallest x, all linkages in one sort (ties
    # may fall in any order: the sweep finds the same pairs)
    by_left = np.lexsort((np.minimum(p0.real, p1.real), link))
    return box_sweep(p0, p1, start, end, first, size, by_left)


def _refine(a, b, c, d, br, phi1, phi2, max_step) -> tuple[F64, F64, NDArray[np.bool_], C128]:
    """Newton on p_B(φ₁) = p_B(φ₂) for all seeds at once; returns angles, converged, point."""
    phi1, phi2 = phi1.astype(float), phi2.astype(float)
    active = np.ones(phi1.size, bool)
    conv = np.zeros(phi1.size, bool)
    for _ in range(_MAX_NEWTON):
        if not active.any():
            break
        k = np.flatnonzero(active)
        p1, dp1, _, ok1 = _track(a[k], b[k], c[k], d[k], br[k], phi1[k])
        p2, dp2, _, ok2 = _track(a[k], b[k], c[k], d[k], br[k], phi2[k])
        res = p2 - p1  # x·dp1 + y·(−dp2) = −F = p2 − p1
        j2 = -dp2
        det = (np.conj(dp1) * j2).imag
        good = ok1 & ok2 & (det != 0)
        safe = np.where(good, det, 1.0)
        d1 = (np.conj(res) * j2).imag / safe
        d2 = (np.conj(dp1) * res).imag / safe
        big = np.maximum(np.abs(d1), np.abs(d2))
        scale = np.minimum(1.0, 4.0 * max_step / np.maximum(big, 1e-300))
        phi1[k] += np.where(good, d1 * scale, 0.0)
        phi2[k] += np.where(good, d2 * scale, 0.0)
        done = good & (big <= ANGLE_TOL)
        conv[k[done]] = True
        active[k[done | ~good]] = False
    p, _, _, ok = _track(a, b, c, d, br, phi1)
    return phi1, phi2, conv & ok, p


def _turn(phi: F64) -> F64:
    """Crank angles reduced to [0, 2π), with 2π − 1e-12 < φ mapped to 0."""
    phi = np.mod(phi, TWO_PI)
    return np.where(TWO_PI - phi < ANGLE_TOL, 0.0, phi)


def _unique_rows(link: I64, lo: F64, hi: F64, tol: float = 1e-9) -> I64:
    """Indices of the first of each group of (linkage, φ₁, φ₂) equal to within ``tol`` rad."""
    if link.size == 0:
        return np.zeros(0, np.int64)
    order = np.lexsort((hi, lo, link))
    l, x, y = link[order], lo[order], hi[order]
    new = np.ones(l.size, bool)
    new[1:] = (l[1:] != l[:-1]) | (np.abs(x[1:] - x[:-1]) > tol) | (np.abs(y[1:] - y[:-1]) > tol)
    return order[new]


def _count_unique(link: I64, phi1: F64, phi2: F64, n_link: int) -> I64:
    lo, hi = np.minimum(phi1, phi2), np.maximum(phi1, phi2)
    first = _unique_rows(link, lo, hi)
    return np.bincount(link[first], minlength=n_link).astype(np.int64)


def _path_line(a, b, c, d, br, phi, p) -> tuple[C128, C128]:
    """Fixed-frame position and unit path direction of coupler points p at crank angles φ."""
    m = fourbar_motion(a, b, c, d, phi, br, order=1)
    z, dz = m.coupler_point(p.real, p.imag, order=1)
    speed = np.abs(dz)
    return z, np.divide(dz, speed, out=np.ones_like(dz), where=speed > 0)
