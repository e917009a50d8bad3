"""Sweep specification: determinism, validation, presets' sizes, canonical JSON."""

from __future__ import annotations

import numpy as np
import pytest

from atlas import PRESETS, SweepSpec, SweepSpecError, sweep_linkages
from kinematics import GrashofType, grashof_type


def test_same_spec_same_linkages_and_crank_rockers_only():
    spec = PRESETS["demo"]
    one, two = sweep_linkages(spec), sweep_linkages(SweepSpec.from_dict(spec.to_dict()))
    for x, y in zip((one.b, one.c, one.d, one.sweep_index), (two.b, two.c, two.d, two.sweep_index)):
        assert np.array_equal(x, y)
    assert np.all(grashof_type(1.0, one.b, one.c, one.d) == GrashofType.CRANK_ROCKER)
    assert np.all(np.diff(one.sweep_index) > 0)
    lo, hi = spec.b
    assert one.b.min() >= lo and one.b.max() <= hi


def test_seed_changes_the_draw():
    a = sweep_linkages(PRESETS["demo"])
    b = sweep_linkages(PRESETS["demo"].replace(seed=1))
    assert not np.array_equal(a.b[:10], b.b[:10])


def test_shards_partition_the_sweep():
    spec = PRESETS["demo"]
    sweep = sweep_linkages(spec)
    parts = [sweep.shard(i, spec.shard_size) for i in range(sweep.n_shards(spec.shard_size))]
    assert np.array_equal(np.concatenate([p.sweep_index for p in parts]), sweep.sweep_index)
    assert all(len(p) > 0 for p in parts)


@pytest.mark.parametrize("name, minimum", [("standard", 20_000), ("large", 1_000_000)])
def test_preset_sizes(name, minimum):
    spec = PRESETS[name]
    assert len(sweep_linkages(spec)) * len(spec.branches) >= minimum


def test_digest_ignores_name_but_not_content():
    spec = PRESETS["demo"]
    assert spec.replace(name="other").digest == spec.digest
    assert spec.replace(rays=25).digest != spec.digest
    assert SweepSpec.from_dict(spec.to_dict()).to_json() == spec.to_json()


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"b": (-1.0, 2.0)}, "range b"),
        ({"c": (3.0, 2.0)}, "range c"),
        ({"d": (1.0, float("inf"))}, "range d"),
        ({"samples": 0}, "samples"),
        ({"branches": (1, 2)}, "branches"),
        ({"branches": ()}, "branches"),
        ({"crank_step_deg": 0.0}, "crank_step_deg"),
        ({"rays": 0}, "rays"),
        ({"tolerances": (1e-3, 1e-4)}, "increasing"),
        ({"tolerances": (0.0,)}, "tolerances"),
        ({"min_dwell_deg": 400.0}, "min_dwell_deg"),
        ({"shard_size": 0}, "shard_size"),
    ],
)
def test_bad_specs_name_the_field(changes, message):
    with pytest.raises(SweepSpecError, match=message):
        PRESETS["demo"].replace(**changes)


def test_unknown_field():
    with pytest.raises(SweepSpecError, match="unknown sweep field"):
        SweepSpec.from_dict({"bogus": 1})
