"""The refinement's compiled loop figures (synth/query/refine_kernel.py) against the numpy path
they replace in the stillest search: the objective of trial six-bars around real ones (taken
from ``--band auto`` on the ``standard`` atlas), failures to assemble included, equal to
~1e-12; each figure against the figures' own functions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from synth.mechanism.buildability import clearances
from synth.mechanism.output_range import output_deviation
from synth.mechanism.sixbar import PIN_ON_PIVOT_EPS, crank_grid, kernel_inputs, simulate
from synth.query.candidates import Request
from synth.query.refine_kernel import FIGURES, trial_figures
from synth.query.refine_objective import CLEARANCE_EVERY, WORST, request_bounds, trial_batch, trial_objective

DEG = math.pi / 180

#: Six-bars the stillest search started from on ``standard`` (b, c, d, u, v, pivot x, pivot y,
#: rocker, rod; four-bar branch, RPR, dyad branch, the dwell's middle in rad) and the request.
BASES = {
    "rrr": (
        Request(dwell=60 * DEG, swing=30 * DEG, output="rrr", band=0.0031 * DEG),
        [
            ([2.5294739883, 2.03969802824, 3.23045699573, -0.133315678118, 9.14208041829, -15.2129202543,
              8.47496683404, 9.24250556285, 4.63696939466], 1, False, -1, 2.07778976036),
            ([2.79024139938, 3.00251323344, 4.32925882754, 0.453108807406, -6.13025219604, -9.3503859428,
              -4.97222960201, 4.76605362518, 3.77840692941], -1, False, 1, 4.0588380636),
            ([4.52379851598, 5.19411007502, 3.73609385378, 7.44030164325, 2.6442059832, 8.55443753209,
              -9.94220721422, 3.99769888496, 4.16203682797], -1, False, -1, 3.0512150862),
        ],
    ),
    "rpr": (
        Request(dwell=45 * DEG, swing=40 * DEG, output="rpr", band=0.0006 * DEG),
        [
            ([5.30304313428, 2.64518038993, 5.04022225512, 6.43173918012, -4.88751194846, 5.37257864176,
              -8.1292579815, 0.0, 0.0], -1, True, 1, 2.24161784325),
            ([2.63549024605, 2.97955707788, 3.37321024577, 3.65516627322, -6.89879945606, -7.45437792596,
              -3.90206932543, 0.0, 0.0], -1, True, 1, 4.37230810287),
            ([3.65372489842, 4.39161807188, 3.90483465383, 5.76335506242, 1.52247069684, 2.44218729034,
              6.79888337221, 0.0, 0.0], 1, True, 1, 3.27853133158),
        ],
    ),
}  # fmt: skip
_LENGTHS = np.array([1, 1, 1, 0, 0, 0, 0, 1, 1], bool)


def _trials(kind: str, seed: int, per_base: int, spread: float):
    """Trial rows around the bases of ``kind`` as the search draws them: each dimension moved by
    ``spread`` × a normal draw, relative to a length, or to max(|x|, 1) for a coordinate."""
    request, bases = BASES[kind]
    rng = np.random.default_rng(seed)
    rows = []
    for p0, branch, rpr, dyad_branch, centre in bases:
        p0 = np.array(p0)
        scale = np.where(_LENGTHS, np.abs(p0), np.maximum(np.abs(p0), 1.0))
        p = p0 + scale * spread * rng.standard_normal((per_base, 9))
        p[:, [0, 1, 2]] = np.abs(p[:, [0, 1, 2]])  # the search's box keeps lengths positive
        rows.append((p, np.full(per_base, branch), np.full(per_base, rpr), np.full(per_base, dyad_branch), centre))
    p, branch, rpr, dyad_branch = (np.concatenate([r[k] for r in rows]) for k in range(4))
    centres = np.concatenate([np.full((len(r[0]), 1), r[4]) for r in rows])
    return request, p, branch, rpr, dyad_branch, centres


def _both(request, p, branch, rpr, dyad_branch, centres, *, stillest: bool):
    bounds = request_bounds(request, len(p))
    phi = crank_grid(360)
    args = (request, p, branch, rpr, dyad_branch, centres, bounds, phi)
    return trial_objective(*args, stillest=stillest), trial_objective(*args, stillest=stillest, compiled=True)


@pytest.mark.parametrize("kind", ["rrr", "rpr"])
@pytest.mark.parametrize("stillest", [True, False])
def test_the_compiled_objective_is_the_numpy_one(kind, stillest):
    """300 trial rows per kind from steps of 0.1 % to 30 %: the same rows rejected, the others'
    objectives equal to 1e-9 relative (measured: ~4e-12 at most, rounding of |P − D| and the
    clearances); the rows cover still rests, penalised ones and failures to assemble."""
    parts = [_trials(kind, seed, 25, spread) for seed, spread in enumerate((0.001, 0.01, 0.1, 0.3))]
    request = parts[0][0]
    p, branch, rpr, dyad_branch, centres = (np.concatenate([part[k] for part in parts]) for k in range(1, 6))
    reference, compiled = _both(request, p, branch, rpr, dyad_branch, centres, stillest=stillest)
    rejected = reference == WORST
    np.testing.assert_array_equal(compiled == WORST, rejected)
    assert 10 <= rejected.sum() <= len(p) - 100  # failures included, most rows judged
    kept = ~rejected
    np.testing.assert_allclose(compiled[kept], reference[kept], rtol=1e-9, atol=0)
    if stillest:  # rows whose rest is within a few hundred bands, no penalty
        assert np.sum(reference[kept] < 1e3) >= 20
    assert np.sum(reference[kept] > 1e4) >= 20  # and rows a constraint penalises


@settings(max_examples=15, deadline=None)
@given(
    kind=st.sampled_from(["rrr", "rpr"]),
    seed=st.integers(0, 2**32 - 1),
    spread=st.floats(1e-4, 0.3),
    stillest=st.booleans(),
)
def test_the_objectives_agree_on_any_draw(kind, seed, spread, stillest):
    request, p, branch, rpr, dyad_branch, centres = _trials(kind, seed, 8, spread)
    reference, compiled = _both(request, p, branch, rpr, dyad_branch, centres, stillest=stillest)
    np.testing.assert_array_equal(compiled == WORST, reference == WORST)
    np.testing.assert_allclose(compiled, reference, rtol=1e-9, atol=0)


def test_each_figure_is_the_figures_functions_one():
    """The kernel's figures of assembling six-bars against simulate, output_deviation (two
    centres, three window lengths) and clearances on every 3rd sample."""
    request, p, branch, rpr, dyad_branch, centres = _trials("rrr", 7, 6, 0.01)
    _, p2, branch2, rpr2, dyad2, centres2 = _trials("rpr", 7, 6, 0.01)
    p, branch, rpr, dyad_branch = (
        np.concatenate(x) for x in ((p, p2), (branch, branch2), (rpr, rpr2), (dyad_branch, dyad2))
    )
    centres = np.concatenate([centres, centres2])
    centres = np.concatenate([centres, centres + 0.3], axis=1)  # (N, 2)
    lengths = np.tile([40 * DEG, 90 * DEG, 200 * DEG], (len(p), 1))
    batch = trial_batch(p, branch, rpr, dyad_branch)
    params, kinds = kernel_inputs(batch)
    phi = crank_grid(360)
    good, dev, figures = trial_figures(params, kinds, phi, PIN_ON_PIVOT_EPS, centres, lengths, CLEARANCE_EVERY)

    motion = simulate(batch, phi, order=0)
    assert good.all() and np.all(motion.status == 0)
    psi = motion.psi
    R, M = psi.shape
    expected, _ = output_deviation(
        phi,
        np.broadcast_to(psi[:, None, None, :], (R, 2, 3, M)),
        np.broadcast_to(centres[:, :, None], (R, 2, 3)),
        np.broadcast_to(lengths[:, None, :], (R, 2, 3)),
    )
    np.testing.assert_array_equal(dev, expected)  # the same samples, max and min round nothing
    reach = np.abs(motion.z[0] - batch.pivot[:, None])
    want = {
        "swing": psi.max(axis=1) - psi.min(axis=1),
        "transmission": np.minimum(motion.transmission_fourbar.min(axis=1), motion.transmission_output.min(axis=1)),
        "reach": reach.max(axis=1),
        "arm": reach.min(axis=1),
        "clearance": clearances(batch, motion, every=CLEARANCE_EVERY)[1],
    }
    for k, name in enumerate(FIGURES):
        np.testing.assert_allclose(figures[:, k], want[name], rtol=1e-13, atol=0, err_msg=name)
    assert np.all(figures[:, 1] > 0.1) and np.all(figures[:, 4] > 0.01)  # real values, not placeholders


def test_a_row_that_does_not_assemble_is_rejected_whole():
    """A coupler too short to close the four-bar: not good, zeros (never NaN), and WORST."""
    request, p, branch, rpr, dyad_branch, centres = _trials("rrr", 0, 1, 0.0)  # the three bases
    p[1, 0] = 0.01  # b: the loop cannot close
    batch = trial_batch(p, branch, rpr, dyad_branch)
    params, kinds = kernel_inputs(batch)
    good, dev, figures = trial_figures(
        params, kinds, crank_grid(360), PIN_ON_PIVOT_EPS, centres, np.full((len(p), 1), 1.0), 3
    )
    assert good.tolist() == [True, False, True]
    assert np.all(dev[1] == 0) and np.all(figures[1] == 0) and np.isfinite(dev).all() and np.isfinite(figures).all()
    reference, compiled = _both(request, p, branch, rpr, dyad_branch, centres, stillest=True)
    assert compiled[1] == reference[1] == WORST
    assert compiled[[0, 2]] == pytest.approx(reference[[0, 2]], rel=1e-12) and np.all(compiled[[0, 2]] < WORST)


def test_a_capped_acceleration_takes_the_numpy_path():
    """With ``max_accel`` the objective needs ψ″ (order 2): compiled or not, the same numbers."""
    request, p, branch, rpr, dyad_branch, centres = _trials("rpr", 3, 10, 0.02)
    capped = Request(dwell=request.dwell, swing=request.swing, output="rpr", band=request.band, max_accel=5.0)
    reference, compiled = _both(capped, p, branch, rpr, dyad_branch, centres, stillest=True)
    np.testing.assert_array_equal(compiled, reference)
    uncapped, _ = _both(request, p, branch, rpr, dyad_branch, centres, stillest=True)
    assert np.any(reference > uncapped)  # the cap penalises some rows: the path matters
