"""Line scanning: conjugate pairs (circle point, centre point) on rays through the pole.

For every ray through the pole, its intersection with the cubic of stationary curvature (the
circle-point curve) is a coupler point whose path has a stationary curvature, i.e. four
infinitesimally close positions on a circle; the Euler–Savary conjugate of that point is the
circle's centre (a point of the centre-point curve). Sweeping the ray angle gives the
one-parameter family of arc candidates at one crank position.

Accuracy flags
--------------
A conjugate pair is an explicit skip unless its first-order error estimate meets the
project's accuracy bar ``ACCURACY`` (1e-9, dimensionless, relative to the crank as in
``dwell bench stability``). The estimate propagates the rounding-error estimates of θ′, θ″, θ‴
(``Pole.dtheta_error``, see ``synth.curvature.pole``) and a few units of rounding of this module's own
arithmetic through r_c = N/Re(ūV) and r₀ = N/Re(ūW) (N = 3R2·I2, see ``line_scan``):

* centre point, measured along its ray from the pole: δr₀ = δI + (δN + |r₀|·δD₀)/|Re(ūW)|
  against ``ACCURACY`` × max(a, radius), where δI = a·δθ′/θ′² is the error of the pole itself
  (a pole 10³ cranks away is known to ~1e-10 of a crank only: the conjugate of a circle point
  near the linkage is then off by that much) and δN, δD₀ bound the error of N and Re(ūW)
  (per instant: the magnitudes of their terms times the errors of their factors);
* circle point, measured as its distance from the cubic: (δN + |r_c|·δD_c)/|∇F| against
  ``ACCURACY`` × max(a, |p|), F(r, α) = r·Re(ūV) − N the cubic in polar coordinates about the
  pole (|∇F| ≥ |Re(ūV)|: near an asymptote the point runs along the cubic, not off it). The
  pole's own error is left out here: θ′ enters the pole and the ray together, and the point
  near the linkage does not inherit it (only δθ′/|θ′| relative, which is added).

A failing circle point is flagged ``CIRCLE_POINT_AT_INFINITY`` and a failing centre point
``CENTER_POINT_AT_INFINITY``, as for ``CANCEL``: at this instant's precision the point is not
placed better than a point at infinity would be, and the other point of the pair is kept.
Measured (``dwell bench stability``, seeds 0–4 × 100 000 cases): the true residual over the
estimate is at most 0.92 (circle points) and 0.66 (centre points); with the flags the largest
unflagged residual is ~4e-11 (circle) and ~3.4e-10 (centre), against 1.8e-7 and 3.4e-8 without
them. On ordinary crank-rockers about one random ray in a thousand is flagged, nearly all of
them centre points of instants whose pole is 10³ cranks or more away.

The estimate costs a few operations per ray: every ray whose denominator is below a
per-instant gate (chosen so that every other ray provably passes, see ``_gates``) is collected
and the estimate is evaluated on those candidates only, after the scan.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinematics.status import Status, check_on_degenerate, raise_on_flags
from synth.curvature.pole import Pole
from synth.types import ANY_FLAG, C128, F64, FAR, INVALID, RAY_EPS, U16

__all__ = ["ACCURACY", "ConjugatePairs", "line_scan"]

#: Elements (instants × rays) per block: the block's temporaries (a reused workspace) stay
#: in the L2 cache. Measured (36 rays, 2-core box): 32768 beats 4096 by ~1.4x (fewer
#: Python-level calls) and whole arrays by ~1.2x.
_CHUNK = 32768
#: A circle point whose denominator Re(ūV) is below CANCEL × the size of the terms that cancel
#: in it (see ``line_scan``) sits on the cubic's asymptote for this instant's own scale: the
#: float64 inputs' relative error (~1e-13 at the largest accepted loop condition) would be
#: amplified over 1/CANCEL, so it is flagged ``CIRCLE_POINT_AT_INFINITY``.
CANCEL = 1e-4
#: Accuracy bar of a conjugate pair, relative to max(crank, the point's scale): a pair whose
#: first-order error estimate exceeds it is flagged (module notes, "Accuracy flags").
ACCURACY = 1e-9
#: Rounding of this module's own arithmetic (dot products, a few operations deep), in the
#: error estimate: a few units of float64 rounding relative to the terms.
_ROUND = 4.0 * float(np.finfo(float).eps)
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
        ``CANCEL``, or the circle point's error estimate above ``ACCURACY``: the circle point
        is a placeholder at the pole, the centre point is kept, it is the conjugate of the
        point at infinity); ``CENTER_POINT_AT_INFINITY`` (the circle point lies on the
        inflection circle, or the centre point's error estimate is above ``ACCURACY``: the
        centre point is a placeholder at the pole, the circle point is kept). Flagged radii
        are 0; flagged instants give 0.
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
    For u = e^{iα}, R2 = Re(ū Z2), I2 = Im(ū Z2), R3 = Re(ū Z3) (docs/curvature.md §2):

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
    ``docs/curvature.md`` §2, "Cubic of stationary curvature", "Centre point",
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
    abs_z2, abs_z3 = np.abs(z2), np.abs(z3)
    thr = (RAY_EPS**2) * (z2 * np.conj(z2)).real
    # |Re(ūV)| ≤ |θ′||Z3| + 3(θ′² + |θ″|)|Z2| bounds the terms that cancel in the denominator
    cancel = CANCEL * (np.abs(t1) * abs_z3 + 3.0 * (t1 * t1 + np.abs(t2)) * abs_z2)
    err = _error_terms(pole, abs_z2, abs_z3)
    gate_c, gate_0 = _gates(err, abs_z2, cancel, (pole.status & INVALID) != 0)
    inst = {
        "z2x": z2.real,
        "z2y": z2.imag,
        "z2x3": 3.0 * z2.real,
        "z2y3": 3.0 * z2.imag,
        "vx": v.real,
        "vy": v.imag,
        "wx": w.real,
        "wy": w.imag,
        "ix": pole.point.real,
        "iy": pole.point.imag,
        "pwx": pw.real,
        "pwy": pw.imag,
        "ct": pole.e_theta.real,
        "st": pole.e_theta.imag,
        "thr": thr,
        "thr9": 9.0 * thr,
        "reach": np.broadcast_to(FAR * pole.size, pole.shape),
        "cancel": cancel,
        "gate_c": gate_c,
        "gate_0": gate_0,
        **{k: x for k, x in err.items() if k != "inv_t1"},
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
    ws.update({k: np.empty(block, bool) for k in ("m_t", "m_n", "m_c", "m_0", "m_bad", "m_cand")})
    candidates = []
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for i in range(0, rows, step):
            sl = slice(i, i + step)
            pick = lambda x: x[sl] if x.shape[0] > 1 else x  # noqa: E731
            c = {k: pick(x) for k, x in inst.items()}
            found = _scan_block(
                pick(ux),
                pick(uy),
                c,
                pick(status_in),
                pick(invalid_in),
                zc[sl],
                uv[sl],
                z0[sl],
                radius[sl],
                status[sl],
                ws,
            )
            if found is not None:
                candidates.append(found + i * rays)
        if candidates:
            _refine(np.concatenate(candidates), ux, uy, inst, zc, uv, z0, radius, status)
    out = ConjugatePairs(
        alpha, zc.reshape(shape), uv.reshape(shape), z0.reshape(shape), radius.reshape(shape), status.reshape(shape)
    )
    if mode == "raise":
        raise_on_flags(out.status, "line scanning", ANY_FLAG)
    return out


def _error_terms(pole: Pole, abs_z2, abs_z3) -> dict[str, F64]:
    """Per-instant ingredients of the error estimates (module notes, "Accuracy flags").

    dz2: error of Z2 from θ″ (Z2 = −E(1 − θ′ + iθ″/θ′)) and rounding; b0, bc: bounds of the
    error of Re(ūW) and Re(ūV) on any ray (|R2|, |R3| ≤ |Z2|, |Z3|); pole_err: error of the
    pole, a·δθ′/θ′²; rel1: δθ′/|θ′|; a: the crank; inv_t1: 1/|θ′|. θ′ enters the pole and the
    ray's values together, so its error is in pole_err and rel1 only. 0 where the instant is
    flagged.
    """
    t1, t2 = pole.dtheta[0], pole.dtheta[1]
    e1, e2, e3 = pole.dtheta_error
    a = np.abs(pole.crank_pin)
    at1, at2 = np.abs(t1), np.abs(t2)
    inv_t1 = np.divide(1.0, at1, out=np.zeros_like(at1 * a), where=((pole.status & INVALID) == 0) & (at1 > 0))
    round_z2 = _ROUND * abs_z2
    dz2 = a * e2 * inv_t1 + round_z2
    dz3 = a * (3.0 * e2 + e3 * inv_t1) + _ROUND * abs_z3
    b0 = at1 * (dz3 + _ROUND * abs_z3) + 3.0 * (at2 * (dz2 + round_z2) + abs_z2 * e2)
    bc = b0 + 3.0 * (t1 * t1) * (dz2 + round_z2)
    rel1 = e1 * inv_t1
    return {"a": a, "dz2": dz2, "b0": b0, "bc": bc, "pole_err": a * rel1 * inv_t1, "rel1": rel1, "inv_t1": inv_t1}


def _gates(err: dict[str, F64], abs_z2, cancel, invalid) -> tuple[F64, F64]:
    """Per-instant gates on |Re(ūV)| and |Re(ūW)|: a ray below either one is a candidate.

    Every ray above both gates passes both accuracy tests of ``_refine``, so only the
    candidates are evaluated. With δN ≤ A = 3√2|Z2|·dz2, |N| ≤ 1.5|Z2|², the scale
    s ≥ a and |r| ≤ K·s for a per-instant K, each estimate is at most

        s·(pole_err/a + (A/a + K·δD)/|D| + rel1)

    (circle points: |∇F| ≥ |D|, no pole_err), below ``ACCURACY``·s once
    |D| ≥ (A/a + K·δD)/(ACCURACY − rel1 − pole_err/a). K = 1 + 1/|θ′| for circle points
    (|p| ≥ |r_c| − |w_P|, |w_P| = a/|θ′|); K = 1 + √(|Z2|/a)/|θ′| for centre points (radius =
    |r₀|·3θ′²|I2|/|Re(ūV)| ≥ |r₀|·3θ′²|I2|/(|Re(ūW)| + 3θ′²|I2|) and |r₀| ≤ 3|Z2||I2|/|Re(ūW)|:
    the smaller of |r₀|/a and |r₀|/radius − 1 is at most their geometric mean). Where the
    denominator is not positive (a pole 10³ cranks away or more) every ray is a candidate.
    The circle-point gate is at least ``cancel``: the CANCEL flag is decided on the candidates.
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        a, inv_t1, rel1 = err["a"], err["inv_t1"], err["rel1"]
        a_rel = (3.0 * np.sqrt(2.0)) * abs_z2 * err["dz2"] / a
        room_c = ACCURACY - rel1
        room_0 = room_c - err["pole_err"] / a
        gate_c = np.maximum(cancel, (a_rel + (1.0 + inv_t1) * err["bc"]) / room_c)
        gate_0 = (a_rel + (1.0 + np.sqrt(abs_z2 / a) * inv_t1) * err["b0"]) / room_0
    gate_c = np.where(invalid, 0.0, np.where(room_c > 0.0, gate_c, np.inf))
    gate_0 = np.where(invalid, 0.0, np.where(room_0 > 0.0, gate_0, np.inf))
    return gate_c, gate_0


def _refine(idx, ux, uy, inst, zc, uv, z0, radius, status) -> None:
    """Decide CANCEL and the accuracy flags on the candidate rays (flat indices ``idx``).

    Recomputes each candidate's values as ``_scan_block`` does, evaluates the error estimates
    of the module notes (the centre point's on the rays below ``gate_0``, the circle point's
    on those below ``gate_c``) and sets flags and placeholders (circle point: the pole,
    centre point: the pole, radius 0) on the pairs that fail.
    """
    row_all, col_all = np.divmod(idx, radius.shape[1])

    def at(x, j=None):  # values of x (rows | 1, rays | 1, contiguous) at the candidates [j]
        if x.shape[0] > 1:
            pick = idx if x.shape[1] > 1 else row_all
        else:
            pick = col_all if x.shape[1] > 1 else col_all * 0
        return np.take(x.reshape(-1), pick if j is None else pick[j])

    u_x, u_y = at(ux), at(uy)
    r2 = u_x * at(inst["z2x"]) + u_y * at(inst["z2y"])
    i2_3 = u_x * at(inst["z2y3"]) - u_y * at(inst["z2x3"])  # 3·I2
    num = r2 * i2_3
    vx, vy = at(inst["vx"]), at(inst["vy"])
    d_c = u_x * vx + u_y * vy
    d_0 = u_x * at(inst["wx"]) + u_y * at(inst["wy"])
    rc = num / d_c
    abs_c = np.abs(d_c)
    circle = abs_c < at(inst["cancel"])
    ok = (np.take(status.reshape(-1), idx) & (_TANGENT | _NORMAL)) == 0
    center = np.zeros(idx.shape, bool)
    # centre point, along the ray from the pole
    j = np.flatnonzero(ok & (np.abs(d_0) < at(inst["gate_0"])))
    if j.size:
        r0 = num[j] / d_0[j]
        a, n_err = at(inst["a"], j), (3.0 * np.abs(r2[j]) + np.abs(i2_3[j])) * at(inst["dz2"], j)
        scale = np.maximum(a, np.abs(rc[j] - r0))
        est = at(inst["pole_err"], j) + (n_err + np.abs(r0) * at(inst["b0"], j)) / np.abs(d_0[j])
        center[j] = ~(est <= (ACCURACY - at(inst["rel1"], j)) * scale)  # NaN (0/0) fails too
    # circle point, distance from the cubic F = r·Re(ūV) − N, ∂F/∂α = r·Im(ūV) − 3(I2² − R2²)
    j = np.flatnonzero(ok & (abs_c < at(inst["gate_c"])))
    if j.size:
        r, ux_j, uy_j = rc[j], u_x[j], u_y[j]
        a, n_err = at(inst["a"], j), (3.0 * np.abs(r2[j]) + np.abs(i2_3[j])) * at(inst["dz2"], j)
        dn = (i2_3[j] * i2_3[j]) / 3.0 - 3.0 * (r2[j] * r2[j])
        grad = np.hypot(d_c[j], (ux_j * vy[j] - uy_j * vx[j]) - dn / r)
        ct, st = at(inst["ct"], j), at(inst["st"], j)
        px = at(inst["pwx"], j) + r * (ct * ux_j + st * uy_j)
        py = at(inst["pwy"], j) + r * (ct * uy_j - st * ux_j)
        scale = np.maximum(a, np.hypot(px, py))
        est = (n_err + np.abs(r) * at(inst["bc"], j)) / grad
        circle[j] |= ~(est <= (ACCURACY - at(inst["rel1"], j)) * scale)
    if not (circle.any() or center.any()):
        return
    flat = status.reshape(-1)
    flat[idx] |= np.where(circle, _CIRCLE_INF, np.uint16(0)) | np.where(center, _CENTER_INF, np.uint16(0))
    hit = np.flatnonzero(circle)  # placeholders: the pole, in both frames
    if hit.size:
        zc.reshape(-1)[idx[hit]] = at(inst["ix"], hit) + 1j * at(inst["iy"], hit)
        uv.reshape(-1)[idx[hit]] = at(inst["pwx"], hit) + 1j * at(inst["pwy"], hit)
    hit = np.flatnonzero(center)
    if hit.size:
        z0.reshape(-1)[idx[hit]] = at(inst["ix"], hit) + 1j * at(inst["iy"], hit)
    radius.reshape(-1)[idx[circle | center]] = 0.0


def _scan_block(ux, uy, c, status_in, invalid_in, zc, uv, z0, radius, status, ws) -> NDArray[np.intp] | None:
    """One cache-sized block of :func:`line_scan` in real arithmetic (see its Notes).

    Every temporary lives in the workspace ``ws`` (reused from block to block: no allocator
    traffic, no fresh pages to fault in). Returns the flat indices (within the block) of the
    candidate rays for :func:`_refine`, or None.
    """
    n = radius.shape[0]
    r2, i2, num, den, rc, r0, tmp = (ws[k][:n] for k in ("r2", "i2", "num", "den", "rc", "r0", "tmp"))
    tangent, normal, circle_inf, center_inf, bad, cand = (
        ws[k][:n] for k in ("m_t", "m_n", "m_c", "m_0", "m_bad", "m_cand")
    )

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
    # candidates for the accuracy flags (and for CANCEL, gate_c ≥ cancel): see _gates
    np.abs(den, out=tmp)
    np.less(tmp, c["gate_c"], out=cand)
    dot(c["wx"], c["wy"], den)
    np.divide(num, den, out=r0)
    np.abs(den, out=tmp)
    np.less(tmp, c["gate_0"], out=bad)
    cand |= bad
    np.multiply(r2, r2, out=tmp)
    np.less_equal(tmp, c["thr"], out=tangent)
    np.multiply(i2, i2, out=tmp)
    np.less_equal(tmp, c["thr9"], out=normal)
    np.abs(rc, out=tmp)
    np.greater(tmp, c["reach"], out=circle_inf)
    np.abs(r0, out=tmp)
    np.greater(tmp, c["reach"], out=center_inf)
    np.logical_or(tangent, normal, out=bad)
    bad |= circle_inf
    bad |= center_inf
    status[...] = status_in
    any_bad = bool(bad.any())
    if any_bad:
        valid = ~invalid_in
        for mask, flag in (
            (tangent, _TANGENT),
            (normal, _NORMAL),
            (circle_inf, _CIRCLE_INF),
            (center_inf, _CENTER_INF),
        ):
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
    return np.flatnonzero(cand) if cand.any() else None
