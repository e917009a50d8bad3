"""Six-bar dwell mechanisms: a four-bar whose coupler point drives an output dyad, and its
exact simulation over the crank turn.

The six-bar is a four-bar (crank a, coupler b, rocker c, ground d, assembly branch; coupler
point p = u + iv in the coupler frame, the README's conventions) whose coupler point P drives
one of two output dyads (docs/curvature.md §4):

* **RPR** (slotted rocker): a slot on the output rocker passes through the fixed pivot D; the
  pin at P slides in it. Output angle ψ = arg(P − D).
* **RRR**: a rod of length ρ = |PQ| from P to the moving pivot Q of a rocker of length
  L = |DQ| about the fixed pivot D. Output angle ψ = arg(Q − D).

:func:`simulate` is the exact closed-form position and derivative solution, never the
curvature approximation (compiled: :mod:`synth.mechanism.sixbar_kernel`; the numpy functions here are
its reference and the path for crank angles of other shapes); every figure a user is shown
(:mod:`synth.mechanism.figures`: dwell angle, output deviation, swing, transmission angles) comes from
it, with dwell ends and extremes refined on its exact path beyond the sample grid
(:mod:`synth.mechanism.output_range`). Points are
complex numbers, angles radians, lengths in the unit of the links (crank-normalised inside the
atlas: a = 1).

Kernels never return NaN/inf: positions where the four-bar or the dyad cannot assemble carry
:class:`~kinematics.status.Status` flags (``uint16``) with finite placeholders.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinematics.fourbar import FourBarMotion, fourbar_motion
from kinematics.loop import circle_intersection, transmission_fold, wrap_angle
from kinematics.status import (
    AssemblyError,
    Status,
    check_on_degenerate,
    raise_on_flags,
)
from synth.kinds import OutputKind
from synth.linkage import CouplerFourBar
from synth.types import C128, F64

__all__ = [
    "ExactOutput",
    "OutputDyad",
    "SixBar",
    "SixBarMotion",
    "SixBars",
    "as_batch",
    "crank_grid",
    "kernel_inputs",
    "output_angle",
    "simulate",
    "simulate_numpy",
]

U16 = NDArray[np.uint16]


#: |P − D| below this × linkage size: the RPR pin sits on the slot pivot, ψ is undefined.
PIN_ON_PIVOT_EPS = 1e-9
#: Transmission angle reported for the RPR output (rad): see :func:`simulate`.
RPR_TRANSMISSION = 0.5 * math.pi

_TWO_PI = 2.0 * math.pi


# --------------------------------------------------------------------------------------------
# Model
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class OutputDyad:
    """The output dyad driven by the coupler point P.

    Attributes
    ----------
    kind : OutputKind
        (a string is accepted, any case). ``"RPR"``: slotted rocker about ``pivot`` whose slot
        passes through the pivot; the pin at P slides in it (``rocker``, ``rod`` and ``branch`` are unused, 0/0/+1).
        ``"RRR"``: rod P–Q of length ``rod`` and rocker D–Q of length ``rocker``.
    pivot : complex
        Fixed pivot D, fixed frame (A0 = 0, B0 = d on +x), link-length units. A pair (x, y) is
        accepted and stored as x + iy.
    rocker : float
        RRR rocker length L = |DQ| (> 0).
    rod : float
        RRR rod length ρ = |PQ| (> 0).
    branch : {+1, −1}
        RRR assembly branch, the four-bar's convention (:class:`~kinematics.status.Branch`)
        with P in the place of the crank pin and D in that of B0: +1 puts Q to the **left of
        the directed line P → D**, i.e. Im(conj(D − P)·(Q − P)) > 0. It is fixed for the whole
        turn; a dyad that would have to change branch passes through a toggle or cannot
        assemble, and is flagged.
    """

    kind: OutputKind
    pivot: complex
    rocker: float = 0.0
    rod: float = 0.0
    branch: int = 1

    def __post_init__(self) -> None:
        try:
            # a member as it is (the fits make dyads by the hundred thousand); text by name
            kind = self.kind if isinstance(self.kind, OutputKind) else OutputKind(str(self.kind).upper())
        except ValueError:
            raise ValueError(
                f"dyad kind must be one of {', '.join(repr(k.value) for k in OutputKind)}, not {self.kind!r}"
            ) from None
        pivot = self.pivot
        if not isinstance(pivot, (complex, float, int, np.number)):
            x, y = pivot  # (x, y)
            pivot = complex(float(x), float(y))
        pivot = complex(pivot)
        if not (math.isfinite(pivot.real) and math.isfinite(pivot.imag)):
            raise AssemblyError(f"dyad pivot must be finite, got {self.pivot!r}")
        if int(self.branch) not in (1, -1):
            raise ValueError(f"dyad branch must be +1 or -1, not {self.branch!r}")
        rocker, rod = float(self.rocker), float(self.rod)
        if kind is OutputKind.RRR:
            for name, value in (("rocker", rocker), ("rod", rod)):
                if not (math.isfinite(value) and value > 0):
                    raise AssemblyError(f"RRR {name} length must be finite and > 0, got {value!r}")
        else:
            rocker, rod = 0.0, 0.0
        object.__setattr__(self, "kind", kind)
        object.__setattr__(self, "pivot", pivot)
        object.__setattr__(self, "rocker", rocker)
        object.__setattr__(self, "rod", rod)
        object.__setattr__(self, "branch", int(self.branch))

    @classmethod
    def rpr(cls, pivot: complex) -> OutputDyad:
        """Slotted rocker about ``pivot``."""
        return cls(OutputKind.RPR, pivot)

    @classmethod
    def rrr(cls, pivot: complex, rocker: float, rod: float, branch: int) -> OutputDyad:
        """Rocker |DQ| = ``rocker`` about ``pivot``, rod |PQ| = ``rod``, on ``branch``."""
        return cls(OutputKind.RRR, pivot, rocker, rod, branch)


@dataclass(frozen=True, slots=True, init=False)
class SixBar:
    """A four-bar with a coupler point driving an output dyad (one mechanism).

    Built from its lengths, ``SixBar(a, b, c, d, branch, u, v, dyad)`` (validated), or from a
    linkage record (:meth:`of`); it holds the linkage as one :class:`~synth.linkage.CouplerFourBar`
    (the record the atlas's rows and the query's segment rows carry) and reads its fields
    through it.

    Attributes
    ----------
    fourbar : CouplerFourBar
        The four-bar and its coupler point: ``a``, ``b``, ``c``, ``d`` crank, coupler, rocker,
        ground lengths (> 0; ground pivots A0 = 0, B0 = d), ``branch`` the four-bar's assembly
        branch (±1, :class:`~kinematics.status.Branch`), ``u``, ``v`` the coupler point
        p = u + iv in the coupler frame (origin at the crank pin A, x-axis along A → B). Each
        is also an attribute of the six-bar (``sixbar.b``).
    dyad : OutputDyad
        The output dyad driven by that point.
    """

    fourbar: CouplerFourBar
    dyad: OutputDyad

    def __init__(
        self, a: float, b: float, c: float, d: float, branch: int, u: float, v: float, dyad: OutputDyad
    ) -> None:
        lengths = {}
        for name, value in (("a", a), ("b", b), ("c", c), ("d", d)):
            value = float(value)
            if not (math.isfinite(value) and value > 0):
                raise AssemblyError(f"length {name} must be finite and > 0, got {value!r}")
            lengths[name] = value
        point = {}
        for name, value in (("u", u), ("v", v)):
            value = float(value)
            if not math.isfinite(value):
                raise AssemblyError(f"coupler point {name} must be finite, got {value!r}")
            point[name] = value
        if int(branch) not in (1, -1):
            raise ValueError(f"four-bar branch must be +1 or -1, not {branch!r}")
        object.__setattr__(self, "fourbar", CouplerFourBar(**lengths, branch=int(branch), **point))
        object.__setattr__(self, "dyad", dyad)

    @classmethod
    def of(cls, fourbar: CouplerFourBar, dyad: OutputDyad) -> SixBar:
        """The six-bar of one linkage record and an output dyad (validated as the lengths are)."""
        f = fourbar
        return cls(f.a, f.b, f.c, f.d, f.branch, f.u, f.v, dyad)

    # The linkage's fields, read through the record: one spelling of the four-bar and its point.
    a = property(lambda self: self.fourbar.a, doc="Crank length.")
    b = property(lambda self: self.fourbar.b, doc="Coupler length.")
    c = property(lambda self: self.fourbar.c, doc="Rocker length.")
    d = property(lambda self: self.fourbar.d, doc="Ground length.")
    branch = property(lambda self: self.fourbar.branch, doc="Four-bar assembly branch (±1).")
    u = property(lambda self: self.fourbar.u, doc="Coupler point, along A → B.")
    v = property(lambda self: self.fourbar.v, doc="Coupler point, across A → B.")

    @property
    def coupler_point(self) -> complex:
        """p = u + iv, coupler frame."""
        return complex(self.u, self.v)

    def scaled(self, scale: float) -> SixBar:
        """The same mechanism with every length multiplied by ``scale`` (> 0)."""
        dy = self.dyad
        return SixBar(
            self.a * scale,
            self.b * scale,
            self.c * scale,
            self.d * scale,
            self.branch,
            self.u * scale,
            self.v * scale,
            OutputDyad(dy.kind, dy.pivot * scale, dy.rocker * scale, dy.rod * scale, dy.branch),
        )


@dataclass(frozen=True, slots=True)
class SixBars:
    """A batch of six-bars as a struct of arrays, all of shape ``(N,)`` (fields as in
    :class:`SixBar`; ``rpr`` is True for an RPR dyad, ``pivot``/``rocker``/``rod``/
    ``dyad_branch`` describe the dyad as in :class:`OutputDyad`)."""

    a: F64
    b: F64
    c: F64
    d: F64
    branch: F64
    u: F64
    v: F64
    rpr: NDArray[np.bool_]
    pivot: C128
    rocker: F64
    rod: F64
    dyad_branch: F64

    @classmethod
    def from_sixbars(cls, sixbars: Sequence[SixBar]) -> SixBars:
        """Stack single :class:`SixBar` objects (validated there) into a batch."""
        if len(sixbars) == 0:
            raise ValueError("a batch needs at least one six-bar")
        f = lambda get: np.array([get(s) for s in sixbars], dtype=float)
        return cls(
            f(lambda s: s.a),
            f(lambda s: s.b),
            f(lambda s: s.c),
            f(lambda s: s.d),
            f(lambda s: s.branch),
            f(lambda s: s.u),
            f(lambda s: s.v),
            np.array([s.dyad.kind is OutputKind.RPR for s in sixbars]),
            np.array([s.dyad.pivot for s in sixbars], dtype=complex),
            f(lambda s: s.dyad.rocker),
            f(lambda s: s.dyad.rod),
            f(lambda s: s.dyad.branch),
        )

    def __len__(self) -> int:
        return int(self.a.shape[0])

    def __getitem__(self, i: int) -> SixBar:
        kind = OutputKind.RPR if self.rpr[i] else OutputKind.RRR
        dyad = OutputDyad(
            kind, complex(self.pivot[i]), float(self.rocker[i]), float(self.rod[i]), int(self.dyad_branch[i])
        )
        return SixBar(
            float(self.a[i]),
            float(self.b[i]),
            float(self.c[i]),
            float(self.d[i]),
            int(self.branch[i]),
            float(self.u[i]),
            float(self.v[i]),
            dyad,
        )


def as_batch(sixbar: SixBar | SixBars) -> tuple[SixBars, bool]:
    """(batch, is_single): a single :class:`SixBar` as a batch of one, a batch as it is."""
    if isinstance(sixbar, SixBar):
        return SixBars.from_sixbars([sixbar]), True
    if isinstance(sixbar, SixBars):
        return sixbar, False
    raise TypeError(f"expected a SixBar or SixBars, not {type(sixbar).__name__}")


# --------------------------------------------------------------------------------------------
# Simulation
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class SixBarMotion:
    """Exact positions and crank-angle derivatives of six-bars, struct of arrays.

    Shapes: ``(M,)`` for a single :class:`SixBar` simulated at ``M`` crank angles, ``(N, M)``
    for a batch of ``N``. Derivatives are with respect to the crank angle φ (rad/rad).

    Attributes
    ----------
    phi : float64
        Crank angles (rad), as given (broadcastable).
    fourbar : FourBarMotion
        The four-bar's motion (crank pin ``A``, joint ``B``, coupler and rocker phasors).
    z : tuple of complex128
        Coupler point path (P, P′, P″)[: order + 1], fixed frame.
    pivot : complex128
        Fixed output pivot D, broadcastable (``(N, 1)`` for a batch).
    moving_pivot : complex128
        RRR: the rocker's moving pivot Q. RPR: the pin P itself (where the block sits in the
        slot).
    psi : float64
        Output angle ψ (rad): RPR arg(P − D), RRR arg(Q − D), unwrapped continuously along the
        last axis (samples in crank order), starting in (−π, π] at the first sample.
    dpsi : tuple of float64
        (ψ′, ψ″)[: order], closed form (the dyad loop differentiated, see :func:`simulate`).
    transmission_fourbar : float64
        Four-bar transmission angle, coupler vs rocker at B, folded to [0, π/2] (rad).
    transmission_output : float64
        RRR: rod vs rocker at Q, folded to [0, π/2]. RPR: π/2 (see :func:`simulate`).
    status : uint16
        :class:`Status` flags: ``NOT_ASSEMBLABLE`` (four-bar or dyad), ``TOGGLE`` (four-bar:
        coupler and rocker aligned; RRR: rod and rocker aligned). Flagged positions hold
        finite placeholders (derivatives 0).
    """

    phi: F64
    fourbar: FourBarMotion
    z: tuple[C128, ...]
    pivot: C128
    moving_pivot: C128
    psi: F64
    dpsi: tuple[F64, ...]
    transmission_fourbar: F64
    transmission_output: F64
    status: U16

    @property
    def shape(self) -> tuple[int, ...]:
        return self.psi.shape

    @property
    def assembled(self) -> NDArray[np.bool_]:
        """True where both the four-bar and the dyad close (toggles count as assembled)."""
        return (self.status & np.uint16(Status.NOT_ASSEMBLABLE)) == 0

    @property
    def ok(self) -> NDArray[np.bool_]:
        return self.status == 0


def crank_grid(samples: int = 720, start: float = 0.0) -> F64:
    """``samples`` uniformly spaced crank angles over one turn from ``start`` (rad), end excluded:
    the sample grid every figure function expects."""
    if int(samples) < 8:
        raise ValueError(f"a crank grid needs at least 8 samples, not {samples!r}")
    return start + np.arange(int(samples)) * (_TWO_PI / int(samples))


def simulate(sixbar: SixBar | SixBars, phi: ArrayLike, *, order: int = 2, on_degenerate: str = "flag") -> SixBarMotion:
    """Exact closed-form motion of a six-bar (or a batch) over crank angles ``phi``.

    Parameters
    ----------
    sixbar : SixBar or SixBars
        One mechanism, or ``N`` of them as a struct of arrays (mixed RPR and RRR allowed).
    phi : array_like
        Crank angles (rad), shape ``(M,)`` (or ``(N, M)`` for a batch). ψ is unwrapped along
        the last axis, so give the samples in crank order for a continuous ψ.
    order : {0, 1, 2}
        Highest derivative order computed (of the coupler point and of ψ).
    on_degenerate : {"flag", "raise"}
        ``"raise"`` raises :class:`~kinematics.status.AssemblyError` where the mechanism cannot
        assemble (or, with ``order`` ≥ 1, sits at a toggle).

    Returns
    -------
    SixBarMotion

    Notes
    -----
    Four-bar and coupler point: :func:`kinematics.fourbar.fourbar_motion` and
    :meth:`~kinematics.fourbar.FourBarMotion.coupler_point` (docs/curvature.md §1).

    RPR: with W = P − D, ψ = Im log W, so ψ′ = Im(P′/W), ψ″ = Im(P″/W − (P′/W)²). The force of
    the slot on the block is normal to the slot, which runs through D, so it is always normal
    to the rocker radius at the contact: the output transmission angle of a slotted rocker is
    π/2 at every position (``RPR_TRANSMISSION``). What does limit an RPR — the pin passing
    over the pivot — is flagged ``NOT_ASSEMBLABLE`` (|P − D| < ``PIN_ON_PIVOT_EPS`` × size).

    RRR: loop ρ·e^{iχ} − L·e^{iψ} = R, R = D − P (χ the rod angle P→Q). Q is the circle–circle
    intersection |Q − P| = ρ, |Q − D| = L on the fixed branch
    (:func:`kinematics.loop.circle_intersection`): e^{iχ} = (R/r)(cos β + i·s·sin β),
    cos β = (ρ² + r² − L²)/(2ρr), 2ρr·sin β = √((r + L − ρ)(ρ + L − r)(r + ρ − L)(r + ρ + L))
    (Heron, no cancellation at a toggle), sin(χ − ψ) = −r·s·sin β/L. Each derivative order
    solves i·ρ·χ⁽ᵏ⁾e^{iχ} − i·L·ψ⁽ᵏ⁾e^{iψ} = Q_k (:meth:`~kinematics.loop.CircleIntersection.rates`) with
    ψ⁽ᵏ⁾ = −Re(Q_k e^{−iχ})/(L sin(χ − ψ)), χ⁽ᵏ⁾ = −Re(Q_k e^{−iψ})/(ρ sin(χ − ψ)),
    Q_1 = −P′, Q_2 = −P″ + ρχ′²e^{iχ} − Lψ′²e^{iψ} (the four-bar's system of docs/curvature.md §1
    with b, c, θ, γ → ρ, L, χ, ψ). Transmission angle at Q: the angle between e^{iχ} and
    e^{iψ}, folded to [0, π/2] (:func:`kinematics.loop.transmission_fold`).

    Crank angles of shape ``(M,)``, or ``(N, M)``/``(1, M)`` for a batch, run through the
    compiled kernel (:mod:`synth.mechanism.sixbar_kernel`: these formulas in one pass per position, 2–4×
    the numpy path); any other shape (a scalar angle, a grid to broadcast) through the numpy
    path below, the reference the kernel is tested against (statuses equal, values to ~1e-11).

    References
    ----------
    ``docs/curvature.md`` §1 (loop derivatives) and §4 (output dyads).
    """
    mode = check_on_degenerate(on_degenerate)
    if order not in (0, 1, 2):
        raise ValueError(f"order must be 0, 1 or 2, not {order!r}")
    single = isinstance(sixbar, SixBar)
    if not single and not isinstance(sixbar, SixBars):
        raise TypeError(f"expected a SixBar or SixBars, not {type(sixbar).__name__}")
    phi = np.asarray(phi, dtype=float)
    if not np.all(np.isfinite(phi)):
        raise ValueError("crank angles must be finite")
    phi_rows = _kernel_phi(phi, 1 if single else len(sixbar), single)
    if phi_rows is not None:
        motion = _simulate_compiled(sixbar, phi, phi_rows, order)
        if mode == "raise":
            raise_on_flags(motion.status, "six-bar", Status.NOT_ASSEMBLABLE | (Status.TOGGLE if order else Status.OK))
        return motion
    batch, single = as_batch(sixbar)
    return simulate_numpy(batch, single, phi, order, mode)


def output_angle(sixbars: SixBars, phi: ArrayLike) -> F64:
    """ψ alone (rad, continuous along the last axis) of ``sixbars`` at crank angles ``phi``
    (``(M,)``, or ``(N, M)``): ``simulate(sixbars, phi, order=0).psi``, without the points and
    transmission angles — what a refinement on the exact path evaluates, many times."""
    return ExactOutput(sixbars)(phi)


class ExactOutput:
    """:func:`output_angle` of one batch as a :data:`~synth.mechanism.output_range.PsiAt` evaluator,
    holding the compiled kernel's rows (``params``, ``rpr``: :func:`kernel_inputs`; the pin
    tolerance :data:`PIN_ON_PIVOT_EPS`): the dwell refinement then evaluates ψ pointwise inside
    its own compiled pass (:mod:`synth.mechanism.dwell_ends_kernel`) instead of calling back."""

    __slots__ = ("sixbars", "params", "rpr")
    pin_eps = PIN_ON_PIVOT_EPS

    def __init__(self, sixbars: SixBars):
        self.sixbars = sixbars
        self.params, self.rpr = kernel_inputs(sixbars)

    def __call__(self, phi: ArrayLike) -> F64:
        """ψ at crank angles ``(M,)`` (shared), ``(N, M)``, or ``(N, ...)`` (row n: six-bar n's)."""
        from synth.mechanism.sixbar_kernel import output_angles  # numba: imported on first use

        phi = np.asarray(phi, dtype=float)
        if phi.ndim > 2 and phi.shape[0] == len(self.sixbars):
            return self(phi.reshape(phi.shape[0], -1)).reshape(phi.shape)
        phi_rows = _kernel_phi(phi, len(self.sixbars), False)
        if phi_rows is None or not np.all(np.isfinite(phi)):
            return simulate(self.sixbars, phi, order=0).psi
        return output_angles(self.params, self.rpr, phi_rows, PIN_ON_PIVOT_EPS)


def kernel_inputs(sixbar: SixBar | SixBars) -> tuple[F64, NDArray[np.bool_]]:
    """The compiled kernel's parameter rows ``(N, 12)`` — a, b, c, d, branch, u, v, pivot x,
    pivot y, rocker, rod, dyad branch — and which rows are RPR."""
    if isinstance(sixbar, SixBar):  # one row straight from the fields: the single call stays cheap
        dy = sixbar.dyad
        params = np.array(
            [
                [
                    sixbar.a,
                    sixbar.b,
                    sixbar.c,
                    sixbar.d,
                    sixbar.branch,
                    sixbar.u,
                    sixbar.v,
                    dy.pivot.real,
                    dy.pivot.imag,
                    dy.rocker,
                    dy.rod,
                    dy.branch,
                ]
            ]
        )
        return params, np.array([dy.kind is OutputKind.RPR])
    s = sixbar
    params = np.stack(
        [s.a, s.b, s.c, s.d, s.branch, s.u, s.v, s.pivot.real, s.pivot.imag, s.rocker, s.rod, s.dyad_branch],
        axis=1,
        dtype=float,
    )
    return params, np.ascontiguousarray(s.rpr, dtype=bool)


def _kernel_phi(phi: F64, n: int, single: bool) -> F64 | None:
    """``phi`` as the compiled kernel's ``(1, M)`` or ``(N, M)`` rows, or None for a shape it
    does not take (then the numpy path broadcasts it)."""
    if phi.ndim == 1 and phi.shape[0] > 0:
        return phi[None, :]
    if not single and phi.ndim == 2 and phi.shape[0] in (1, n) and phi.shape[1] > 0:
        return np.ascontiguousarray(phi)
    return None


def _simulate_compiled(sixbar: SixBar | SixBars, phi: F64, phi_rows: F64, order: int) -> SixBarMotion:
    """The compiled kernel (:mod:`synth.mechanism.sixbar_kernel`): the numpy path's figures and statuses
    in one pass over the positions."""
    from synth.mechanism.sixbar_kernel import sixbar_positions  # numba: imported on first use

    single = isinstance(sixbar, SixBar)
    params, rpr = kernel_inputs(sixbar)
    points, angles, derivs, st_fb, status = sixbar_positions(params, rpr, phi_rows, PIN_ON_PIVOT_EPS, order)
    if single:
        points, angles, derivs, st_fb, status = points[:, 0], angles[:, 0], derivs[:, 0], st_fb[0], status[0]
        a, b, c, d, br = (params[:, k] for k in range(5))
        pivot = np.complex128(sixbar.dyad.pivot)
    else:
        a, b, c, d, br = (params[:, k, None] for k in range(5))
        pivot = sixbar.pivot[:, None]
    fb = FourBarMotion(a, b, c, d, phi, br, points[0], tuple(derivs[0::3]), tuple(derivs[1::3]), st_fb)
    z = (points[1], *points[3:])
    psi, mu_fb, mu_out = angles
    return SixBarMotion(phi, fb, z, pivot, points[2], psi, tuple(derivs[2::3]), mu_fb, mu_out, status)


def simulate_numpy(batch: SixBars, single: bool, phi: F64, order: int, mode: str) -> SixBarMotion:
    """Every order, every broadcastable ``phi``: the reference path (see :func:`simulate`) and
    the fallback for crank angles the compiled kernel does not take."""
    col = (lambda x: x[0]) if single else (lambda x: x[:, None])
    a, b, c, d, br, u, v = (col(x) for x in (batch.a, batch.b, batch.c, batch.d, batch.branch, batch.u, batch.v))
    fb = fourbar_motion(a, b, c, d, phi, br, order=order)
    z = fb.coupler_point(u, v, order)
    shape = fb.shape
    z = tuple(np.broadcast_to(x, shape) for x in z)
    pivot = col(batch.pivot)
    size = np.maximum.reduce([a, b, c, d, np.abs(pivot)])

    if single:
        if batch.rpr[0]:
            Q, e_psi, dpsi, mu_out, st = _rpr(z, pivot, size, order)
        else:
            Q, e_psi, dpsi, mu_out, st = _rrr(z, pivot, batch.rocker[0], batch.rod[0], batch.dyad_branch[0], order)
    else:
        Q = np.empty(shape, complex)
        e_psi = np.empty(shape, complex)
        dpsi = tuple(np.empty(shape) for _ in range(order))
        mu_out = np.empty(shape)
        st = np.empty(shape, np.uint16)
        for rows, rpr in ((np.flatnonzero(batch.rpr), True), (np.flatnonzero(~batch.rpr), False)):
            if len(rows) == 0:
                continue
            zr = tuple(x[rows] for x in z)
            if rpr:
                res = _rpr(zr, pivot[rows], size[rows], order)
            else:
                res = _rrr(
                    zr,
                    pivot[rows],
                    batch.rocker[rows, None],
                    batch.rod[rows, None],
                    batch.dyad_branch[rows, None],
                    order,
                )
            Q[rows], e_psi[rows], mu_out[rows], st[rows] = res[0], res[1], res[3], res[4]
            for k in range(order):
                dpsi[k][rows] = res[2][k]

    status = (fb.status.astype(np.uint16) | st).astype(np.uint16)
    # Derivatives at any flagged position (four-bar or dyad) are placeholders: 0.
    flagged = status != 0
    dpsi = tuple(np.where(flagged, 0.0, x) for x in dpsi)
    psi = _unwrap(e_psi, dpsi[0] if order else None, np.broadcast_to(phi, shape))
    mu_fb = transmission_fold(fb.e_theta * np.conj(fb.e_gamma))
    motion = SixBarMotion(phi, fb, z, pivot, Q, psi, dpsi, mu_fb, mu_out, status)
    if mode == "raise":
        flags = Status.NOT_ASSEMBLABLE | (Status.TOGGLE if order else Status.OK)
        raise_on_flags(status, "six-bar", flags)
    return motion


def _rpr(z: tuple, D, size, order: int):
    """Slotted rocker: ψ = arg(P − D) and its derivatives (see :func:`simulate`)."""
    w = z[0] - D
    r = np.abs(w)
    on_pivot = r <= PIN_ON_PIVOT_EPS * size
    w = np.where(on_pivot, size, w)  # placeholder direction +x
    e_psi = w / np.where(on_pivot, size, r)
    status = np.where(on_pivot, np.uint16(Status.NOT_ASSEMBLABLE), np.uint16(0)).astype(np.uint16)
    dpsi: list[F64] = []
    if order >= 1:
        f1 = z[1] / w
        dpsi.append(np.where(on_pivot, 0.0, f1.imag))
    if order >= 2:
        f2 = z[2] / w - f1 * f1
        dpsi.append(np.where(on_pivot, 0.0, f2.imag))
    mu = np.full(np.shape(e_psi), RPR_TRANSMISSION)
    return z[0], e_psi, tuple(dpsi), mu, status


def _rrr(z: tuple, D, L, rho, branch, order: int):
    """RRR dyad: Q, ψ and derivatives, transmission angle at Q (see :func:`simulate`)."""
    # The loop P + ρ·e^{iχ} = D + L·e^{iψ}: circles about P (radius ρ) and D (radius L).
    loop = circle_intersection(D - z[0], rho, L, branch)
    e_chi, e_psi = loop.e1, loop.e2
    Q = D + L * e_psi
    bad = (loop.status & np.uint8(Status.NOT_ASSEMBLABLE)) != 0
    mu = np.where(bad, 0.0, transmission_fold(e_chi * np.conj(e_psi)))
    status = loop.status.astype(np.uint16)
    dpsi: list[F64] = []
    if order >= 1:
        c1, p1 = loop.rates(-z[1])  # (χ′, ψ′)
        dpsi.append(p1)
        if order >= 2:
            dpsi.append(loop.rates(-z[2] + rho * c1 * c1 * e_chi - L * p1 * p1 * e_psi)[1])
    return Q, e_psi, tuple(dpsi), mu, status


def _unwrap(e_psi: C128, dpsi1: F64 | None, phi: F64) -> F64:
    """ψ continuous along the last axis. With ψ′ known, each step is taken as the 2π-branch
    nearest to the trapezoidal prediction ½(ψ′ₖ + ψ′ₖ₊₁)Δφ, which keeps fast swings (pin
    passing near the pivot) on the right branch where a plain unwrap would jump."""
    base = np.angle(e_psi)
    if base.ndim == 0 or base.shape[-1] < 2:
        return base
    step = np.angle(e_psi[..., 1:] * np.conj(e_psi[..., :-1]))
    if dpsi1 is not None:
        pred = 0.5 * (dpsi1[..., 1:] + dpsi1[..., :-1]) * np.diff(phi, axis=-1)
        step = pred + wrap_angle(step - pred)
    out = np.empty_like(base)
    out[..., 0] = base[..., 0]
    np.cumsum(step, axis=-1, out=out[..., 1:])
    out[..., 1:] += base[..., :1]
    return out
