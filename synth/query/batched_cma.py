"""CMA-ES for many independent small problems at once (pure: arrays in, arrays out).

The (μ/μ_w, λ)-CMA-ES of Hansen's tutorial (N. Hansen, "The CMA Evolution Strategy: A
Tutorial", arXiv:1604.00772, 2016/2023: the default parameters of its Table 1, cumulative
step-size adaptation, rank-one and rank-μ covariance updates with the active (negative)
weights of its eq. 53, as the ``cma`` package uses by default), run for K problems of the same
dimension in lockstep: every problem's λ trial points are evaluated in one call, the updates
are batched numpy over (K, n, n) arrays. That shape is why it is written here: a library
instance per problem (``cma``, Hansen's own) costs ~2 ms of Python per problem and iteration
at n = 9, λ = 16 — most of a refinement's reach — where the batch costs a few µs each.

Box constraints are handled by repair: a trial point is clipped into the box before it is
evaluated, and the step it contributes to the update is recomputed from the clipped point
(Hansen's "Lamarckian" repair), so the mean never leaves the box.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["CMAResult", "cma_es"]


@dataclass(frozen=True, slots=True)
class CMAResult:
    """The outcome for K problems.

    Attributes
    ----------
    x : ndarray (K, n)
        Best point seen per problem (the start where nothing beat it).
    f : ndarray (K,)
        Its objective.
    evaluations : ndarray (K,)
        Points evaluated per problem (the start included).
    iterations : ndarray (K,)
        Iterations each problem ran.
    """

    x: np.ndarray
    f: np.ndarray
    evaluations: np.ndarray
    iterations: np.ndarray


def _whiten(B: np.ndarray, D: np.ndarray, v: np.ndarray) -> np.ndarray:
    """C^(−1/2)·v = B·diag(1/D)·Bᵀ·v per problem (C = B·diag(D²)·Bᵀ; v (W, n) or (W, T, n))."""
    return np.einsum("kij,kj,klj,k...l->k...i", B, 1.0 / D, B, v)


def cma_es(
    evaluate: Callable[[np.ndarray, np.ndarray], np.ndarray],
    start: np.ndarray,
    sigma: float,
    rngs: Sequence[np.random.Generator],
    *,
    population: int = 16,
    iterations: int = 100,
    box: float = math.inf,
    stop_below: float = -math.inf,
    tol_sigma: float = 1e-12,
) -> CMAResult:
    """Minimise K problems from ``start`` (K, n), all at once.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(x, who)``: objectives (len(who), T) of the points x (len(who), T, n) of
        problems ``who`` (indices into ``start``); lower is better (+inf and NaN rank last).
    start : ndarray (K, n)
        Initial means; also the points the best is compared with.
    sigma : float
        Initial step size (the same unit in every coordinate).
    rngs : sequence of numpy Generator, one per problem
        Each problem's normal draws (a problem's run does not depend on the others).
    population : int
        λ, trial points per problem and iteration (≥ 4).
    iterations : int
        Iterations at most.
    box : float
        Every coordinate is kept within ±``box`` (repair, see the module docstring).
    stop_below : float
        A problem stops once its best objective is below this.
    tol_sigma : float
        A problem stops when σ times the square root of C's largest eigenvalue falls below it.
    """
    start = np.asarray(start, float)
    K, n = start.shape
    if population < 4 or len(rngs) != K:
        raise ValueError("cma_es needs population >= 4 and one generator per problem")
    lam = population
    mu = lam // 2
    raw = math.log((lam + 1) / 2) - np.log(np.arange(1, lam + 1))  # w'_i, positive for i ≤ μ
    mueff = raw[:mu].sum() ** 2 / float(np.sum(raw[:mu] ** 2))
    mueff_neg = raw[mu:].sum() ** 2 / float(np.sum(raw[mu:] ** 2))
    cs = (mueff + 2) / (n + mueff + 5)
    ds = 1 + 2 * max(0.0, math.sqrt((mueff - 1) / (n + 1)) - 1) + cs
    cc = (4 + mueff / n) / (n + 4 + 2 * mueff / n)
    c1 = 2 / ((n + 1.3) ** 2 + mueff)
    cmu = min(1 - c1, 2 * (mueff - 2 + 1 / mueff) / ((n + 2) ** 2 + mueff))
    # active CMA: the worse half gets negative weights (the tutorial's eq. 53)
    neg = min(1 + c1 / cmu, 1 + 2 * mueff_neg / (mueff + 2), (1 - c1 - cmu) / (n * cmu))
    w = np.where(raw >= 0, raw / raw[raw >= 0].sum(), neg * raw / -raw[raw < 0].sum())
    chin = math.sqrt(n) * (1 - 1 / (4 * n) + 1 / (21 * n * n))

    mean = np.clip(start, -box, box)
    step = np.full(K, float(sigma))
    C = np.broadcast_to(np.eye(n), (K, n, n)).copy()
    B = C.copy()
    D = np.ones((K, n))
    ps = np.zeros((K, n))
    pc = np.zeros((K, n))
    g = np.zeros(K, int)
    best_x = start.copy()
    best_f = evaluate(start[:, None, :], np.arange(K))[:, 0]
    count = np.ones(K, int)
    active = best_f >= stop_below
    for _ in range(iterations):
        who = np.flatnonzero(active)
        if not len(who):
            break
        z = np.stack([rngs[k].standard_normal((lam, n)) for k in who])  # (W, λ, n)
        y = np.einsum("kij,kj,klj->kli", B[who], D[who], z)  # B·diag(D)·z
        x = np.clip(mean[who, None, :] + step[who, None, None] * y, -box, box)  # repaired
        y = (x - mean[who, None, :]) / step[who, None, None]
        f = evaluate(x, who)
        count[who] += lam
        order = np.argsort(np.where(np.isnan(f), np.inf, f), axis=1, kind="stable")
        top = f[np.arange(len(who)), order[:, 0]]
        better = top < best_f[who]
        best_x[who[better]] = x[better, order[better, 0]]
        best_f[who[better]] = top[better]

        ranked = np.take_along_axis(y, order[:, :, None], axis=1)  # (W, λ, n), best first
        yw = np.einsum("i,kin->kn", w[:mu], ranked[:, :mu])
        mean[who] = mean[who] + step[who, None] * yw
        g[who] += 1
        ps[who] = (1 - cs) * ps[who] + math.sqrt(cs * (2 - cs) * mueff) * _whiten(B[who], D[who], yw)
        norm = np.linalg.norm(ps[who], axis=1)
        hs = norm / np.sqrt(1 - (1 - cs) ** (2 * g[who])) < (1.4 + 2 / (n + 1)) * chin
        pc[who] = (1 - cc) * pc[who] + (hs * math.sqrt(cc * (2 - cc) * mueff))[:, None] * yw
        # the negative weights act on steps rescaled to the length n has under C (eq. 46)
        length2 = np.sum(_whiten(B[who], D[who], ranked) ** 2, axis=2)
        wo = np.where(w >= 0, w, w * n / np.maximum(length2, 1e-300))  # (W, λ)
        rank_mu = np.einsum("ki,kin,kim->knm", wo, ranked, ranked)
        keep = 1 + (~hs) * c1 * cc * (2 - cc) - c1 - cmu * w.sum()
        C[who] = keep[:, None, None] * C[who] + c1 * np.einsum("kn,km->knm", pc[who], pc[who]) + cmu * rank_mu
        step[who] *= np.exp(np.minimum(1.0, (cs / ds) * (norm / chin - 1)))
        sym = 0.5 * (C[who] + np.swapaxes(C[who], 1, 2))
        ev, vec = np.linalg.eigh(sym)
        ev = np.maximum(ev, 1e-300)
        C[who], B[who], D[who] = sym, vec, np.sqrt(ev)
        spread = step[who] * D[who].max(axis=1)
        active[who] = (best_f[who] >= stop_below) & (spread >= tol_sigma) & (ev.max(axis=1) < 1e14 * ev.min(axis=1))
    return CMAResult(best_x, best_f, count, g)
