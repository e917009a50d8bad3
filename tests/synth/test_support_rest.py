"""The far-field test of a short slotted-rocker rest at a support point
(synth.mechanism.support_rest): against a circle traced evenly (a harmonic output, closed
forms) and against the rule spelled out sample by sample on random closed curves."""

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from synth.mechanism.support_rest import DIRECTIONS, harmonic_rest, slot_pivots, support_points

N = 360
PHI = np.arange(N) * 2 * math.pi / N


def test_harmonic_rest_closed_form():
    # ψ = (S/2)cos φ within β of its top: cos φ ≥ 1 − 2β/S
    band, swing = math.radians(0.1), math.radians(10)
    assert math.degrees(harmonic_rest(band, swing)) == pytest.approx(22.9567, abs=1e-4)
    psi = 0.5 * swing * np.cos(np.linspace(-math.pi, math.pi, 2_000_001))
    inside = np.linspace(-math.pi, math.pi, 2_000_001)[psi >= 0.5 * swing - band]
    assert inside.max() - inside.min() == pytest.approx(harmonic_rest(band, swing), abs=1e-5)
    assert harmonic_rest(1.0, 0.5) == pytest.approx(2 * math.pi)


@pytest.mark.parametrize("swing_deg", [10.0, 20.0])
def test_circle_rests_as_a_harmonic_output(swing_deg):
    """An evenly traced circle seen from afar is a harmonic output: every direction passes at
    the harmonic rest's length, none at half of it."""
    band, swing = math.radians(0.1), math.radians(swing_deg)
    path = np.exp(1j * PHI)[None]
    rest = harmonic_rest(band, swing)
    at = support_points(path, dwell=rest, dwell_tol=math.radians(2), swing=swing, band=band)
    k = np.arange(DIRECTIONS)
    assert (at[0] == np.rint(k * N / DIRECTIONS).astype(int) % N).all()  # the support point of e^{iφ}
    short = support_points(path, dwell=rest / 2, dwell_tol=math.radians(2), swing=swing, band=band)
    assert (short == -1).all()


def test_circle_slot_pivot_reach():
    """From a pivot on a unit circle's tangent at distance R the slot swings 2·atan(1/R)."""
    swing = math.radians(10)
    path = np.exp(1j * PHI)[None]
    hits, pivots, swung = slot_pivots(path, np.array([0]), np.array([0]), swing=swing)
    assert hits.tolist() == [0, 0]
    assert np.allclose(pivots, [1 - 1j / math.tan(swing / 2), 1 + 1j / math.tan(swing / 2)], atol=1e-6)
    psi = np.unwrap(np.angle(path[0][None] - pivots[:, None]), axis=1)
    assert np.allclose(psi.max(1) - psi.min(1), swing, atol=math.radians(0.01))
    assert np.allclose(swung, psi.max(1) - psi.min(1))


def _rule(path, k, dwell, dwell_tol, swing, band):
    """The module's far-field rule, one (path, direction) at a time, in plain Python."""
    step = 2 * math.pi / N
    shortest = max(2, math.floor((dwell - dwell_tol) / step) + 1)
    longest = math.ceil((dwell + dwell_tol) / step) + 1
    n = np.exp(2j * math.pi * k / DIRECTIONS)
    p = (path * np.conj(n)).real
    i_top, tol = int(np.argmax(p)), band / swing * (p.max() - p.min())
    if not tol > 0:
        return -1

    def run(values, at):
        inside = values <= tol
        if inside.all():
            return N
        n_ = 1
        while inside[(at + n_) % N]:
            n_ += 1
        b = 1
        while inside[(at - b) % N]:
            b += 1
        return n_ + b - 1

    r = run(p.max() - p, i_top)
    if not shortest <= r <= longest or run(p - p.min(), int(np.argmin(p))) > longest:
        return -1
    windows = np.stack([np.roll(p, -j) for j in range(longest + 1)])
    if ((windows.max(0) - windows.min(0)) <= tol).any():
        return -1
    return i_top


@settings(max_examples=30, deadline=None)
@given(
    coef=st.lists(st.floats(-1, 1), min_size=8, max_size=8),
    dwell=st.floats(6, 30),
    swing=st.floats(5, 40),
)
@example(coef=[1, 0, 0, 0, 0, 0, 0, 0], dwell=23.0, swing=10.0)
@example(coef=[1, 0, 0.3, 0, 0, 0.2, 0, 0], dwell=10.0, swing=10.0)
def test_support_points_follow_the_rule(coef, dwell, swing):
    """A closed curve of a few harmonics: the kernel agrees with the rule sample by sample."""
    a = np.array(coef[:4]) + 1j * np.array(coef[4:])
    path = sum(a[m] * np.exp(1j * (m + 1) * PHI) + 0.3 * a[3 - m] * np.exp(-1j * (m + 1) * PHI) for m in range(4))
    path = path[None]
    args = dict(dwell=math.radians(dwell), dwell_tol=math.radians(2), swing=math.radians(swing), band=math.radians(0.1))
    got = support_points(path, **args)[0]
    want = [_rule(path[0], k, **args) for k in range(DIRECTIONS)]
    assert got.tolist() == want
