"""Line scanning: conjugate pairs (circle point, centre point) on rays through the pole.

For every ray through the pole, its intersection with the cubic of stationary curvature (the
circle-point curve) is a coupler point whose path has a stationary curvature, i.e. four
infinitesimally close positions on a circle; the Euler–Savary conjugate of that point is the
circle's centre (a point of the centre-point curve). Sweeping the ray angle gives the
one-parameter family of arc candidates at one crank position.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from kinematics.status import Status, check_on_degenerate, raise_on_flags
from synth.pole import ANY_FLAG, C128, F64, FAR, INVALID, RAY_EPS, U16, Pole

__all__ = ["ConjugatePairs", "line_scan"]

#: Elements (instants × rays) per block: the block's temporaries (a reused workspace) stay
#: in the L2 cache. Measured (36 rays, 2-core box): 32768 beats 4096 by ~1.4x (fewer
#: Python-level calls) and whole arrays by ~1.2x.
_CHUNK = 32768
#: A circle point whose denominator Re(ūV) is below CANCEL × the size of the terms that cancel
#: in it (see ``line_scan``) sits on the cubic's asymptote for this instant's own scale: the
#: float64 inputs' relative error (~1e-13 at the largest accepted loop condition) would be
#: amplified over 1/CANCEL, so it is flagged ``CIRCLE_POINT_AT_INFINITY``.
CANCEL = 1e-4
_TANGENT = np.uint16(Status.RAY_ALONG_POLE_TANGENT)
_NORMAL = np.uint16(Status.AT_POLE)
_CIRCLE_INF = np.uint16(Status.CIRCLE_POINT_AT_INFINITY)
_CENTER_INF = np.uint16(Status.CENTER_POINT_AT_INFINITY)


@dataclass(frozen=True, slots=True)
class ConjugatePairs:
    """Circle point, conjugate centre point and osculating radius on each ray, struct of arrays.

    All arrays have the broadcast shape of the pole and the ray angles, except ``alpha``,
    kept as given (broadcastable to it).

    Attributes
    ----------
    alpha : float64
        Ray direction (rad) through the pole, counter-clockwise from the fixed +x axis. A ray
        and its opposite (α + π) are the same line and give the same pair.
    circle_point : complex128
        Circle point (on the cubic of stationary curvature), fixed frame.
    circle_point_uv : complex128
        The same coupler point in the coupler frame (origin A, x-axis along A→B).
    center_point : complex128
        Its conjugate centre point (centre of the osculating circle), fixed frame.
    radius : float64
        Osculating radius |circle_point − center_point| ≥ 0 (length).
    status : uint16
        The instant's flags, plus per ray: ``RAY_ALONG_POLE_TANGENT`` (within RAY_EPS of
        the pole tangent) and ``AT_POLE`` (within RAY_EPS of the pole normal): both points
        are the pole (placeholder: the pole, radius 0); ``CIRCLE_POINT_AT_INFINITY``
        (|r_c| > FAR·L, or the ray within rounding of an asymptote of the cubic, see
        ``CANCEL``: the circle point is a placeholder at the pole, the centre point is kept,
        it is the conjugate of the point at infinity); ``CENTER_POINT_AT_INFINITY``
        (the circle point lies on the inflection circle: the centre point is a placeholder
        at the pole, the circle point is kept). Flagged radii are 0; flagged instants give 0.
    """

    alpha: F64
    circle_point: C128
    circle_point_uv: C128
    center_point: C128
    radius: F64
    status: U16


def line_scan(pole: Pole, alpha: ArrayLike, *, on_degenerate: str = "flag") -> ConjugatePairs:
    """Conjugate pairs on rays through the pole at angles ``alpha``.

    Parameters
    ----------
    pole : Pole
        Instantaneous invariants, e.g. of shape ``(N, M, 1)`` (linkages × crank angles).
    alpha : array_like of float
        Ray angles (rad) from the fixed +x axis, e.g. shape ``(K,)``; broadcast against the
        pole. Rays that differ only along the last axis are the fast path: the per-instant
        coefficients are computed once and reused for every ray.
    on_degenerate : {"flag", "raise"}
        ``"raise"`` raises :class:`~kinematics.status.AssemblyError` if any result is flagged.

    Returns
    -------
    ConjugatePairs
        Shape ``broadcast(pole.shape, alpha.shape)``, e.g. ``(N, M, K)``.

    Raises
    ------
    ValueError
        If a ray angle is not finite.

    Notes
    -----
    For u = e^{iα}, R2 = Re(ū Z2), I2 = Im(ū Z2), R3 = Re(ū Z3) (curvature.md §2):

    .. math::

        r_c = \\frac{3 R_2 I_2}{θ' R_3 + 3θ'^2 I_2 - 3θ'' R_2}
            = \\frac{3 R_2 I_2}{\\operatorname{Re}(\\bar u V)},\\qquad
        r_0 = \\frac{r_c R_2}{R_2 - θ'^2 r_c}
            = \\frac{3 R_2 I_2}{\\operatorname{Re}(\\bar u W)},

    with W = θ′Z3 − 3θ″Z2 and V = W − 3iθ′²Z2 per instant: the second form of r₀ follows by
    substituting r_c, so circle and centre point share one numerator and each ray costs a few
    real multiply-adds. Circle point I + r_c·u, centre point I + r₀·u, radius |r_c − r₀|.
    The cubic has a double point at the pole with tangents along the pole tangent (R2 = 0)
    and the pole normal (I2 = 0): rays along them are flagged.

    References
    ----------
    ``shared/design/curvature.md`` §2, "Cubic of stationary curvature", "Centre point",
    "Line scanning"; the textbook form 1/r = 1/(M sin ψ) + 1/(N cos ψ) is the same curve.
    """
    mode = check_on_degenerate(on_degenerate)
    alpha = np.asarray(alpha, dtype=float)
    if not np.all(np.isfinite(alpha)):
        raise ValueError("ray angles must be finite")
    shape = np.broadcast_shapes(pole.shape, alpha.shape)
    ndim = max(len(shape), 1)
    rays = shape[-1] if shape else 1
    lead = shape[:-1] if shape else ()
    rows = int(np.prod(lead, dtype=np.int64))

    def as_rows(x: np.ndarray) -> np.ndarray:
        """View ``x`` as (rows, 1 | rays) or (1, 1 | rays) without copying the ray axis."""
        x = x.reshape((1,) * (ndim - x.ndim) + x.shape)
        last = x.shape[-1]
        if all(n == 1 for n in x.shape[:-1]):
            return x.reshape(1, last)
        return np.ascontiguousarray(np.broadcast_to(x, lead + (last,))).reshape(rows, last)

    t1, t2 = pole.dtheta[0], pole.dtheta[1]
    z2, z3 = pole.z2, pole.z3
    w = t1 * z3 - 3.0 * t2 * z2
    v = w - 3j * (t1 * t1) * z2
    pw = np.conj(pole.e_theta) * (pole.point - pole.crank_pin)
    thr = (RAY_EPS**2) * (z2 * np.conj(z2)).real
    # |Re(ūV)| ≤ |θ′||Z3| + 3(θ′² + |θ″|)|Z2| bounds the terms that cancel in the denominator
    cancel = CANCEL * (np.abs(t1) * np.abs(z3) + 3.0 * (t1 * t1 + np.abs(t2)) * np.abs(z2))
    inst = {
        "z2x": z2.real, "z2y": z2.imag, "z2x3": 3.0 * z2.real, "z2y3": 3.0 * z2.imag,
        "vx": v.real, "vy": v.imag, "wx": w.real, "wy": w.imag,
        "ix": pole.point.real, "iy": pole.point.imag, "pwx": pw.real, "pwy": pw.imag,
        "ct": pole.e_theta.real, "st": pole.e_theta.imag,
        "thr": thr, "thr9": 9.0 * thr, "reach": np.broadcast_to(FAR * pole.size, pole.shape), "cancel": cancel,
    }
    inst = {k: as_rows(np.asarray(x, float)) for k, x in inst.items()}
    status_in = as_rows(pole.status)
    invalid_in = as_rows((pole.status & INVALID) != 0)
    ux, uy = as_rows(np.cos(alpha)), as_rows(np.sin(alpha))

    zc = np.empty((rows, rays), np.complex128)
    uv = np.empty((rows, rays), np.complex128)
    z0 = np.empty((rows, rays), np.complex128)
    radius = np.empty((rows, rays))
    status = np.empty((rows, rays), np.uint16)
    step = max(1, _CHUNK // max(rays, 1))
    block = (max(min(step, rows), 1), rays)
    ws = {k: np.empty(block) for k in ("r2", "i2", "num", "den", "rc", "r0", "tmp")}
    ws.update({k: np.empty(block, bool) for k in ("m_t", "m_n", "m_c", "m_0", "m_bad")})
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for i in range(0, rows, step):
            sl = slice(i, i + step)
            pick = lambda x: x[sl] if x.shape[0] > 1 else x  # noqa: E731
            c = {k: pick(x) for k, x in inst.items()}
            _scan_block(pick(ux), pick(uy), c, pick(status_in), pick(invalid_in),
                        zc[sl], uv[sl], z0[sl], radius[sl], status[sl], ws)
    out = ConjugatePairs(alpha, zc.reshape(shape), uv.reshape(shape), z0.reshape(shape),
                         radius.reshape(shape), status.reshape(shape))
    if mode == "raise":
        raise_on_flags(out.status, "line scanning", ANY_FLAG)
    return out


def _scan_block(ux, uy, c, status_in, invalid_in, zc, uv, z0, radius, status, ws) -> None:
    """One cache-sized block of :func:`line_scan` in real arithmetic (see its Notes).

    Every temporary lives in the workspace ``ws`` (reused from block to block: no allocator
    traffic, no fresh pages to fault in).
    """
    n = radius.shape[0]
    r2, i2, num, den, rc, r0, tmp = (ws[k][:n] for k in ("r2", "i2", "num", "den", "rc", "r0", "tmp"))
    tangent, normal, circle_inf, center_inf, bad = (ws[k][:n] for k in ("m_t", "m_n", "m_c", "m_0", "m_bad"))

    def dot(cx, cy, out):  # out = ux·cx + uy·cy
        np.multiply(ux, cx, out=out)
        np.multiply(uy, cy, out=tmp)
        out += tmp

    dot(c["z2x"], c["z2y"], r2)
    np.multiply(ux, c["z2y3"], out=i2)  # 3·I2
    np.multiply(uy, c["z2x3"], out=tmp)
    i2 -= tmp
    np.multiply(r2, i2, out=num)
    dot(c["vx"], c["vy"], den)
    np.divide(num, den, out=rc)
    np.abs(den, out=tmp)
    np.less(tmp, c["cancel"], out=circle_inf)
    dot(c["wx"], c["wy"], den)
    np.divide(num, den, out=r0)
    np.multiply(r2, r2, out=tmp)
    np.less_equal(tmp, c["thr"], out=tangent)
    np.multiply(i2, i2, out=tmp)
    np.less_equal(tmp, c["thr9"], out=normal)
    np.abs(rc, out=tmp)
    np.greater(tmp, c["reach"], out=bad)
    circle_inf |= bad
    np.abs(r0, out=tmp)
    np.greater(tmp, c["reach"], out=center_inf)
    np.logical_or(tangent, normal, out=bad)
    bad |= circle_inf
    bad |= center_inf
    status[...] = status_in
    any_bad = bool(bad.any())
    if any_bad:
        valid = ~invalid_in
        for mask, flag in ((tangent, _TANGENT), (normal, _NORMAL), (circle_inf, _CIRCLE_INF), (center_inf, _CENTER_INF)):
            mask &= valid
            status |= mask * flag
        at_pole = tangent | normal
        np.copyto(rc, 0.0, where=at_pole | circle_inf)
        np.copyto(r0, 0.0, where=at_pole | center_inf)
    np.subtract(rc, r0, out=radius)
    np.abs(radius, out=radius)
    for out, r in ((zc, rc), (z0, r0)):
        np.multiply(r, ux, out=out.real)
        out.real += c["ix"]
        np.multiply(r, uy, out=out.imag)
        out.imag += c["iy"]
    # coupler frame: e^{−iθ}(I + r_c·u − A) = e^{−iθ}w_P + r_c·e^{−iθ}u, e^{−iθ}u = (ct·ux + st·uy) + i(ct·uy − st·ux)
    dot(c["ct"], c["st"], r2)
    np.multiply(rc, r2, out=uv.real)
    uv.real += c["pwx"]
    np.multiply(uy, c["ct"], out=i2)
    np.multiply(ux, c["st"], out=tmp)
    i2 -= tmp
    np.multiply(rc, i2, out=uv.imag)
    uv.imag += c["pwy"]
    if any_bad:
        np.copyto(radius, 0.0, where=bad)
    if invalid_in.any():
        inv = np.broadcast_to(invalid_in, radius.shape)
        for arr in (zc, uv, z0):
            np.copyto(arr, 0j, where=inv)
        np.copyto(radius, 0.0, where=inv)
