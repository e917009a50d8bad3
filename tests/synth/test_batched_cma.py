"""The batched CMA-ES (synth/query/batched_cma.py): it solves what an isotropic step size cannot —
ill-conditioned, rotated quadratics — for many problems at once, each problem's run
independent of the others, inside its box."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from synth.query.batched_cma import cma_es


def _ellipsoids(K: int, n: int, condition: float, seed: int):
    """K rotated ellipsoids f(x) = Σ λ_i ((x − x*)·q_i)², eigenvalues from 1 to ``condition``,
    minima x* in [−0.5, 0.5]^n; f as ``cma_es`` evaluates it."""
    rng = np.random.default_rng(seed)
    Q = np.linalg.qr(rng.standard_normal((K, n, n)))[0]
    lam = condition ** (np.arange(n) / (n - 1))
    H = np.einsum("kij,j,klj->kil", Q, lam, Q)
    xstar = rng.uniform(-0.5, 0.5, (K, n))

    def evaluate(x, who):
        d = x - xstar[who, None, :]
        return np.einsum("kti,kij,ktj->kt", d, H[who], d)

    return evaluate, xstar


def _rngs(K: int, seed: int = 7):
    return [np.random.default_rng([seed, k]) for k in range(K)]


def test_rotated_ill_conditioned_quadratics_are_solved_in_a_batch():
    """Nine dimensions, condition 1e4, six problems at once: every minimum found to 1e-6 in
    x, with f below 1e-10 (the start's f is ~1e3)."""
    K, n = 6, 9
    evaluate, xstar = _ellipsoids(K, n, 1e4, seed=1)
    start = np.zeros((K, n))
    f0 = evaluate(start[:, None, :], np.arange(K))[:, 0]
    out = cma_es(evaluate, start, 0.3, _rngs(K), population=16, iterations=600)
    assert np.all(f0 > 10)
    assert np.all(out.f < 1e-10)
    assert np.abs(out.x - xstar).max() < 1e-6
    assert np.all(out.evaluations == 1 + 16 * out.iterations)


def test_an_isotropic_strategy_stalls_where_it_does_not():
    """The reason for CMA-ES: at condition 1e6 the (1 + λ) polish of synth.query.refine with the same
    number of evaluations ends far above the minimum; CMA-ES reaches it."""
    from synth.query.refine import descend

    K, n = 4, 9
    evaluate, _ = _ellipsoids(K, n, 1e6, seed=2)
    start = np.zeros((K, n))
    out = cma_es(evaluate, start, 0.3, _rngs(K), population=16, iterations=800, box=1.0)
    x, f, count = descend(evaluate, start, 1.0, 800, 16, 0)
    assert np.all(out.f < 1e-8)
    assert np.all(f > 1e3 * out.f.max()) and np.all(count <= out.evaluations.max() + 16)


def test_each_problem_runs_as_if_alone():
    """Problem k's result with its generator is the same alone as in a batch of five."""
    K, n = 5, 9
    evaluate, _ = _ellipsoids(K, n, 1e3, seed=3)
    start = np.zeros((K, n))
    batch = cma_es(evaluate, start, 0.3, _rngs(K), iterations=60)
    for k in (0, 3):
        alone = cma_es(
            lambda x, who: evaluate(x, np.array([k])[who]),
            start[k : k + 1],
            0.3,
            [np.random.default_rng([7, k])],
            iterations=60,
        )
        assert np.array_equal(alone.x[0], batch.x[k]) and alone.f[0] == batch.f[k]


@settings(max_examples=25, deadline=None)
@example(box=1.0, shift=0.0, stop=1.0, seed=0)  # the start is the minimum: no iteration
@given(box=st.floats(0.01, 2.0), shift=st.floats(-3.0, 3.0), stop=st.floats(1e-3, 1e3), seed=st.integers(0, 2**16))
def test_points_stay_in_the_box_and_the_best_is_what_was_seen(box, shift, stop, seed):
    """Every evaluated point lies within ±box; the best returned is the smallest f seen (or the
    start); a problem stops once below ``stop_below``; NaN objectives are ranked last."""
    K, n = 3, 4
    seen = []

    def evaluate(x, who):
        assert np.all(np.abs(x) <= box)
        f = np.sum((x - shift) ** 2, axis=-1)
        f = np.where(x[..., 0] > 0.9 * box, np.nan, f)  # a region where the objective fails
        seen.append((who.copy(), x.copy(), f.copy()))
        return f

    out = cma_es(evaluate, np.zeros((K, n)), 0.3 * box, _rngs(K, seed), iterations=40, box=box, stop_below=stop)
    for k in range(K):
        fk = [f[list(w).index(k)] for w, _, f in seen if k in w]
        values = np.concatenate([v[np.isfinite(v)] for v in fk])
        assert out.f[k] == pytest.approx(values.min())
        assert np.all(np.abs(out.x[k]) <= box)
        runs = [i for i, (w, _, _) in enumerate(seen[1:], 1) if k in w]
        assert len(runs) == out.iterations[k]
        if seen[0][2][k, 0] < stop:  # the start is good enough: no iteration
            assert runs == []
        elif out.f[k] < stop:  # it stopped at the first iteration whose best fell below stop
            firsts = [i for i in runs if np.nanmin(seen[i][2][list(seen[i][0]).index(k)]) < stop]
            assert firsts and runs[-1] == firsts[0]
