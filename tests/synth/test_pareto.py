"""Pareto layers (synth.query.pareto) against peeling spelled out: layer 0 the points nothing
dominates, then the front of the rest, and so on."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from synth.query.pareto import pareto_layers


def _peeled(obj: np.ndarray) -> np.ndarray:
    n = obj.shape[0]
    layer = np.full(n, -1)
    remaining = set(range(n))
    k = 0
    while remaining:
        front = {
            i for i in remaining if not any(np.all(obj[j] <= obj[i]) and np.any(obj[j] < obj[i]) for j in remaining)
        }
        for i in front:
            layer[i] = k
        remaining -= front
        k += 1
    return layer


@settings(max_examples=150, deadline=None)
@given(
    st.integers(1, 5).flatmap(
        lambda k: st.lists(st.lists(st.integers(0, 4), min_size=k, max_size=k), min_size=1, max_size=40)
    )
)
@example([[0, 1], [1, 0], [1, 1], [1, 1], [2, 2]])  # a tie: equal points share a layer
@example([[3, 0, 0], [2, 1, 0], [1, 2, 0], [0, 3, 1], [3, 3, 3]])
def test_layers_are_the_peeled_fronts(points):
    obj = np.array(points, float)
    assert pareto_layers(obj).tolist() == _peeled(obj).tolist()


def test_a_chain_and_an_antichain():
    chain = np.arange(6, dtype=float)[::-1, None] * np.ones((1, 3))  # each dominates the ones before it
    assert pareto_layers(chain).tolist() == [5, 4, 3, 2, 1, 0]
    antichain = np.stack([np.arange(5.0), -np.arange(5.0)], axis=1)
    assert pareto_layers(antichain).tolist() == [0] * 5


def test_many_points_in_linear_memory():
    # the size at which the pairwise peel needed ~2 GB: 20 000 points, 5 objectives
    rng = np.random.default_rng(1)
    obj = rng.random((20_000, 5))
    layer = pareto_layers(obj)
    front = obj[layer == 0]
    # no point of the front is dominated by any point; every other point by one of the layer above
    for block in np.array_split(obj, 20):
        dominated = np.all(block[:, None, :] <= front[None], axis=2) & np.any(block[:, None, :] < front[None], axis=2)
        assert not dominated.any()
    second = obj[layer == 1]
    cover = np.all(front[:, None, :] <= second[None], axis=2) & np.any(front[:, None, :] < second[None], axis=2)
    assert cover.any(axis=0).all()


def test_refuses_nan_and_wrong_shapes():
    with pytest.raises(ValueError, match="NaN"):
        pareto_layers(np.array([[0.0, np.nan]]))
    with pytest.raises(ValueError, match=r"\(n, k\)"):
        pareto_layers(np.zeros(3))
