"""A small ``dwell bench stability`` run: random and adversarial cases (link ratios 1e-3…1e3,
change points ± 1e-12, 1e-9 rad from toggles and from θ′ = 0, rays 1e-12 rad from the pole
tangent and normal, coupler points 1e6 cranks away). The cases are the benchmark's own
(:mod:`cli.bench.stability`); the last test turns them on line scanning's gates."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from cli.bench.stability import FAMILIES, evaluate_cases, make_cases, stability_summary
from kinematics.status import Status
from synth import line_scan
from synth.curvature.line_scan import ACCURACY

line_scan_module = importlib.import_module("synth.curvature.line_scan")


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
    """The product's bar, 1e-9 of a crank, for every kind, centre points included."""
    worst = summary["max_residual_unflagged"]
    assert set(worst) == {"pole", "inflection_circle", "ball_point", "circle_point", "center_point", "euler_savary"}
    for kind, value in worst.items():
        assert value <= ACCURACY, (kind, value)
    assert summary["max_residual_unflagged_overall"] <= ACCURACY, worst


def test_ordinary_crank_rockers_are_rarely_flagged(summary):
    """Beyond the adversarial rays (four per instant along the pole tangent and normal), about
    one line-scanning result in a thousand of an ordinary crank-rocker is an accuracy skip."""
    family = summary["by_family"]["crank_rocker"]
    instants = family["items"]["pole"]
    extra = family["flagged"]["line_scan"] - 4 * (instants - family["flagged"]["pole"])
    assert extra <= 0.01 * 2 * instants, family


def test_the_gates_only_skip_rays_that_pass(monkeypatch):
    """Line scanning evaluates the error estimates only on candidate rays (below per-instant
    gates); with every ray a candidate the flags and values are the same."""
    got = evaluate_cases(make_cases(3000, seed=5))
    pl, scan = got["pole"], got["line_scan"]
    assert np.count_nonzero(scan.status & (Status.CIRCLE_POINT_AT_INFINITY | Status.CENTER_POINT_AT_INFINITY)) > 0

    def every_ray(err, abs_z2, cancel, invalid):
        return np.where(invalid, 0.0, np.inf), np.where(invalid, 0.0, np.inf)

    monkeypatch.setattr(line_scan_module, "_gates", every_ray)
    full = line_scan(pl, scan.alpha)
    for name in ("status", "circle_point", "circle_point_uv", "center_point", "radius"):
        np.testing.assert_array_equal(getattr(full, name), getattr(scan, name), err_msg=name)
