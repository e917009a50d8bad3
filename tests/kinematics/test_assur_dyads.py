"""Class II groups: reference cases, velocities and accelerations, random dyads of every type."""

from __future__ import annotations

import math

import numpy as np
import pytest
from assur_builders import check_derivatives, dyad_linkage, example
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from kinematics.assur import (
    assemble,
    configurations,
    decompose,
    linkage_from_mapping,
    linkage_motion,
    loop_closure,
)
from kinematics.fourbar import fourbar_motion
from kinematics.status import Status

# -- the dyad, four-bar and slider-crank cases of docs/cases/classic_mechanisms.json ----------


def _solver_rows(case):
    return [row["solver"] for row in case["rows"]]


def _close_to_some(got, rows, tol):
    """Every row of ``rows`` matches one entry of ``got`` (angles modulo 360)."""
    assert len(got) == len(rows)
    for want in rows:
        errs = [max(_diff(g, w) for g, w in zip(cand, want)) for cand in got]
        assert min(errs) <= tol, (want, got)


def _diff(a, b):
    return abs(a - b)


def test_L201_rrr_dyad(reference_cases):
    case = reference_cases["L201_RRR_dyad"]
    p = case["inputs"]
    lk = linkage_from_mapping(
        {
            "ground": {"A": [p["xA"], p["yA"]], "C": [p["xC"], p["yC"]]},
            "links": {
                "link1": {"joints": ["A", "B"], "length": p["l1"]},
                "link2": {"joints": ["C", "B"], "length": p["l2"]},
            },
        }
    )
    assert lk.dof == 0 and [g.kind for g in decompose(lk).groups] == ["RRR"]
    found = configurations(lk, [])
    got = [[math.degrees(c.theta[0, 1]), math.degrees(c.theta[0, 2])] for c in found]
    # branch +1 (B left of A->C) is the document's first row
    assert got[0] == pytest.approx(case["rows"][0]["solver"], abs=1e-9)
    _close_to_some(got, _solver_rows(case), 1e-9)
    assert max(loop_closure(lk, c)[0] for c in found) < 1e-12


def test_L211_rrp_dyad(reference_cases):
    case = reference_cases["L211_RRP_dyad"]
    p = case["inputs"]
    alpha = math.radians(p["alpha"])
    lk = linkage_from_mapping(
        {
            "ground": {"A": [p["xA"], p["yA"]], "P": [p["xP"], p["yP"]]},
            "links": {
                "link1": {"joints": ["A", "B"], "length": p["l1"]},
                "slider": {"points": {"B": [p["e"] * math.cos(alpha), p["e"] * math.sin(alpha)]}},
            },
            "prismatic": [{"name": "s", "guide": "ground", "block": "slider", "through": "P", "angle": p["beta"]}],
        }
    )
    found = configurations(lk, [])
    got = [[math.degrees(c.theta[0, 1]), float(linkage_motion(lk, c).s[0, 0])] for c in found]
    _close_to_some(got, _solver_rows(case), 1e-8)


def test_L221_rpp_dyad(reference_cases):
    case = reference_cases["L221_RPP_dyad"]
    p = case["inputs"]
    alpha = math.radians(p["alpha"])
    lk = linkage_from_mapping(
        {
            "ground": {"A": [p["xA"], p["yA"]], "P": [p["xP"], p["yP"]]},
            "links": {
                "slider1": {},
                "slider2": {"points": {"A": [p["e"] * math.cos(alpha), p["e"] * math.sin(alpha)]}},
            },
            "prismatic": [
                {"name": "s1", "guide": "ground", "block": "slider1", "through": "P", "angle": p["beta"]},
                {"name": "s2", "guide": "slider1", "block": "slider2", "through": [0, 0], "angle": p["gamma"]},
            ],
        }
    )
    assert [g.kind for g in decompose(lk).groups] == ["RPP"]
    found = configurations(lk, [])
    assert len(found) == case["n_configs_solver"] == 1
    s = linkage_motion(lk, found[0]).s[0]
    assert s.tolist() == pytest.approx(case["rows"][0]["solver"], abs=1e-8)


def test_P204001_fourbar(reference_cases):
    case = reference_cases["P204001_fourbar"]
    p = case["inputs"]
    lk = linkage_from_mapping(
        {
            "ground": {"A": [0, 0], "D": [p["l4"], 0]},
            "links": {
                "crank": {"joints": ["A", "B"], "length": p["l1"]},
                "coupler": {"joints": ["B", "C"], "length": p["l2"]},
                "rocker": {"joints": ["D", "C"], "length": p["l3"]},
            },
            "inputs": [{"joint": "A", "link": "crank"}],
        }
    )
    found = configurations(lk, [math.radians(p["theta1"])])
    got = [[math.degrees(c.theta[0, 2]), math.degrees(c.theta[0, 3])] for c in found]
    _close_to_some(got, _solver_rows(case), 1e-9)


def test_P204101_offset_slider_crank(reference_cases):
    case = reference_cases["P204101_offset_slider_crank"]
    p = case["inputs"]
    a = math.radians(p["alpha"])
    foot = p["e"] * complex(math.cos(a - math.pi / 2), math.sin(a - math.pi / 2))
    lk = linkage_from_mapping(
        {
            "ground": {"A": [0, 0]},
            "links": {
                "crank": {"joints": ["A", "B"], "length": p["l1"]},
                "rod": {"joints": ["B", "C"], "length": p["l2"]},
                "slider": {"points": {"C": [0, 0]}},
            },
            "prismatic": [
                {
                    "name": "s",
                    "guide": "ground",
                    "block": "slider",
                    "through": [foot.real, foot.imag],
                    "angle": p["alpha"],
                }
            ],
            "inputs": [{"joint": "A", "link": "crank"}],
        }
    )
    found = configurations(lk, [math.radians(p["theta1"])])
    got = [[math.degrees(c.theta[0, 2]), float(linkage_motion(lk, c).s[0, 0])] for c in found]
    _close_to_some(got, _solver_rows(case), 1e-8)


# -- velocity and acceleration tables (slider-crank: RRP; shaper: RPR + RRP) --------------------


def _table_errors(case, lk, columns):
    rows = case["rows"]
    phi = np.radians([r["phi1_deg"] for r in rows])
    start = configurations(lk, phi[:1])[0]
    asm = assemble(lk, phi[:, None], start)
    motion = linkage_motion(lk, asm, rates=[case["inputs"]["omega1_rad_s"]])
    worst = 0.0
    for name, values in columns(asm, motion).items():
        want = np.array([r[name] for r in rows])
        worst = max(worst, float(np.max(np.abs(values - want) / np.maximum(1.0, np.abs(want)))))
    return worst


def test_offset_slider_crank_table(reference_cases):
    lk = example("slider_crank.toml")
    case = reference_cases["offset_slider_crank_reference"]
    worst = _table_errors(
        case,
        lk,
        lambda asm, m: {
            "phi2_deg": np.degrees(asm.theta[:, 2]),
            "s3_mm": m.s[:, 0],
            "omega2_rad_s": m.omega[:, 2],
            "v3_mm_s": m.ds[:, 0],
            "eps2_rad_s2": m.alpha[:, 2],
            "a3_mm_s2": m.dds[:, 0],
        },
    )
    assert worst < 1e-10  # the table holds 12 significant digits


def test_shaper_table(reference_cases):
    lk = example("shaper.toml")
    assert [g.kind for g in decompose(lk).groups] == ["RPR", "RRP"]
    case = reference_cases["shaper_crank_guiderod_slider_reference"]
    worst = _table_errors(
        case,
        lk,
        lambda asm, m: {
            "s2_mm": m.s[:, 0],
            "phi3_deg": np.degrees(asm.theta[:, 3]),
            "phi4_deg": np.degrees(asm.theta[:, 4]),
            "s5_mm": m.s[:, 1],
            "v2_mm_s": m.ds[:, 0],
            "omega3_rad_s": m.omega[:, 3],
            "omega4_rad_s": m.omega[:, 4],
            "v5_mm_s": m.ds[:, 1],
            "a2_mm_s2": m.dds[:, 0],
            "eps3_rad_s2": m.alpha[:, 3],
            "eps4_rad_s2": m.alpha[:, 4],
            "a5_mm_s2": m.dds[:, 1],
        },
    )
    assert worst < 1e-10


def test_fourbar_file_matches_closed_form():
    lk = example("fourbar.toml")
    phi = np.radians(np.arange(0.0, 360.0, 5.0))
    for branch, start in zip((1, -1), configurations(lk, phi[:1])):
        asm = assemble(lk, phi[:, None], start)
        m = linkage_motion(lk, asm)
        fb = fourbar_motion(50, 80, 80, 100, phi, branch)
        assert np.max(np.abs(asm.e[:, 3] - fb.e_gamma)) < 1e-13
        assert np.max(np.abs(m.omega[:, 2] - fb.dtheta[0])) < 1e-13
        assert np.max(np.abs(m.alpha[:, 3] - fb.dgamma[1])) < 1e-13
        # coupler point P = (40, 30) in the coupler frame
        z, v, a = m.point(2, 40 + 30j)
        zz = fb.coupler_point(40, 30, order=2)
        assert (
            np.max(np.abs(z - zz[0])) < 1e-12
            and np.max(np.abs(v - zz[1])) < 1e-12
            and np.max(np.abs(a - zz[2])) < 1e-11
        )


# -- random dyads of every type: the drawn pose is found, loops close, derivatives agree ---------

DYAD_KINDS = ["RRR", "RRP", "PRR", "RPR", "PRP", "RPP", "PPR"]


@pytest.mark.parametrize("kinds", DYAD_KINDS)
@settings(max_examples=20, deadline=None)
@given(
    values=st.lists(st.floats(0.0, 1.0, exclude_max=True), min_size=16, max_size=16),
    flips=st.lists(st.booleans(), min_size=3, max_size=3),
)
def test_random_dyad(kinds, values, flips):
    b = dyad_linkage(kinds, values, flips)
    lk = b.linkage()
    L = lk.length_scale
    drawn = b.assembly(lk)
    cond = linkage_motion(lk, drawn).condition[0]
    assume(cond > 1e-5)  # well away from a toggle, where the drawn branch is ill-defined
    found = configurations(lk, [b.phi0])
    assert 1 <= len(found) <= 2
    assert decompose(lk).groups[0].kind in ("RRR", "RRP", "RPR", "PRP", "RPP")
    dist = [np.max(np.abs(c.r - drawn.r)) + L * np.max(np.abs(c.e - drawn.e)) for c in found]
    assert min(dist) < 1e-8 * L
    for c in found:
        assert loop_closure(lk, c)[0] < 1e-11 * L
    config = found[int(np.argmin(dist))]
    check_derivatives(lk, config, b.phi0)


def test_branches_and_status_of_the_kernels():
    from kinematics.assur.dyads import line_circle
    from kinematics.loop import circle_intersection, line_intersection

    # circles of radius 1 about 0 and 1.5 about 2: x = (1 + 4 − 2.25)/4 = 0.6875 (law of cosines)
    loop = circle_intersection(2 + 0j, 1.0, 1.5, np.array([1, -1]))
    B = loop.e1
    assert B[0].imag > 0 > B[1].imag and not loop.status.any()
    np.testing.assert_allclose(B.real, 0.6875, rtol=1e-15)
    np.testing.assert_allclose(np.abs(B - 2), 1.5, rtol=1e-15)
    np.testing.assert_allclose(2 + 1.5 * loop.e2, B, atol=1e-15)
    assert circle_intersection(5 + 0j, 1.0, 1.0, 1).status == Status.NOT_ASSEMBLABLE
    assert circle_intersection(2 + 0j, 1.0, 1.0, 1).status == Status.TOGGLE
    t, status = line_circle(0j, 1 + 0j, 1j, 2.0, np.array([1, -1]))
    assert t[0] == pytest.approx(math.sqrt(3)) and t[1] == pytest.approx(-math.sqrt(3)) and not status.any()
    assert line_intersection(0j, 1 + 0j, 1j, -1 + 0j).status == Status.NOT_ASSEMBLABLE
    # the x-axis and the line through 1 + 1j at 45°: they meet at 0, t1 = 0, t2 = −√2
    hit = line_intersection(0j, 1 + 0j, 1 + 1j, np.exp(0.25j * math.pi))
    assert hit.t1 == pytest.approx(0.0, abs=1e-15) and hit.t2 == pytest.approx(-math.sqrt(2)) and hit.status == 0


def test_slide_driven_dead_centre_is_reported_singular():
    # a slider-crank driven by its slider: at s = l1 + l2 crank and rod are stretched out
    lk = linkage_from_mapping(
        {
            "ground": {"A": [0, 0]},
            "links": {
                "crank": {"joints": ["A", "B"], "length": 30},
                "rod": {"joints": ["B", "C"], "length": 70},
                "slider": {"points": {"C": [0, 0]}},
            },
            "prismatic": [{"name": "s", "guide": "ground", "block": "slider", "through": [0, 0], "angle": 0}],
            "inputs": [{"joint": "s", "value": 60}],
        }
    )
    start = configurations(lk, [60.0])[0]
    asm = assemble(lk, np.array([[60.0], [100.0], [101.0]]), start)
    assert asm.status[0] == 0
    assert asm.status[1] & Status.TOGGLE and asm.status[2] & Status.NOT_ASSEMBLABLE
    m = linkage_motion(lk, asm, rates=[10.0])
    assert m.status[1] & Status.TOGGLE and m.condition[1] < 1e-10
    for x in (m.v, m.a, m.omega, m.alpha, m.ds, m.dds):
        assert np.all(np.isfinite(x)) and np.all(x[1:] == 0)
