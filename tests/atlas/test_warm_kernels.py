"""The build's forkserver warms a shard's compiled kernels (:mod:`atlas.warm_kernels`): after
its small shard, a real shard compiles nothing more, so the forked workers compile nothing."""

from __future__ import annotations

import sys

import numba

from atlas.shard import compute_shard
from atlas.sweep import PRESETS
from synth import parallel_rows


def _compiled() -> dict[str, int]:
    """Signatures compiled so far, per kernel of the loaded synth and kinematics modules."""
    counts = {}
    for name, module in list(sys.modules.items()):
        if not name.startswith(("synth.", "kinematics.")):
            continue
        for attr, value in vars(module).items():
            if isinstance(value, numba.core.registry.CPUDispatcher):
                counts[f"{name}.{attr}"] = len(value.signatures)
    return counts


def test_after_the_warm_shard_a_real_shard_compiles_nothing():
    import atlas.warm_kernels  # noqa: F401 - its import warms (as in the forkserver)
    from atlas.warm_kernels import warm_shard_kernels

    parallel_rows.set_threads(3)
    try:
        warm_shard_kernels()
        assert parallel_rows.threads() == 3  # put back
        before = _compiled()
        # compiled (once, or more if another test of this process met other types)
        assert before["synth.segment_search.dwell_measure.measure_dwells"] >= 1
        assert before["synth.curvature.double_ball_kernel.box_sweep"] >= 1
        parallel_rows.set_threads(1)  # as a worker with the cores shared out
        result = compute_shard(PRESETS["demo"], 7)
        assert result.n_segments > 100
        after = _compiled()
        assert {k: n for k, n in after.items() if before.get(k, 0) != n} == {}
    finally:
        parallel_rows.set_threads(parallel_rows._default_threads())
