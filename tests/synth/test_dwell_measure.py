"""The compiled dwell measurement (synth.segment_search.dwell_measure) on paths with known answers.

A path is handed to the kernel as the crank pin's track ``A`` with e^{iθ} = 0, so any sampled
curve can be measured. On y = x⁴ the minimum-zone line over [−L, L] is y = L⁴/2, so the longest
stretch within a band of half-width ε is L = (2ε)^¼ — 2^¼ ≈ 1.19 times the osculating line's
ε^¼: the fits must find it. Every returned run is checked against the array deviation
(:func:`synth.segment_search.minimum_zone.path_deviation`), and a candidate's result must not depend on the
batch it is measured in.
"""

from __future__ import annotations

import numpy as np

from synth.kinds import SegmentKind
from synth.segment_search.dwell_measure import measure_dwells
from synth.segment_search.minimum_zone import path_deviation

LINE, ARC = SegmentKind.LINE.code, SegmentKind.ARC.code
MF = 2000
H = 1e-3  # sample step (the path's parameter x)
X = (np.arange(MF) - MF // 2) * H
SPREAD = np.linspace(0.0, 1.0, 21)
# narrowest first, as the search measures the levels it keeps: a wider band's minimum-zone line
# over a quartic stretch passes ε off the centre, outside a narrower band
LEVELS = np.array([1e-4, 1e-3, 1e-2])


def _measure(A, uv, kind, centre, width, point, direction, radius, levels=LEVELS):
    n = len(centre)
    return measure_dwells(
        np.ascontiguousarray(A),
        np.zeros((1, MF), complex),
        np.zeros(n, np.int64),
        np.asarray(centre, np.int64),
        np.asarray(uv, complex),
        np.full(n, kind, np.int64),
        np.asarray(width, np.int64),
        np.asarray(point, complex),
        np.asarray(direction, complex),
        np.asarray(radius, float),
        levels,
        5,
        10,
        SPREAD,
        1e-3,
        0.98,
    )


def _check_runs(A, kind, centre, width, levels, out):
    lo, hi, truncated, p, d, r = out
    for i, c in enumerate(centre):
        z = A[c - width[i] : c + width[i] + 1]
        for k, eps in enumerate(levels):
            if hi[i, k] < lo[i, k]:
                continue
            dev = np.abs(path_deviation(z, kind, p[i, k], d[i, k], r[i, k]))
            assert np.all(dev[lo[i, k] : hi[i, k] + 1] <= eps)
            for edge in (lo[i, k] - 1, hi[i, k] + 1):  # the run ends where the band is left
                if 0 <= edge < z.size:
                    assert dev[edge] > eps
            assert truncated[i, k] == (lo[i, k] == 0 or hi[i, k] == z.size - 1)


def test_quartic_stretch_is_measured_with_its_minimum_zone_line():
    A = X + 1j * X**4
    centre, width = [MF // 2], [600]
    out = _measure(A, [0j], LINE, centre, width, [0j], [1 + 0j], [0.0])
    lo, hi = out[0][0], out[1][0]
    half = (hi - lo) / 2 * H
    exact = (2 * LEVELS) ** 0.25
    # the fit accepts a band ε·(1 − 10⁻³) at most, and the sampled run may end a step short on
    # each side; it cannot be longer than the minimum zone allows (+ one step of sampling)
    assert np.all(half >= (2 * LEVELS * (1 - 1e-3)) ** 0.25 - 2 * H)
    assert np.all(half <= exact + H)
    assert np.all(half > 1.15 * LEVELS**0.25)  # longer than the osculating line's stretch
    _check_runs(A, LINE, centre, width, LEVELS, out)


def test_circular_stretch_within_a_wavy_path():
    """A circle of radius 2 with a ripple of amplitude 10⁻³ growing away from the centre:
    the run at each level is checked sample by sample; on an exact circle, started 3·10⁻⁵ off
    it, the run fills the window at every level."""
    t = X
    A = 2 * np.exp(1j * t) * (1 + 1e-3 * np.sin(40 * t) * t**2) + 0.5j
    centre, width = [MF // 2, MF // 2 + 100], [400, 300]
    out = _measure(A, [0j, 0j], ARC, centre, width, [0.5j, 0.5j], [1 + 0j, 1 + 0j], [2.0, 2.0])
    _check_runs(A, ARC, centre, width, LEVELS, out)
    assert np.all(out[1] >= out[0])  # every level has a run
    exact = 2 * np.exp(1j * t) + 0.5j
    lo, hi, truncated, p, _, r = _measure(exact, [0j], ARC, [MF // 2], [300], [0.50002j], [1 + 0j], [2.00003])
    assert np.all(truncated) and np.all(lo == 0) and np.all(hi == 600)


def test_no_run_keeps_the_start_geometry():
    A = X + 1j * X**4 + 0.1j  # the start line misses the centre by 0.1 > every band
    lo, hi, truncated, p, d, r = _measure(A, [0j], LINE, [MF // 2], [200], [0j], [1 + 0j], [0.0])
    assert np.all(hi < lo) and not truncated.any()
    assert np.all(p == 0) and np.all(d == 1)


def test_a_candidate_is_measured_the_same_in_any_batch():
    rng = np.random.default_rng(3)
    A = X + 1j * (X**4 + 0.3 * X**5 + 1e-4 * np.sin(90 * X))
    n = 12
    centre = MF // 2 + rng.integers(-150, 150, n)
    width = rng.choice([16, 64, 128, 300], n)
    g = A[centre]
    tangent = (A[centre + 1] - A[centre - 1]) / np.abs(A[centre + 1] - A[centre - 1])
    together = _measure(A, np.zeros(n), LINE, centre, width, g, tangent, np.zeros(n))
    _check_runs(A, LINE, centre, width, LEVELS, together)
    for i in range(n):
        alone = _measure(A, [0j], LINE, centre[i : i + 1], width[i : i + 1], g[i : i + 1], tangent[i : i + 1], [0.0])
        for a, t in zip(alone, together):
            assert np.array_equal(a[0], t[i])
