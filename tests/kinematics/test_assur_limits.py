"""Limit positions: closed forms (four-bar, slider-crank, Scotch yoke) and a dense scan (six-bars)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from assur_builders import example

from kinematics.assur import (
    assemble,
    configurations,
    limit_positions,
    linkage_from_mapping,
    linkage_motion,
    output_series,
)
from kinematics.fourbar import rocker_limits
from kinematics.status import AssemblyError


def test_fourbar_limits_match_the_closed_form():
    lk = example("fourbar.toml")
    ref = rocker_limits(50, 80, 80, 100, 1)
    lim = limit_positions(lk, configurations(lk, [0.0])[0], lk.output)
    assert [p.kind for p in lim.positions] == ["min", "max"]
    lo, hi = lim.positions
    assert lo.input == pytest.approx(ref.phi_extended, abs=1e-10)
    assert hi.input == pytest.approx(ref.phi_folded, abs=1e-10)
    assert lo.output == pytest.approx(ref.gamma_extended, abs=1e-10)
    assert hi.output == pytest.approx(ref.gamma_folded, abs=1e-10)
    assert lim.stroke == pytest.approx(ref.swing, abs=1e-10)
    assert lim.time_ratio == pytest.approx(ref.time_ratio, abs=1e-9)
    assert lim.full_turn and lim.advance + lim.return_ == pytest.approx(2 * math.pi)


@pytest.mark.parametrize("offset", [0.0, 20.0, -35.0])
def test_slider_crank_dead_centres(offset):
    l1, l2 = 50.0, 150.0
    lk = linkage_from_mapping(
        {
            "ground": {"A": [0, 0]},
            "links": {
                "crank": {"joints": ["A", "B"], "length": l1},
                "rod": {"joints": ["B", "C"], "length": l2},
                "slider": {"points": {"C": [0, 0]}},
            },
            "prismatic": [{"name": "s", "guide": "ground", "block": "slider", "through": [0, -offset], "angle": 0}],
            "inputs": [{"joint": "A", "link": "crank"}],
            "output": {"joint": "s"},
        }
    )
    # crank and rod in line: |C| = l2 + l1 (outer) or l2 − l1 (inner dead centre)
    s_out = math.sqrt((l1 + l2) ** 2 - offset**2)
    s_in = math.sqrt((l2 - l1) ** 2 - offset**2)
    phi_out = math.atan2(-offset, s_out) % (2 * math.pi)
    phi_in = (math.atan2(-offset, s_in) + math.pi) % (2 * math.pi)
    lim = limit_positions(lk, configurations(lk, [0.0])[0], lk.output)
    byk = {p.kind: p for p in lim.positions}
    assert set(byk) == {"max", "min"}
    assert byk["max"].input == pytest.approx(phi_out, abs=1e-10) and byk["max"].output == pytest.approx(s_out, abs=1e-9)
    assert byk["min"].input == pytest.approx(phi_in, abs=1e-10) and byk["min"].output == pytest.approx(s_in, abs=1e-9)
    advance = (phi_out - phi_in) % (2 * math.pi)
    assert lim.time_ratio == pytest.approx(
        max(advance, 2 * math.pi - advance) / min(advance, 2 * math.pi - advance), abs=1e-9
    )


def test_limits_on_grid_points_and_at_the_range_start():
    # x = 40 cos(phi): the zeros of the velocity fall exactly on grid points (0 and 180 deg)
    lk = example("scotch_yoke.toml")
    lim = limit_positions(lk, configurations(lk, [0.0])[0], lk.output)
    assert [(round(math.degrees(p.input), 9), p.kind) for p in lim.positions] == [(0.0, "max"), (180.0, "min")]
    assert lim.stroke == pytest.approx(80.0, abs=1e-12) and lim.time_ratio == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize(
    "name, configuration",
    [("class3_sixbar.toml", 3), ("eightbar.toml", 6), ("shaper.toml", 1), ("class3_sliders.toml", 2)],
)
def test_limits_against_a_dense_scan(name, configuration):
    lk = example(name)
    start = configurations(lk, [0.0])[configuration - 1]
    lim = limit_positions(lk, start, lk.output, samples=720)
    # dense scan of the output, extremes refined by a parabola through the three best samples
    phi = np.linspace(0.0, 2 * math.pi, 8001)
    asm = assemble(lk, phi[:, None], start)
    y, dy, _ = output_series(lk, linkage_motion(lk, asm), lk.output)
    h = phi[1] - phi[0]
    scan = []
    for i in range(1, len(phi) - 1):
        if (y[i] - y[i - 1]) * (y[i + 1] - y[i]) < 0:
            denom = y[i - 1] - 2 * y[i] + y[i + 1]
            scan.append((phi[i] + 0.5 * h * (y[i - 1] - y[i + 1]) / denom, "max" if denom < 0 else "min"))
    assert len(scan) == len(lim.positions) >= 2
    for (x, kind), p in zip(scan, lim.positions):
        assert p.kind == kind
        assert p.input == pytest.approx(x, abs=1e-6)
    # the refined zeros of the velocity are zeros to rounding
    for p in lim.positions:
        row = np.array([[p.input]])
        m = linkage_motion(lk, assemble(lk, row, start))
        assert abs(output_series(lk, m, lk.output)[1][0]) < 1e-10 * np.max(np.abs(dy))
    assert lim.stroke == pytest.approx(np.ptp(y), rel=1e-6)


def test_a_range_that_leaves_the_assembly_is_refused():
    lk = linkage_from_mapping(
        {
            "ground": {"A": [0, 0], "D": [3, 0]},
            "links": {
                "crank": {"joints": ["A", "B"], "length": 2.0},
                "coupler": {"joints": ["B", "C"], "length": 2.0},
                "rocker": {"joints": ["D", "C"], "length": 2.0},
            },
            "inputs": [{"joint": "A", "link": "crank"}],
            "output": {"link": "rocker"},
        }
    )  # a triple rocker: the crank cannot turn fully
    start = configurations(lk, [0.0])[0]
    with pytest.raises(AssemblyError, match="does not assemble"):
        limit_positions(lk, start, lk.output)
    lim = limit_positions(lk, start, lk.output, first=-1.0, last=1.0)
    assert lim.time_ratio is None and not lim.full_turn
