"""Loop-closure geometry shared by every linkage kernel: the closing triangle of a binary
loop (circle–circle intersection) and its derivative system, the intersection of two lines,
the vertex of a sampled extreme and the folded transmission angle.

One source of truth for each formula and one set of thresholds: the four-bar
(:mod:`kinematics.fourbar`), the Assur dyads (:mod:`kinematics.assur.dyads`), the six-bar
simulation (:mod:`synth.mechanism.sixbar`), the dyad fits (:mod:`synth.mechanism.dyad`) and the segment search
(:mod:`synth.segment_search.segments`) all call these kernels.

Points and directions are complex numbers (x + iy), angles radians. Every kernel broadcasts
its inputs and never returns NaN/inf: degenerate geometry carries a
:class:`~kinematics.status.Status` flag (``uint8``) and a finite placeholder.
"""

from __future__ import annotations

import math
from contextlib import nullcontext
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinematics.status import Status, assembly_status

__all__ = [
    "COINCIDENT_EPS",
    "PARALLEL_EPS",
    "TOGGLE_EPS",
    "CircleIntersection",
    "LineIntersection",
    "ParabolaVertex",
    "circle_intersection",
    "circle_intersection_xy",
    "line_intersection",
    "parabola_vertex",
    "sampled_extreme",
    "transmission_fold",
    "wrap_angle",
]

F64 = NDArray[np.float64]
C128 = NDArray[np.complex128]

#: |sin| of the angle between the two links at their joint below which the loop is at a toggle
#: (the two circles touch): the derivative system is singular there. At 1e-12 the rates
#: ∝ 1/sin would be ≥ 1e12 × the input rate — no mechanism runs there.
TOGGLE_EPS = 1e-12
#: Distance between the two circle centres below this × (l1 + l2): the centres coincide and the
#: direction of the loop is undetermined (counted as not assemblable). The centres are known to
#: ~1e-16 of the link lengths, so below 1e-12 the direction would carry errors above 1e-4 rad.
COINCIDENT_EPS = 1e-12
#: Where l1 + l2 lies outside [1/HERON_SAFE, HERON_SAFE], or the centres' distance r beyond it,
#: the loop is solved in units of max(l1 + l2, r): Heron's product of four lengths
#: over/underflows float64 beyond about 1e±77. (r > l1 + l2 only where the loop cannot close.)
HERON_SAFE = 1e60
#: |sin| of the angle between two (unit) line directions below which they count as parallel.
#: The intersection's position error grows like (rounding of the directions)/sin ≈ 1e-16/sin of
#: its distance: 1e-9 keeps it within ~1e-7, and an intersection that close to parallel lies a
#: billion offsets away — no pivot, no assembly. (Was 1e-12, 1e-9 and 1e-6 in three copies; the
#: callers that need a nearer bound add a distance limit of their own.)
PARALLEL_EPS = 1e-9

_NA = np.uint8(Status.NOT_ASSEMBLABLE)


def _real(x: ArrayLike) -> np.ndarray:
    """A floating array, keeping an extended precision (longdouble) as given."""
    x = np.asarray(x)
    return x if x.dtype.kind == "f" else x.astype(float)


def _phasor(x: F64, y: F64) -> C128:
    out = np.empty(np.broadcast(x, y).shape, np.result_type(x, y, np.complex64))  # complex128 or clongdouble
    out.real, out.imag = x, y
    return out


@dataclass(frozen=True, slots=True)
class CircleIntersection:
    """The closing point of a binary loop: |X − C₁| = l1, |X − C₂| = l2, struct of arrays.

    With R = C₂ − C₁, the point is X = C₁ + l1·e1 = C₂ + l2·e2. The unit phasors are kept as
    their real and imaginary parts (the four-bar's hot loop works on those); :attr:`e1` and
    :attr:`e2` give them as complex numbers.

    Attributes
    ----------
    cos1, sin1 : float64
        e1 = cos1 + i·sin1, unit phasor from centre 1 to the point (the four-bar's e^{iθ}).
    cos2, sin2 : float64 or None
        e2 = cos2 + i·sin2, unit phasor from centre 2 to the point (the four-bar's e^{iγ});
        None when computed with ``rates=False``.
    l1, l2 : float64
        The radii, as given (broadcastable).
    height : float64
        r·sin β = −l2·sin(θ − γ), signed by the branch (β: the angle at centre 1 between R and
        X − C₁; θ, γ the arguments of e1, e2). Zero at a toggle.
    status : uint8
        ``NOT_ASSEMBLABLE`` where |R| is outside [|l1 − l2|, l1 + l2] or the centres coincide;
        otherwise ``TOGGLE`` where |sin(θ − γ)| < ``TOGGLE_EPS``. Flagged positions hold finite
        placeholders: the stretched or folded configuration (cos β clipped to ±1), unit phasors.
    k1, k2 : float64 or None
        Cramer factors of :meth:`rates`, (l2/l1)/height and 1/height (0 where flagged); None
        when computed with ``rates=False``.
    """

    cos1: F64
    sin1: F64
    cos2: F64 | None
    sin2: F64 | None
    l1: F64
    l2: F64
    height: F64
    status: NDArray[np.uint8]
    k1: F64 | None = None
    k2: F64 | None = None

    @property
    def e1(self) -> C128:
        """Unit phasor e^{iθ} from centre 1 to the point."""
        return _phasor(self.cos1, self.sin1)

    @property
    def e2(self) -> C128:
        """Unit phasor e^{iγ} from centre 2 to the point (needs ``rates=True``)."""
        if self.cos2 is None:
            raise ValueError("e2 needs a circle intersection computed with rates=True")
        return _phasor(self.cos2, self.sin2)

    @property
    def sin_relative(self) -> F64:
        """sin(θ − γ), the sine of the angle from link 2 to link 1 at their joint."""
        return -self.height / self.l2

    @property
    def transmission(self) -> F64:
        """Transmission angle at the joint, folded to [0, π/2] (rad; see :func:`transmission_fold`)."""
        return transmission_fold(self.e1 * np.conj(self.e2))

    def rates(self, q: ArrayLike, out: tuple[F64, F64] | None = None) -> tuple[F64, F64]:
        """Solve the differentiated loop i·l1·x·e1 − i·l2·y·e2 = q for the angular rates (x, y).

        The loop C₁ + l1·e^{iθ} − l2·e^{iγ} − C₂ = 0 differentiated k times with respect to the
        input gives this linear system in x = θ⁽ᵏ⁾, y = γ⁽ᵏ⁾; q (complex) collects the known
        terms (q = R′ for k = 1, docs/curvature.md §1). Cramer's rule:

        .. math:: x = -\\frac{\\operatorname{Re}(q\\,\\bar e_2)}{l_1 \\sin(θ − γ)},\\quad
                  y = -\\frac{\\operatorname{Re}(q\\,\\bar e_1)}{l_2 \\sin(θ − γ)}.

        Both are 0 where the position is flagged (toggle or not assemblable). ``out`` may give
        two float64 arrays of the broadcast shape to write into.
        """
        q = np.asarray(q)
        return self.rates_xy(q.real, q.imag, out)

    def rates_xy(self, qx: F64, qy: F64, out: tuple[F64, F64] | None = None) -> tuple[F64, F64]:
        """:meth:`rates` with q given as its real and imaginary parts."""
        if self.k1 is None:
            raise ValueError("rates need a circle intersection computed with rates=True")
        x_out, y_out = (None, None) if out is None else out
        x = np.multiply(qx * self.cos2 + qy * self.sin2, self.k1, out=x_out)
        y = np.multiply(qx * self.cos1 + qy * self.sin1, self.k2, out=y_out)
        return x, y


def circle_intersection(
    R: ArrayLike, l1: ArrayLike, l2: ArrayLike, branch: ArrayLike, *, rates: bool = True
) -> CircleIntersection:
    """Closing point of a binary loop: the intersection of two circles, on one branch.

    Parameters
    ----------
    R : complex array_like
        C₂ − C₁, centre 2 seen from centre 1 (any length unit).
    l1, l2 : array_like
        Radii about C₁ and C₂ (> 0, same unit), broadcast against ``R``.
    branch : array_like of {+1, −1}
        +1 puts the point to the left of the directed line C₁ → C₂ (the four-bar convention of
        :class:`~kinematics.status.Branch`).
    rates : bool
        Also compute e2 and the factors of :meth:`CircleIntersection.rates` (False: position
        of link 1 and status only, the cheapest solve).

    Returns
    -------
    CircleIntersection

    Notes
    -----
    With r = |R|: e1 = (R/r)·(cos β + i·branch·sin β), cos β = (r² + l1² − l2²)/(2·l1·r), and
    the height in Heron's form,

    .. math:: 4 l_1^2 r^2 \\sin^2β = (r + l_2 − l_1)(l_1 + l_2 − r)(r − l_2 + l_1)(r + l_1 + l_2),

    which is an exact zero at a toggle and negative where the loop cannot close, without the
    cancellation of √(1 − cos²β). It is kept factored: the expanded
    ((l1+l2)² − r²)(r² − (l1−l2)²) measured up to 1.5× larger four-bar derivative errors on
    crank-rockers and near change points (against longdouble). e2 = (l1·e1 − R)/l2, and
    sin(θ − γ) = −r·sin β / l2.

    References
    ----------
    ``docs/curvature.md`` §1; I. I. Artobolevsky, *Theory of Mechanisms and Machines*, § 11.
    """
    R = np.asarray(R, dtype=np.complex128)
    return circle_intersection_xy(R.real, R.imag, l1, l2, branch, rates=rates)


def circle_intersection_xy(
    rx: ArrayLike, ry: ArrayLike, l1: ArrayLike, l2: ArrayLike, branch: ArrayLike, *, rates: bool = True
) -> CircleIntersection:
    """:func:`circle_intersection` with R given as its real and imaginary parts (float64, or
    longdouble for a reference computation: the precision of the inputs is kept)."""
    rx, ry, l1_in, l2_in, branch = (_real(x) for x in (rx, ry, l1, l2, branch))
    l1, l2 = l1_in, l2_in
    r2 = rx * rx + ry * ry
    r = np.sqrt(r2)
    s12 = l1 + l2
    u = None
    # (the lengths' test on their own shape, the distance's as one reduction: the common case
    # adds no full-size pass)
    if np.any((s12 > HERON_SAFE) | (s12 < 1.0 / HERON_SAFE)) or np.max(r, initial=0.0) > HERON_SAFE:
        span = np.maximum(s12, r)  # s12 wherever the loop can close
        scaled = (span > HERON_SAFE) | (s12 < 1.0 / HERON_SAFE)
        # lengths in units of the span there: the same angles and status as at unit scale, the
        # height and rate factors scaled back at the end (elsewhere the bits are unchanged).
        # Heron's product of four lengths over/underflows beyond ~1e±77 (a far centre with
        # short links overflowed it), and 1/(2·l1·r) of a loop 1e-150 long whose centres are
        # 1e-9 of it apart overflowed (NaN at status OK).
        u = np.where(scaled, span, 1.0)
        rx, ry, l1, l2 = rx / u, ry / u, l1 / u, l2 / u
        r2 = rx * rx + ry * ry
        r = np.sqrt(r2)
        s12 = l1 + l2
    d21 = l2 - l1  # r + (l1 − l2) is r − (l2 − l1) exactly
    heron = (r + d21) * (s12 - r) * (r - d21) * (r + s12)
    root = np.sqrt(np.maximum(heron, 0.0))
    coincident = r <= COINCIDENT_EPS * s12
    bad = (heron < 0) | coincident
    any_bad = bool(bad.any())
    r = np.where(coincident, 1.0, r)
    # finite wherever the loop closes; where it cannot and its links are ~1e100 apart or more,
    # cos β overflows (clipped below) and sin β = 0·∞ (0 below)
    with np.errstate(over="ignore", invalid="ignore") if any_bad else nullcontext():
        inv_2r = 0.5 / (l1 * r)
        cb = (r2 - d21 * s12) * inv_2r  # l1² − l2² = −(l2 − l1)(l1 + l2), without cancellation
        sb = root * (branch * inv_2r)
    if any_bad:
        # placeholders: the stretched or folded configuration, along +x where the centres meet
        cb = np.where(bad, np.clip(cb, -1.0, 1.0), cb)
        if not np.isfinite(np.sum(sb)):  # only where the loop cannot close (above); one pass
            sb = np.where(np.isfinite(sb), sb, 0.0)
        rx, ry = np.where(coincident, 1.0, rx), np.where(coincident, 0.0, ry)
    inv_r = 1.0 / r
    c1 = (rx * cb - ry * sb) * inv_r
    s1 = (rx * sb + ry * cb) * inv_r
    height = r * sb
    toggle = np.abs(height) < TOGGLE_EPS * l2
    status = assembly_status(bad, toggle)
    if not rates:
        return CircleIntersection(c1, s1, None, None, l1_in, l2_in, height if u is None else height * u, status)
    inv_l2 = 1.0 / l2
    c2 = (l1 * c1 - rx) * inv_l2
    s2 = (l1 * s1 - ry) * inv_l2
    if any_bad:
        # |l1·e1 − R| ≠ l2 where the loop does not close: back onto the unit circle (+x if 0)
        mag = np.hypot(c2, s2)
        zero = bad & (mag == 0)
        mag = np.where(bad & ~zero, mag, 1.0)
        c2, s2 = np.where(zero, 1.0, c2 / mag), s2 / mag
    k2 = 1.0 / np.where(status != 0, np.inf, height)  # height = −l2·sin(θ − γ)
    k1 = (l2 / l1) * k2
    if u is not None:
        height, k1, k2 = height * u, k1 / u, k2 / u
    return CircleIntersection(c1, s1, c2, s2, l1_in, l2_in, height, status, k1, k2)


class LineIntersection(NamedTuple):
    """Where two lines P₁ + t₁·U₁ and P₂ + t₂·U₂ meet: the parameters along each line and a
    ``uint8`` status (``NOT_ASSEMBLABLE`` where parallel; then t₁ = t₂ = 0)."""

    t1: F64
    t2: F64
    status: NDArray[np.uint8]

    @property
    def parallel(self) -> NDArray[np.bool_]:
        return self.status != 0


def line_intersection(
    p1: ArrayLike, u1: ArrayLike, p2: ArrayLike, u2: ArrayLike, *, parallel_eps: float = PARALLEL_EPS
) -> LineIntersection:
    """Intersection of the lines p1 + t₁·u1 and p2 + t₂·u2 (complex points, unit directions);
    lines closer to parallel than ``parallel_eps`` (|sin| of their angle) do not meet.

    Notes
    -----
    The cross product (Im(ā·b)) of p1 + t₁u1 = p2 + t₂u2 with u2, then with u1:

    .. math:: t_1 = \\frac{\\operatorname{Im}(\\overline{(p_2 − p_1)}\\,u_2)}{\\operatorname{Im}(\\bar u_1 u_2)},\\quad
              t_2 = \\frac{\\operatorname{Im}(\\overline{(p_2 − p_1)}\\,u_1)}{\\operatorname{Im}(\\bar u_1 u_2)},

    Im(ū₁u₂) = sin(δ₂ − δ₁); below ``parallel_eps`` in magnitude the lines are parallel.
    """
    p1, u1, p2, u2 = (np.asarray(x, dtype=np.complex128) for x in (p1, u1, p2, u2))
    den = (np.conj(u1) * u2).imag
    parallel = np.abs(den) < parallel_eps
    safe = np.where(parallel, 1.0, den)
    gap = np.conj(p2 - p1)
    t1 = np.where(parallel, 0.0, (gap * u2).imag / safe)
    t2 = np.where(parallel, 0.0, (gap * u1).imag / safe)
    return LineIntersection(t1, t2, np.where(parallel, _NA, np.uint8(0)).astype(np.uint8))


class ParabolaVertex(NamedTuple):
    """Vertex of the parabola through three equally spaced samples (y₋, y₀, y₊).

    ``offset``: abscissa of the vertex from the middle sample, in sample steps (not clipped);
    ``rise``: vertex value − y₀ (> 0 above a maximum, < 0 below a minimum);
    ``curvature``: the second difference y₋ − 2y₀ + y₊ (< 0: a maximum, > 0: a minimum).
    offset and rise are 0 where the curvature is 0 (a straight line has no vertex).
    """

    offset: F64
    rise: F64
    curvature: F64


def parabola_vertex(y_minus: ArrayLike, y0: ArrayLike, y_plus: ArrayLike) -> ParabolaVertex:
    """Vertex of the parabola through (−1, y₋), (0, y₀), (+1, y₊): refines a sampled extreme.

    Notes
    -----
    With the second difference D = y₋ − 2y₀ + y₊:

    .. math:: δ = \\frac{y_- − y_+}{2D},\\qquad y(δ) − y_0 = −\\frac{(y_- − y_+)^2}{8D}.

    For a smooth function sampled at step h the vertex is within O(h³·y‴) of the true
    extreme's abscissa (times h) and O(h⁴) of its value. Callers keep the vertex only where
    the sign of D matches the extreme they look for (D < 0 for a maximum).
    """
    ym, y0, yp = (np.asarray(x, dtype=float) for x in (y_minus, y0, y_plus))
    den = ym - 2 * y0 + yp
    curved = den != 0
    safe = np.where(curved, den, 1.0)
    diff = ym - yp
    offset = np.where(curved, 0.5 * diff / safe, 0.0)
    rise = np.where(curved, -(diff**2 / (8 * safe)), 0.0)
    return ParabolaVertex(offset, rise, den)


def sampled_extreme(y: ArrayLike, sign: int = 1) -> tuple[F64, NDArray[np.int64]]:
    """Maximum (``sign`` +1) or minimum (−1) along the last axis of samples of a smooth
    periodic function, refined to the vertex of the parabola through the extreme sample and
    its two cyclic neighbours (:func:`parabola_vertex`) where it bends the right way.

    Returns (value, index of the extreme sample), of the leading shape.
    """
    y = np.asarray(y, dtype=float)
    m = y.shape[-1]
    k = np.argmax(sign * y, axis=-1)[..., None]
    y0 = np.take_along_axis(y, k, -1)[..., 0]
    ym = np.take_along_axis(y, (k - 1) % m, -1)[..., 0]
    yp = np.take_along_axis(y, (k + 1) % m, -1)[..., 0]
    vertex = parabola_vertex(ym, y0, yp)
    return y0 + np.where(sign * vertex.curvature < 0, vertex.rise, 0.0), k[..., 0]


def transmission_fold(relative: ArrayLike) -> F64:
    """Transmission angle folded to [0, π/2] (rad; π/2 is ideal) from the relative phasor of
    the two links at their joint, e_a·conj(e_b) (unit magnitude).

    μ = arccos Re(e_a·ē_b) ∈ [0, π]; μ and π − μ transmit equally well, so the design quality
    is min(μ, π − μ).

    Notes
    -----
    arccos of the cosine loses about half the digits near μ = 0 (an error of ~1e-8 rad at a
    toggle), which no design figure (degrees, one decimal) can see; atan2(|sin μ|, |cos μ|)
    would not, but differs from it in the 13th digit elsewhere and would change every stored
    transmission angle of an atlas (its content digest). Change both together or neither.
    """
    rel = np.asarray(relative, dtype=np.complex128)
    mu = np.arccos(np.clip(rel.real, -1.0, 1.0))
    return np.minimum(mu, np.pi - mu)


def wrap_angle(x):
    """x folded into [−π, π) (rad)."""
    return np.mod(np.asarray(x) + math.pi, 2.0 * math.pi) - math.pi
