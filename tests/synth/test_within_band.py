"""The screen's dwell test (:func:`synth.query.candidates.within_band`): some run of ``length``
consecutive samples of a periodic ψ lies within the band — against every cyclic window read
one by one."""

from __future__ import annotations

import numpy as np
from hypothesis import example, given
from hypothesis import strategies as st

from synth.query.candidates import within_band


def _every_window(psi: np.ndarray, length: int, band) -> np.ndarray:
    turn = psi.shape[1]
    windows = np.take(psi, (np.arange(turn)[:, None] + np.arange(length)) % turn, axis=1)  # (n, turn, length)
    spread = windows.max(axis=2) - windows.min(axis=2)
    return np.any(spread <= np.reshape(band, (-1, 1)), axis=1)


@given(
    st.integers(0, 2**32 - 1),
    st.integers(2, 240),
    st.integers(1, 6),
    st.floats(0.0, 1.0),
    st.sampled_from([1e-4, 1e-2, 1.0]),
    st.booleans(),
)
@example(0, 2, 1, 0.0, 1.0, False)  # the shortest run, a zero band
@example(7, 240, 3, 1.0, 1e-2, True)  # a window as long as the turn
def test_within_band_reads_every_cyclic_window(seed, turn, rows, fraction, step, per_row):
    rng = np.random.default_rng(seed)
    psi = np.cumsum(rng.normal(scale=step, size=(rows, turn)), axis=1)
    length = max(2, round(fraction * turn))
    if per_row:
        band = rng.uniform(0.0, 2.0, rows) * np.ptp(psi, axis=1) * length / turn
        band[0] = np.ptp(psi[0, :length])  # a tie: a band exactly a window's spread holds it
    else:
        band = float(step * length * fraction)
    assert np.array_equal(within_band(psi, length, band), _every_window(psi, length, band))
