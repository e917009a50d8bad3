"""Double Ball points: θ⁗ and the track derivative, completeness, dead-centre rejection,
deduplication, tangent lines, bad input. (Ball at both angles, to 40 digits: test_accuracy.)"""

from __future__ import annotations

import numpy as np
import pytest
from mp_fourbar import Instant
from test_accuracy import crank_rockers

from kinematics.fourbar import fourbar_motion, rocker_limits
from kinematics.status import AssemblyError, Status
from synth import ball_point_offset, ball_point_offset_rate, double_ball_points, theta4


@pytest.fixture(scope="module")
def linkages():
    rows = crank_rockers(12, 99)
    return rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], rows[:, 4]


def test_theta4_matches_40_digit_differentiation():
    for a, b, c, d, br, phi in crank_rockers(20, 5):
        m = fourbar_motion(a, b, c, d, phi, br)
        ref = float(Instant(a, b, c, d, br, phi).dtheta[3])
        assert float(theta4(m)) == pytest.approx(ref, rel=1e-11, abs=1e-12)


def test_ball_track_rate_matches_a_central_difference():
    """dŵ/dφ by the chain rule against a central difference of ŵ(φ) at a safe step."""
    h = 1e-5
    for a, b, c, d, br, phi in crank_rockers(10, 6):

        def w(p):
            m = fourbar_motion(a, b, c, d, p, br)
            n, den = ball_point_offset(*m.dtheta)
            return complex(n / den)

        m = fourbar_motion(a, b, c, d, phi, br)
        value, rate = ball_point_offset_rate(*m.dtheta, theta4(m))
        assert complex(value) == pytest.approx(w(phi), rel=1e-13)
        fd = (w(phi + h) - w(phi - h)) / (2 * h)
        assert abs(complex(rate) - fd) <= 1e-7 * (1 + abs(fd))


def test_every_crank_rocker_has_double_ball_points_sorted_and_unique(linkages):
    found = double_ball_points(*linkages)
    counts = np.bincount(found.linkage_index, minlength=12)
    assert np.all(counts >= 1) and counts.max() <= 32
    assert np.all((0 <= found.phi1) & (found.phi1 < found.phi2) & (found.phi2 < 2 * np.pi))
    for k in range(12):
        sel = found.linkage_index == k
        pairs = np.stack([found.phi1[sel], found.phi2[sel]], axis=1)
        gaps = np.abs(pairs[:, None, :] - pairs[None, :, :]).max(axis=2) + np.eye(sel.sum())
        assert gaps.min() > 1e-6
    assert np.all(found.status == 0) and np.all(found.unconverged == 0)


def test_denser_sampling_finds_the_same_points(linkages):
    coarse = double_ball_points(*linkages)
    fine = double_ball_points(*linkages, samples=16384)
    assert len(coarse) == len(fine)
    np.testing.assert_allclose(coarse.phi1, fine.phi1, atol=1e-10)
    np.testing.assert_allclose(coarse.phi2, fine.phi2, atol=1e-10)
    np.testing.assert_allclose(coarse.uv, fine.uv, atol=1e-9)


def test_batch_equals_one_at_a_time(linkages):
    batch = double_ball_points(*linkages)
    for k in (0, 5):
        one = double_ball_points(*(x[k] for x in linkages))
        np.testing.assert_allclose(one.uv, batch.uv[batch.linkage_index == k], atol=1e-12)


def test_dead_centre_crossing_at_b_is_rejected_not_returned(linkages):
    a, b, c, d, br = linkages
    found = double_ball_points(*linkages)
    assert np.all(found.false_crossings == 1)  # the track passes through B at both dead-centres
    assert np.all(np.abs(found.uv - b[found.linkage_index]) > 1e-6)
    # B is Ball's point (= the pole) at the rocker dead-centres
    for k in range(3):
        lim = rocker_limits(a[k], b[k], c[k], d[k], int(br[k]))
        for phi in (lim.phi_extended, lim.phi_folded):
            m = fourbar_motion(a[k], b[k], c[k], d[k], phi, br[k])
            n, den = ball_point_offset(*m.dtheta)
            p = complex(np.conj(m.e_theta) * m.A * n / den)
            assert abs(p - b[k]) < 1e-9 * b[k]


def test_tangent_lines_are_the_coupler_path_tangents(linkages):
    a, b, c, d, br = linkages
    found = double_ball_points(*linkages)
    k = found.linkage_index
    for phi, point, tangent in ((found.phi1, found.point1, found.tangent1), (found.phi2, found.point2, found.tangent2)):
        m = fourbar_motion(a[k], b[k], c[k], d[k], phi, br[k], order=1)
        z, dz = m.coupler_point(found.uv.real, found.uv.imag, order=1)
        np.testing.assert_allclose(point, z, atol=1e-12)
        np.testing.assert_allclose(tangent, dz / np.abs(dz), atol=1e-12)


def test_linkage_that_never_assembles():
    found = double_ball_points(1.0, 1.0, 1.0, 5.0)
    assert len(found) == 0 and found.status[0] & Status.NOT_ASSEMBLABLE
    with pytest.raises(AssemblyError, match="cannot assemble"):
        double_ball_points(1.0, 1.0, 1.0, 5.0, on_degenerate="raise")


@pytest.mark.parametrize(
    "kwargs, error",
    [
        ({"a": -1.0}, AssemblyError),
        ({"a": np.nan}, AssemblyError),
        ({"samples": 10}, ValueError),
        ({"reach": 0.0}, ValueError),
        ({"on_degenerate": "skip"}, ValueError),
    ],
)
def test_bad_arguments(kwargs, error):
    args = {"a": 1.0, "b": 3.0, "c": 2.5, "d": 3.0}
    args.update(kwargs)
    with pytest.raises(error):
        double_ball_points(**args)


@pytest.mark.parametrize("kite", [(1, 1, 10, 10), (1, 1, 1.5, 1.5), (1, 1, 2, 2), (1, 1, 3, 3), (2, 3, 3, 2)])
def test_a_kite_track_standing_still_gives_no_crossing_seeds(kite, monkeypatch):
    """A kite (a = b, c = d) parks its Ball-point track on one spot, moving by rounding noise:
    those samples are not usable, so the crossing search gets no noise seeds (it got 1.3-3.7
    million, 15-30 s and ~3 GB, before) and finds no double Ball point there."""
    import synth.curvature.double_ball as module

    seeds = []
    crossings = module._crossings

    def counted(*args):
        found = crossings(*args)
        seeds.append(found[0].size)
        return found

    monkeypatch.setattr(module, "_crossings", counted)
    found = double_ball_points(*kite, 1)
    assert len(found.uv) == 0
    assert sum(seeds) < 100, seeds
