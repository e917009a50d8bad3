"""The compiled prescreen (:mod:`synth.query.prescreen_kernel`) against the numpy expressions it
replaced (kept here as the reference): on coupler curves of random four-bars, with slot and
rocker pivots anywhere, the same decisions wherever every tested quantity is more than 1e-9
from its threshold (a scalar ``atan2`` may round the last bit otherwise than numpy's)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kinematics.fourbar import fourbar_motion
from kinematics.loop import circle_intersection
from kinematics.status import Status
from synth.mechanism.sixbar import crank_grid
from synth.query.candidates import Request, dwell_runs, output_may_meet
from synth.query.prescreen_kernel import screen_outputs

MARGIN = 1e-9


def _numpy_psi(P, D, rest, rrr):
    """The output angle as the numpy screen took it, and where the RRR loop closes."""
    closes = np.ones(P.shape[0], bool)
    if rrr is not None:
        rho, L, br = (np.reshape(x, (-1, 1)) for x in rrr)
        loop = circle_intersection(D - P, rho, L, br, rates=False)
        closes = ~np.any((loop.status & np.uint8(Status.NOT_ASSEMBLABLE)) != 0, axis=-1)
        P = P + rho * loop.e1
    w = (P - D) * np.conj(rest - D)
    psi = np.angle(w[..., :1]) + np.concatenate(
        [np.zeros(w.shape[:-1] + (1,)), np.cumsum(np.angle(w[..., 1:] * np.conj(w[..., :-1])), axis=-1)], axis=-1
    )
    return psi, closes


def _spread(psi, length):
    """The least max − min over every cyclic window of ``length`` samples, per row."""
    m = psi.shape[1]
    if length >= m:
        return psi.max(axis=1) - psi.min(axis=1)
    idx = (np.arange(m)[:, None] + np.arange(length)[None, :]) % m
    win = psi[:, idx]
    return (win.max(axis=2) - win.min(axis=2)).min(axis=1)


def _reference(request, P, D, rest, rrr):
    """The numpy decisions and, per row, whether one of its tested quantities lies within
    MARGIN of its threshold (there the two forms may round to either side)."""
    psi, closes = _numpy_psi(P, D, rest, rrr)
    ok = closes & output_may_meet(request, psi)
    stray = np.abs(np.roll(psi, -1, axis=1) - 2 * psi + np.roll(psi, 1, axis=1)).max(axis=1) / 8
    swing = psi.max(axis=1) - psi.min(axis=1)
    near = np.zeros(len(psi), bool)
    if request.swing is not None:
        near |= np.abs(swing - (request.swing + request.swing_tol)) < MARGIN
        near |= np.abs(swing + 2 * stray - (request.swing - request.swing_tol)) < MARGIN
    shortest, longest = dwell_runs(request, psi.shape[1])
    if shortest >= 2:
        near |= np.abs(_spread(psi, shortest) - request.band) < MARGIN
    if longest < psi.shape[1]:
        near |= np.abs(_spread(psi, longest) - (request.band - 2 * stray)) < MARGIN
    return ok, near & closes


@st.composite
def screens(draw):
    """A request and dyads on a random four-bar's coupler curve: pivots near the curve and
    far off it, rockers short and long."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    b, c, d = rng.uniform(1.5, 4.5, 3)
    samples = draw(st.sampled_from([90, 360]))
    motion = fourbar_motion(1.0, b, c, d, crank_grid(samples), 1, order=0)
    n = draw(st.integers(1, 40))
    u, v = rng.uniform(-2, 3, n), rng.uniform(-2, 2, n)
    P = np.stack([motion.coupler_point(u[k], v[k])[0] for k in range(n)])
    centre = P.mean(axis=1, keepdims=True)
    D = centre + rng.uniform(0.5, 12, (n, 1)) * np.exp(2j * np.pi * rng.random((n, 1)))
    rest = P[:, :1] + rng.normal(size=(n, 1)) + 1j * rng.normal(size=(n, 1))
    rrr = None
    if draw(st.booleans()):
        rrr = (rng.uniform(0.5, 8, n), rng.uniform(0.3, 8, n), rng.choice([-1.0, 1.0], n))
    dwells = draw(st.sampled_from([1, 2]))  # a double dwell names its swing too
    swing = draw(st.floats(math.radians(5), math.radians(120)))
    dwell = draw(st.floats(math.radians(5), math.radians(170 if dwells == 1 else 120)))
    request = Request(
        dwell=dwell,
        dwell_tol=draw(st.floats(math.radians(0.5), math.radians(10))),
        swing=swing,
        swing_tol=draw(st.floats(math.radians(0.1), math.radians(60))),
        dwells=dwells,
        band=draw(st.floats(math.radians(0.01), math.radians(20))),
        output="rrr" if rrr is not None and dwells == 1 else "rpr",
    )  # the screen reads neither
    return request, P, D, rest, rrr


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(screens())
def test_the_compiled_screen_decides_as_the_numpy_one(case):
    request, P, D, rest, rrr = case
    shortest, longest = dwell_runs(request, P.shape[1])
    got = screen_outputs(P, D, rest, rrr, request.swing, request.swing_tol, request.band, shortest, longest)
    want, near = _reference(request, P, D, rest, rrr)
    assert got.shape == want.shape
    np.testing.assert_array_equal(got[~near], want[~near])


def test_the_screen_passes_and_rejects_real_dyads():
    """Not a screen that passes everything or nothing: a slot pivot 8 cranks off a coupler
    curve (swing 14.1°, 62° within a 1° band) passes a request for what it does and fails one
    for a swing it does not reach or a dwell it does not hold."""
    phi = crank_grid(360)
    P = fourbar_motion(1.0, 3.0, 3.0, 3.5, phi, 1, order=0).coupler_point(1.2, 0.8)[0][None, :]
    D = np.array([[P[0].mean() + 8.0]])
    rest = P[:, :1]
    psi, _ = _numpy_psi(P, D, rest, None)
    swing = float(psi.max() - psi.min())
    deg = math.radians
    for dwell, s, expected in ((62, swing, True), (62, swing + deg(20), False), (120, swing, False)):
        request = Request(dwell=deg(dwell), dwell_tol=deg(5), swing=s, band=deg(1))
        shortest, longest = dwell_runs(request, 360)
        got = screen_outputs(P, D, rest, None, request.swing, request.swing_tol, request.band, shortest, longest)
        want, _ = _reference(request, P, D, rest, None)
        assert got[0] == want[0] == expected
