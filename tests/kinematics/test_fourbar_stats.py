"""Output-speed statistics of a four-bar as a pulsating-transmission stage."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.fourbar import fourbar_motion, rocker_limits
from kinematics.fourbar_stats import minimise_cv, output_speed_stats, speed_profile
from kinematics.status import AssemblyError, Status

B, C, D = 80.0, 60.0, 90.0


def _dense(a, phases=1, clutch="freewheel", n=400_000):
    phi = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    u = speed_profile(a, B, C, D, phi, phases=phases, clutch=clutch)
    return u.mean(), u.std()


def test_contract():
    st = output_speed_stats([10, 20, 30, 70], B, C, D, [60, 120, 300])
    for name in ("crank_length", "rpm", "mean", "std", "variance", "cv", "ratio_min", "ratio_max", "status"):
        x = getattr(st, name)
        assert x.shape == (4, 3) and np.all(np.isfinite(x))
    assert st.status.dtype == np.uint8
    assert np.all(st.status[3] & Status.NOT_ASSEMBLABLE) and np.all(st.mean[3] == 0)  # 70 cannot turn fully
    assert not np.any(st.status[:3])
    # mean and std scale with the input speed, cv and ratios do not
    assert st.mean[:3, 1] == pytest.approx(2 * st.mean[:3, 0], rel=1e-14)
    assert st.cv[:3, 2] == pytest.approx(st.cv[:3, 0], rel=1e-14)
    assert st.variance == pytest.approx(st.std**2, rel=1e-12)


@pytest.mark.parametrize("a", [10.0, 25.0, 40.0])
def test_one_freewheel_stage_mean_is_the_swing(a):
    # the forward strokes add up to the swing once per turn: mean = omega * swing / 2pi exactly
    st = output_speed_stats([a], B, C, D, [60.0])
    swing = rocker_limits(a, B, C, D).swing
    assert st.mean[0, 0] == pytest.approx(2 * np.pi * swing / (2 * np.pi), rel=1e-13)


@pytest.mark.parametrize("phases", [1, 2, 3, 4])
def test_statistics_against_a_dense_average(phases):
    st = output_speed_stats([30.0], B, C, D, [30 / np.pi], phases=phases)  # omega_in = 1 rad/s
    mean, std = _dense(30.0, phases)
    assert st.mean[0, 0] == pytest.approx(mean, rel=1e-8)
    assert st.std[0, 0] == pytest.approx(std, rel=1e-7)
    assert st.cv[0, 0] == pytest.approx(std / mean, rel=1e-7)


def test_ratio_extremes_against_a_dense_scan():
    st = output_speed_stats([35.0], B, C, D, [60.0])
    g = fourbar_motion(35.0, B, C, D, np.linspace(0, 2 * np.pi, 200_001), order=1).dgamma[0]
    assert st.ratio_max[0, 0] == pytest.approx(g.max(), abs=1e-9)
    assert st.ratio_min[0, 0] == pytest.approx(g.min(), abs=1e-9)


def test_no_clutch_drag_link_and_crank_rocker():
    # a drag link turns its output once per turn: mean = input speed; a crank-rocker without a
    # clutch has zero mean, so its cv is unbounded and flagged
    st = output_speed_stats([100.0], 80.0, 90.0, 30.0, [60.0], clutch="none")
    assert st.mean[0, 0] == pytest.approx(2 * np.pi, rel=1e-13) and st.status[0, 0] == 0
    mean, std = (lambda u: (u.mean(), u.std()))(
        speed_profile(100.0, 80.0, 90.0, 30.0, np.linspace(0, 2 * np.pi, 400_000, endpoint=False), clutch="none")
    )
    assert st.cv[0, 0] == pytest.approx(std / mean, rel=1e-8)
    st = output_speed_stats([20.0], B, C, D, [60.0], clutch="none")
    assert abs(st.mean[0, 0]) < 1e-12 and st.status[0, 0] & Status.AT_INFINITY and st.cv[0, 0] == 0


def test_minimum_cv_within_bounds():
    best = minimise_cv({"a": 20.0, "b": B, "c": C, "d": D}, {"a": (10.0, 40.0)}, phases=3)
    assert 10.0 <= best.a <= 40.0 and (best.b, best.c, best.d) == (B, C, D)
    grid = np.linspace(10.0, 40.0, 61)
    cvs = output_speed_stats(grid, B, C, D, [60.0], phases=3).cv[:, 0]
    assert best.cv <= cvs.min() + 1e-9
    two = minimise_cv({"a": 20.0, "b": B, "c": C, "d": D}, {"a": (10.0, 40.0), "c": (40.0, 70.0)}, phases=3)
    assert two.cv <= best.cv + 1e-12 and 40.0 <= two.c <= 70.0


def test_bad_input():
    with pytest.raises(AssemblyError, match="crank"):
        output_speed_stats([-1.0], B, C, D, [60])
    with pytest.raises(AssemblyError, match="input speeds"):
        output_speed_stats([10.0], B, C, D, [0.0])
    with pytest.raises(ValueError, match="clutch"):
        output_speed_stats([10.0], B, C, D, [60.0], clutch="ratchet")
    with pytest.raises(AssemblyError, match="no four-bar"):
        minimise_cv({"a": 70.0, "b": B, "c": C, "d": D}, {"a": (60.0, 70.0)})
    with pytest.raises(AssemblyError, match="unknown lengths"):
        minimise_cv({"a": 20.0, "b": B, "c": C, "d": D}, {"e": (1.0, 2.0)})
    assert math.isfinite(minimise_cv({"a": 20.0, "b": B, "c": C, "d": D}, {}).cv)
