"""The compiled minimum-zone fit and band peak (synth.segment_search.minimum_zone_kernel), against independent forms.

Lawson's iteration is held to an exact linear program (scipy.optimize.linprog) of the same
Chebyshev problem; the fit to a closed form (the minimax line of a parabola); the scalar
deviation to the array one; the band peak to :func:`kinematics.loop.parabola_vertex`.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog

from kinematics.loop import parabola_vertex
from synth.kinds import SegmentKind
from synth.segment_search.minimum_zone import minimum_zone_fit, path_deviation
from synth.segment_search.minimum_zone_kernel import deviation_at, lawson, window_peak

LINE, ARC = SegmentKind.LINE.code, SegmentKind.ARC.code
K = 21
X = np.linspace(-1.0, 1.0, K)
#: Below this the LP's optimum (HiGHS, feasibility tolerance 1e-7 on residuals of size 1) says
#: nothing: there both fits must merely be as small.
LP_RESOLUTION = 1e-6


def _chebyshev_lp(cols, r0):
    """min over x of max_j |r0_j − Σ x_k·cols[k]_j|, exactly (an LP in x and the bound t)."""
    C = np.stack(cols, axis=1)
    p = C.shape[1]
    A = np.block([[-C, -np.ones((K, 1))], [C, -np.ones((K, 1))]])
    lp = linprog(np.r_[np.zeros(p), 1.0], A_ub=A, b_ub=np.r_[-r0, r0], bounds=[(None, None)] * (p + 1))
    assert lp.status == 0
    return lp.x[-1]


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-3, 3), min_size=5, max_size=5),
    st.floats(0, 0.05),
    st.integers(0, 2**32 - 1),
    st.sampled_from([2, 3]),
)
@example([0.0, 0.0, 1e-10, 0.0, 0.0], 0.0, 0, 2)  # tiny: the LP's tolerances (~1e-7) made it 0
@example([0.0, 0.0, 1e-10, 0.0, 1.0], 0.0, 0, 2)  # an optimum of 5e-11, below the LP's resolution
def test_lawson_comes_within_15_percent_of_the_exact_chebyshev_fit(coef, noise, seed, p):
    r0 = np.polyval(coef, X) + noise * np.random.default_rng(seed).normal(size=K)
    assume(np.abs(r0).max() > 0)
    r0 = r0 / np.abs(r0).max()  # both fits are linear in r0; the LP's tolerances are absolute
    if p == 2:
        cols = [np.ones(K), X.copy()]
    else:
        cols = [np.cos(0.7 * X), np.sin(0.7 * X), np.ones(K)]
    c2 = cols[2] if p == 3 else np.zeros(K)
    x = lawson(cols[0], cols[1], c2, r0, p, 10, np.empty(K), np.empty(K))
    h = np.abs(r0 - x[0] * cols[0] - x[1] * cols[1] - x[2] * c2).max()
    best = _chebyshev_lp(cols, r0)
    if best < LP_RESOLUTION:  # the LP resolves the optimum no better (it reported 0 for 5e-11)
        assert h < LP_RESOLUTION
        return
    # never better than the optimum (else its residual is miscomputed), close to it (measured:
    # at most 6 % over 300 random problems, median 1.7 %)
    assert best * (1 - 1e-7) - 1e-12 <= h <= 1.15 * best + 1e-12


def test_line_through_a_parabola_is_its_minimax_line():
    """y = x² on [−1, 1]: the minimax line is y = ½, the band's half-width ½ (equioscillation
    at x = −1, 0, 1). One linearisation from the x-axis gets within 1 %."""
    z = (X + 1j * X**2)[None]
    point, direction, radius = minimum_zone_fit(z, LINE, np.array([0j]), np.array([1 + 0j]), np.zeros(1), 10)
    h = np.abs(path_deviation(z, LINE, point[:, None], direction[:, None], radius[:, None])).max()
    assert h == pytest.approx(0.5, rel=1e-2)
    assert point[0].imag == pytest.approx(0.5, rel=1e-2)
    assert abs(direction[0]) == pytest.approx(1.0, abs=1e-12)


def test_circle_through_an_arc_is_that_circle():
    """Samples of a circle (centre 2 + i, radius 3) started off it: each fit is first order in
    the change, so re-linearised a few times it finds the circle."""
    z = (2 + 1j + 3 * np.exp(1j * (0.4 + 0.6 * X)))[None]
    point, direction, radius = np.array([2.05 + 0.97j]), np.ones(1, complex), np.array([3.04])
    for _ in range(4):
        point, direction, radius = minimum_zone_fit(z, ARC, point, direction, radius, 10)
    assert point[0] == pytest.approx(2 + 1j, abs=1e-5)
    assert radius[0] == pytest.approx(3.0, abs=1e-5)


def test_rows_are_fitted_independently():
    rng = np.random.default_rng(7)
    z = np.exp(1j * rng.uniform(0, 1, (5, K))) * (1 + 0.01 * rng.normal(size=(5, K)))
    start = (np.zeros(5, complex), np.ones(5, complex), np.ones(5))
    together = minimum_zone_fit(z, ARC, *start, 10)
    for i in range(5):
        alone = minimum_zone_fit(z[i : i + 1], ARC, start[0][i : i + 1], start[1][i : i + 1], start[2][i : i + 1], 10)
        assert [a[0] for a in alone] == [t[i] for t in together]


@given(
    st.complex_numbers(max_magnitude=1e3, allow_nan=False),
    st.complex_numbers(max_magnitude=1e3, allow_nan=False),
    st.floats(0, 2 * math.pi),
    st.floats(0, 1e3),
    st.sampled_from([LINE, ARC]),
)
def test_scalar_deviation_is_the_array_one(z, point, angle, radius, kind):
    direction = complex(math.cos(angle), math.sin(angle))
    expected = float(path_deviation(np.array([z]), kind, point, direction, radius)[0])
    assert deviation_at(z, kind, point, direction, radius) == pytest.approx(
        expected, rel=1e-12, abs=1e-12 * (abs(z) + abs(point) + 1)
    )


@given(st.lists(st.floats(0, 1e3), min_size=1, max_size=40), st.data())
@example([1.0, 2.0, 1.5], None)
def test_window_peak_is_the_highest_sample_or_parabola_vertex(values, data):
    d = np.array(values)
    if data is None:
        t_lo, t_hi = 0, d.size - 1
    else:
        t_lo = data.draw(st.integers(0, d.size - 1))
        t_hi = data.draw(st.integers(t_lo, d.size - 1))
    expected = d[t_lo : t_hi + 1].max()
    for j in range(t_lo + 1, t_hi):
        if d[j] >= d[j - 1] and d[j] >= d[j + 1]:
            v = parabola_vertex(d[j - 1], d[j], d[j + 1])
            expected = max(expected, d[j] + (float(v.rise) if v.curvature < 0 else 0.0))
    assert window_peak(d, t_lo, t_hi) == pytest.approx(expected, rel=1e-14)
    if data is None:
        # the parabola through (−1, 1), (0, 2), (1, 1.5) peaks at 2 + 0.5² / (8 · 1.5)
        assert window_peak(d, t_lo, t_hi) == pytest.approx(2.0 + 0.25 / 12)
