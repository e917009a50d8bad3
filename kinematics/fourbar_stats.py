"""Output-speed statistics of a four-bar used as a pulsating-transmission stage.

In an impulse (pulsating) variable-speed drive, a crank-rocker four-bar turns its rocker to
and fro and a one-way clutch (freewheel) passes only the forward strokes to the output shaft;
the crank length sets the swing and so the transmission ratio. With ``phases`` = n identical
stages driven 2π/n apart onto one shaft, the shaft follows the fastest engaged rocker:

.. math:: u(φ) = \\max\\bigl(0, \\max_k γ′(φ + 2πk/n)\\bigr), \\qquad ω_{out} = ω_{in}·u(φ)

(``clutch="freewheel"``), or ω_out = ω_in·γ′(φ) without a clutch (``clutch="none"``, e.g. a
drag-link double-crank). At constant input speed the time average over a turn is the
crank-angle average, so

.. math:: \\bar ω = \\frac{ω_{in}}{2π}\\int_0^{2π} u\\,dφ, \\quad
          σ^2 = \\frac{ω_{in}^2}{2π}\\int_0^{2π} u^2\\,dφ - \\bar ω^2, \\quad
          c_v = σ/\\bar ω .

c_v does not depend on the input speed. u has kinks where the engaged stage changes; they are
located on a dense grid and refined by Brent's method, and each smooth piece is integrated by
16-point Gauss–Legendre quadrature (γ′ is analytic there), so the statistics are accurate to
rounding (for one freewheel stage the mean is exactly ω·swing/2π, which the tests check).
The transmission ratio i = ω_out/ω_in = γ′ before the clutch has its extremes where γ″ = 0.

References
----------
N. Ilie, "Kinematic analysis of impulse continuously variable transmissions", and
G. A. Pires, *Impulse variable transmissions* (four-bar stages with one-way clutches).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinematics.fourbar import check_lengths, crank_range, fourbar_motion
from kinematics.status import AssemblyError, Status

__all__ = ["CLUTCHES", "CvMinimum", "OutputSpeedStats", "minimise_cv", "output_speed_stats", "speed_profile"]

CLUTCHES = ("freewheel", "none")
_GRID = 1024  # cells per period for locating kinks and ratio extremes
_GAUSS = np.polynomial.legendre.leggauss(16)
_PIECES = 64  # Gauss–Legendre panels per period


@dataclass(frozen=True, slots=True)
class OutputSpeedStats:
    """Output-speed statistics over one crank turn, struct of arrays of shape (crank lengths, rpms).

    Attributes
    ----------
    crank_length, rpm : float64
        The crank length (length unit) and input speed (rev/min) of each entry.
    mean, std, variance : float64
        Mean (rad/s), standard deviation (rad/s) and variance (rad²/s²) of the output angular
        velocity over a turn.
    cv : float64
        Coefficient of variation σ/ω̄ (dimensionless); 0 with ``AT_INFINITY`` where ω̄ = 0.
    ratio_min, ratio_max : float64
        Extremes of the transmission ratio γ′ = ω_rocker/ω_crank over a turn (before the clutch).
    status : uint8
        NOT_ASSEMBLABLE where the crank cannot make a full turn (values 0), TOGGLE where the
        turn passes a toggle, AT_INFINITY where c_v is unbounded (zero mean speed).
    """

    crank_length: NDArray[np.float64]
    rpm: NDArray[np.float64]
    mean: NDArray[np.float64]
    std: NDArray[np.float64]
    variance: NDArray[np.float64]
    cv: NDArray[np.float64]
    ratio_min: NDArray[np.float64]
    ratio_max: NDArray[np.float64]
    status: NDArray[np.uint8]


@dataclass(frozen=True, slots=True)
class _Turn:
    """Speed-independent results of one linkage: ∫u/2π, ∫u²/2π, ratio extremes, status."""

    m1: float
    m2: float
    ratio_min: float
    ratio_max: float
    status: int


def _check_clutch(clutch: str, phases: int) -> None:
    if clutch not in CLUTCHES:
        raise ValueError(f"clutch must be one of {', '.join(map(repr, CLUTCHES))}, not {clutch!r}")
    if int(phases) != phases or phases < 1:
        raise ValueError(f"phases must be a whole number >= 1, not {phases!r}")


def speed_profile(
    a: float,
    b: float,
    c: float,
    d: float,
    phi: ArrayLike,
    branch: int = 1,
    *,
    phases: int = 1,
    clutch: str = "freewheel",
) -> NDArray[np.float64]:
    """u(φ) = ω_out/ω_in at crank angles ``phi`` (rad), see the module notes."""
    _check_clutch(clutch, phases)
    phi = np.asarray(phi, float)
    shifts = 2 * np.pi * np.arange(phases) / phases
    g = fourbar_motion(a, b, c, d, phi[..., None] + shifts, branch, order=1).dgamma[0]
    if clutch == "none":
        return g[..., 0]
    return np.maximum(g.max(axis=-1), 0.0)


def _turn(a: float, b: float, c: float, d: float, branch: int, phases: int, clutch: str, grid: int = _GRID) -> _Turn:
    from scipy.optimize import brentq  # ~1 s to import: on first use, not at every command's start

    if crank_range(a, b, c, d) != [(-np.pi, np.pi)]:
        return _Turn(0.0, 0.0, 0.0, 0.0, int(Status.NOT_ASSEMBLABLE))
    if clutch == "none":
        phases = 1
    shifts = 2 * np.pi * np.arange(phases) / phases
    period = 2 * np.pi / phases if clutch == "freewheel" else 2 * np.pi
    x = np.linspace(0.0, period, grid + 1)
    m = fourbar_motion(a, b, c, d, x[:, None] + shifts, branch, order=2)
    status = int(np.bitwise_or.reduce(m.status.ravel()))
    g, g2 = m.dgamma[0], m.dgamma[1]

    def gk(phi, k):
        return float(fourbar_motion(a, b, c, d, phi + shifts[k], branch, order=1).dgamma[0])

    def active(values):  # index of the engaged function: −1 the clutch is open, k stage k
        if clutch == "none":
            return np.zeros(values.shape[0], int)
        k = np.argmax(values, axis=-1)
        return np.where(values.max(axis=-1) > 0, k, -1)

    def value(phi, k):
        return 0.0 if k < 0 else gk(phi, k)

    act = active(g)
    breaks = [0.0]
    for i in np.flatnonzero(act[1:] != act[:-1]):
        ka, kb = act[i], act[i + 1]
        breaks.append(brentq(lambda p: value(p, ka) - value(p, kb), x[i], x[i + 1], xtol=1e-14))
    breaks.append(period)
    nodes, weights = _GAUSS
    m1 = m2 = 0.0
    for lo, hi in zip(breaks[:-1], breaks[1:]):
        if hi <= lo:
            continue
        mid = active(np.atleast_2d(fourbar_motion(a, b, c, d, 0.5 * (lo + hi) + shifts, branch, order=1).dgamma[0]))[0]
        if mid < 0:
            continue
        pieces = max(1, int(np.ceil(_PIECES * (hi - lo) / period)))  # keep each Gauss rule short
        edges = np.linspace(lo, hi, pieces + 1)
        half = 0.5 * np.diff(edges)[:, None]
        p = (half * nodes + 0.5 * (edges[1:] + edges[:-1])[:, None]).ravel()
        w = (half * weights).ravel()
        u = fourbar_motion(a, b, c, d, p + shifts[mid], branch, order=1).dgamma[0]
        m1 += float(np.dot(w, u))
        m2 += float(np.dot(w, u * u))
    m1, m2 = m1 / period, m2 / period

    # extremes of γ′ over a turn: grid values and the zeros of γ″ between them
    g0, g20 = g[:, 0], g2[:, 0]
    full = np.linspace(0.0, 2 * np.pi, grid + 1) if period < 2 * np.pi else x
    if period < 2 * np.pi:
        mf = fourbar_motion(a, b, c, d, full, branch, order=2)
        g0, g20 = mf.dgamma[0], mf.dgamma[1]
    cands = list(g0)
    for i in np.flatnonzero(g20[1:] * g20[:-1] < 0):
        r = brentq(
            lambda p: float(fourbar_motion(a, b, c, d, p, branch, order=2).dgamma[1]), full[i], full[i + 1], xtol=1e-14
        )
        cands.append(gk(r, 0))
    return _Turn(m1, m2, float(min(cands)), float(max(cands)), status)


def output_speed_stats(
    crank_lengths: ArrayLike,
    b: float,
    c: float,
    d: float,
    rpms: ArrayLike,
    branch: int = 1,
    *,
    phases: int = 1,
    clutch: str = "freewheel",
) -> OutputSpeedStats:
    """Statistics of the output speed for every crank length × input speed (rev/min).

    Coupler b, rocker c and ground d stay fixed. See :class:`OutputSpeedStats` and the module
    notes for the definitions.
    """
    _check_clutch(clutch, phases)
    L = np.atleast_1d(np.asarray(crank_lengths, float))
    n = np.atleast_1d(np.asarray(rpms, float))
    check_lengths(crank=L, b=b, c=c, d=d)
    if not np.all(np.isfinite(n)) or np.any(n <= 0):
        raise AssemblyError(f"input speeds must be finite and > 0 rpm, got {n.tolist()}")
    turns = [_turn(float(a), b, c, d, branch, phases, clutch) for a in L]
    m1 = np.array([t.m1 for t in turns])[:, None]
    m2 = np.array([t.m2 for t in turns])[:, None]
    status = np.array([t.status for t in turns], np.uint8)[:, None]
    w = np.pi * n / 30.0
    mean = m1 * w
    variance = np.maximum(m2 - m1 * m1, 0.0) * w * w
    std = np.sqrt(variance)
    zero_mean = np.abs(m1) <= 1e-9 * np.sqrt(np.maximum(m2, 1e-300))
    cv = np.where(zero_mean, 0.0, np.sqrt(np.maximum(m2 - m1 * m1, 0.0)) / np.where(zero_mean, 1.0, np.abs(m1)))
    status = status | np.where(zero_mean & (status == 0), np.uint8(Status.AT_INFINITY), np.uint8(0))
    shape = (L.size, n.size)
    bc = lambda v: np.broadcast_to(v, shape).copy()  # noqa: E731
    return OutputSpeedStats(
        bc(L[:, None]),
        bc(n[None, :]),
        bc(mean),
        bc(std),
        bc(variance),
        bc(cv),
        bc(np.array([t.ratio_min for t in turns])[:, None]),
        bc(np.array([t.ratio_max for t in turns])[:, None]),
        bc(status),
    )


@dataclass(frozen=True, slots=True)
class CvMinimum:
    """The link lengths within the bounds that give the smallest coefficient of variation.

    ``a, b, c, d`` are the lengths (those not bounded keep their given values); ``cv`` the
    coefficient of variation there; ``mean_ratio`` the mean output speed over the input speed;
    ``evaluations`` how many linkages were evaluated.
    """

    a: float
    b: float
    c: float
    d: float
    cv: float
    mean_ratio: float
    evaluations: int


def minimise_cv(
    lengths: dict[str, float],
    bounds: dict[str, tuple[float, float]],
    branch: int = 1,
    *,
    phases: int = 1,
    clutch: str = "freewheel",
    budget: int = 400,
) -> CvMinimum:
    """Minimise c_v over the link lengths named in ``bounds`` (others fixed at ``lengths``).

    A grid of about ``budget`` linkages over the box (only those whose crank turns fully count)
    picks the start; Powell's method (bounded) refines it. Raises :class:`AssemblyError` if no
    linkage in the box lets the crank turn fully with a non-zero mean output speed.
    """
    from scipy.optimize import minimize  # ~1 s to import: on first use, not at every command's start

    _check_clutch(clutch, phases)
    names = [k for k in ("a", "b", "c", "d") if k in bounds]
    unknown = set(bounds) - {"a", "b", "c", "d"}
    if unknown:
        raise AssemblyError(f"bounds name unknown lengths: {', '.join(sorted(unknown))} (use a, b, c, d)")
    for k in names:
        lo, hi = bounds[k]
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo <= hi):
            raise AssemblyError(f"bounds for {k} must satisfy 0 < low <= high, got {lo:g}:{hi:g}")
    count = [0]
    penalty = 1e6

    def cv_of(x) -> float:
        vals = dict(lengths)
        vals.update(zip(names, map(float, x)))
        count[0] += 1
        t = _turn(vals["a"], vals["b"], vals["c"], vals["d"], branch, phases, clutch, grid=256)
        if t.status or t.m1 <= 1e-12:  # cannot turn fully, or passes a toggle
            return penalty
        return float(np.sqrt(max(t.m2 - t.m1 * t.m1, 0.0)) / t.m1)

    if not names:
        x_best = np.zeros(0)
        best = cv_of(x_best)
    else:
        per = max(3, int(round(budget ** (1 / len(names)))))
        axes = [np.linspace(*bounds[k], per) for k in names]
        mesh = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(names))
        values = np.array([cv_of(x) for x in mesh])
        x_best = mesh[int(np.argmin(values))]
        best = float(values.min())
        if best < penalty and any(bounds[k][1] > bounds[k][0] for k in names):
            res = minimize(
                cv_of, x_best, method="Powell", bounds=[bounds[k] for k in names], options={"xtol": 1e-6, "ftol": 1e-10}
            )
            if res.fun < best:
                x_best, best = np.asarray(res.x, float), float(res.fun)
    if best >= penalty:
        raise AssemblyError("no four-bar within the bounds lets the crank turn fully with a non-zero mean output speed")
    vals = dict(lengths)
    vals.update(zip(names, map(float, x_best)))
    t = _turn(vals["a"], vals["b"], vals["c"], vals["d"], branch, phases, clutch)
    cv = float(np.sqrt(max(t.m2 - t.m1 * t.m1, 0.0)) / t.m1)
    return CvMinimum(vals["a"], vals["b"], vals["c"], vals["d"], cv, t.m1, count[0])
