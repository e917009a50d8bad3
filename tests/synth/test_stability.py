"""A small ``dwell bench stability`` run: random and adversarial cases (link ratios 1e-3…1e3,
change points ± 1e-12, 1e-9 rad from toggles and from θ′ = 0, rays 1e-12 rad from the pole
tangent and normal, coupler points 1e6 cranks away)."""

from __future__ import annotations

import pytest

from cli.bench.stability import FAMILIES, stability_summary


@pytest.fixture(scope="module")
def summary():
    return stability_summary(2000, seed=11)


def test_no_nan_or_inf_and_no_undocumented_exception(summary):
    assert summary["nonfinite_values"] == 0
    assert summary["exceptions"] == {}
    assert summary["raise_mode"]["other_exceptions"] == 0
    assert summary["raise_mode"]["assembly_error"] > 0  # the documented one does occur


def test_every_family_ran_and_the_adversaries_are_flagged(summary):
    assert all(summary["families"][f] > 200 for f in FAMILIES)
    pole_flags = summary["flagged"]["pole"]
    for reason in ("not_assemblable", "ill_conditioned", "pole_at_infinity"):
        assert pole_flags.get(reason, 0) > 0, reason
    scan_flags = summary["flagged"]["line_scan"]
    # two rays per instant within 1e-12 rad of the pole tangent, two of the pole normal
    assert scan_flags["ray_along_pole_tangent"] == scan_flags["at_pole"] == 2 * summary["unflagged"]["pole"]


def test_unflagged_results_are_accurate(summary):
    worst = summary["max_residual_unflagged"]
    assert summary["max_residual_unflagged_overall"] <= 1e-7, worst
    for kind in ("pole", "inflection_circle", "ball_point", "circle_point", "euler_savary"):
        assert worst[kind] <= 1e-9, (kind, worst[kind])
