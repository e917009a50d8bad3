"""Class III groups: every real configuration, checked against an independent dense search;
random triads of every leg type; an eight-bar with all its combinations; tracking over folds."""

from __future__ import annotations

import math

import numpy as np
import pytest
from assur_builders import check_derivatives, example, triad_linkage
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
from kinematics.status import Status

# -- an independent search: a dense grid over two leg angles, Newton on every cell minimum -------


def _rr_triad_geometry(lk, phi):
    """Ground/crank pivots A_i, leg lengths l_i and ternary points b_i of an all-revolute triad."""
    pts = {name: complex(*v) if not isinstance(v, complex) else v for name, v in lk.links[0].points.items()}
    crank = lk.links[lk.link_index("crank")]
    A3 = pts["O"] + crank.points["A3"] * np.exp(1j * phi)
    A = [pts["A1"], pts["A2"], A3]
    legs = [lk.links[lk.link_index(f"leg{i}")] for i in (1, 2, 3)]
    lengths = [abs(leg.points[f"B{i + 1}"] - leg.points[j]) for i, (leg, j) in enumerate(zip(legs, ("A1", "A2", "A3")))]
    tern = lk.links[lk.link_index("ternary")]
    b = [tern.points["B1"], tern.points["B2"], tern.points["B3"]]
    return A, lengths, b


def _dense_search(A, l, b, n=500):
    """All ternary poses (X, θ) with |B_i − A_i| = l_i, by a grid over the angles of legs 1 and 2.

    For leg angles (ψ1, ψ2): B1 = A1 + l1·e^{iψ1}, B2 = A2 + l2·e^{iψ2}; residuals
    r1 = |B1 − B2| − |b1 − b2| and r2 = |B3 − A3| − l3 with the ternary placed on B1 and the
    direction B1→B2. Every grid cell that is a local minimum of r1² + r2² over its 8 neighbours
    (periodic) starts Newton's method; converged, distinct poses are returned.
    """

    def resid(p1, p2):
        B1 = A[0] + l[0] * np.exp(1j * p1)
        B2 = A[1] + l[1] * np.exp(1j * p2)
        d = B2 - B1
        e = d / np.abs(d) * np.conj(b[1] - b[0]) / abs(b[1] - b[0])
        X = B1 - e * b[0]
        B3 = X + e * b[2]
        return np.stack([np.abs(d) - abs(b[1] - b[0]), np.abs(B3 - A[2]) - l[2]]), X, e

    g = np.linspace(0, 2 * np.pi, n, endpoint=False)
    P1, P2 = np.meshgrid(g, g, indexing="ij")
    r, _, _ = resid(P1, P2)
    f = (r**2).sum(axis=0)
    is_min = np.ones_like(f, bool)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                is_min &= f <= np.roll(np.roll(f, di, 0), dj, 1)
    sols = []
    for i, j in zip(*np.nonzero(is_min)):
        x = np.array([g[i], g[j]])
        for _ in range(60):
            r0, _, _ = resid(*x)
            h = 1e-7
            Jc = np.stack(
                [
                    (resid(x[0] + h, x[1])[0] - resid(x[0] - h, x[1])[0]) / (2 * h),
                    (resid(x[0], x[1] + h)[0] - resid(x[0], x[1] - h)[0]) / (2 * h),
                ],
                axis=1,
            )
            try:
                x = x - np.linalg.solve(Jc, r0)
            except np.linalg.LinAlgError:
                break
        r0, X, e = resid(*x)
        if np.max(np.abs(r0)) < 1e-9 and not any(abs(X - Y) < 1e-6 and abs(e - f_) < 1e-8 for Y, f_ in sols):
            sols.append((complex(X), complex(e)))
    return sols


@pytest.mark.parametrize("name, phi_deg", [("class3_sixbar.toml", 0.0), ("class3_sixbar.toml", 133.0)])
def test_class3_sixbar_has_six_configurations_and_no_others(name, phi_deg):
    lk = example(name)
    phi = math.radians(phi_deg)
    dec = decompose(lk)
    assert [g.kind for g in dec.groups] == ["triad"] and dec.groups[0].legs == ("RR", "RR", "RR")
    found = configurations(lk, [phi])
    assert len(found) == 6
    L = lk.length_scale
    t = lk.link_index("ternary")
    for c in found:
        assert loop_closure(lk, c)[0] < 1e-12 * L
    A, lengths, b = _rr_triad_geometry(lk, phi)
    dense = _dense_search(A, lengths, b)
    assert len(dense) == 6
    for X, e in dense:  # every pose of the independent search is one of ours
        assert min(abs(c.r[0, t] - X) + L * abs(c.e[0, t] - e) for c in found) < 1e-7 * L


def test_fold_case_configurations_are_all_found():
    # a triad whose number of assemblies changes with the crank angle (6, 4, 2)
    lk = _fold_sixbar()
    counts = []
    for deg in (0, 90, 150, 300):
        phi = math.radians(deg)
        found = configurations(lk, [phi])
        A, lengths, b = _rr_triad_geometry(lk, phi)
        assert len(_dense_search(A, lengths, b, n=400)) == len(found)
        counts.append(len(found))
    assert counts == [6, 4, 2, 4]


def _fold_sixbar(legs=(104.1, 63.2, 97.6)):
    return linkage_from_mapping(
        {
            "ground": {"A1": [-70.6, 60.4], "A2": [-55.8, -4.9], "O": [-51.9, 52.7]},
            "links": {
                "crank": {"joints": ["O", "A3"], "length": 20.9},
                "ternary": {"points": {"B1": [-39.8, -38.1], "B2": [-78.1, 64.0], "B3": [-74.6, -29.7]}},
                "leg1": {"joints": ["A1", "B1"], "length": legs[0]},
                "leg2": {"joints": ["A2", "B2"], "length": legs[1]},
                "leg3": {"joints": ["A3", "B3"], "length": legs[2]},
            },
            "inputs": [{"joint": "O", "link": "crank"}],
        }
    )


def test_tracking_stops_at_folds_and_does_not_jump():
    lk = _fold_sixbar()
    ends = {}
    for start in configurations(lk, [0.0]):
        results = []
        for step in (30.0, 10.0, 1.0):  # the sweep's own step must not change what is followed
            phi = np.radians(np.arange(0.0, 361.0, step))
            asm = assemble(lk, phi[:, None], start)
            ok = asm.status == 0
            last = int(np.flatnonzero(ok)[-1])
            assert ok[: last + 1].all() and not ok[last + 1 :].any()
            assert loop_closure(lk, asm)[ok].max() < 1e-11 * lk.length_scale
            results.append((math.degrees(phi[last]), asm.e[last, 2] if ok.all() else None))
        # every sweep ends at its last position before the same fold (or none ends)
        stops = [r[0] for r in results]
        for stop, step in zip(stops[:2], (30.0, 10.0)):
            assert stop - 1e-9 <= stops[2] < stop + step
        if results[2][1] is not None:
            assert abs(results[0][1] - results[2][1]) < 1e-9
        ends[start.choice] = round(stops[2], 6)
    assert sorted(ends.values()) == [72.0, 72.0, 123.0, 123.0, 360.0, 360.0]


def test_every_configuration_of_the_example_turns_fully_and_periodically():
    lk = example("class3_sixbar.toml")
    phi = np.radians(np.arange(0.0, 361.0, 2.0))
    for start in configurations(lk, [0.0]):
        asm = assemble(lk, phi[:, None], start)
        assert not asm.status.any()
        assert np.max(np.abs(asm.r[0] - asm.r[-1])) < 1e-9 * lk.length_scale


def test_class3_with_prismatic_legs():
    lk = example("class3_sliders.toml")
    dec = decompose(lk)
    assert sorted(dec.groups[0].legs) == ["PR", "RP", "RR"]
    for deg in (0.0, 120.0, 250.0):
        found = configurations(lk, [math.radians(deg)])
        assert len(found) == 6
        assert max(loop_closure(lk, c)[0] for c in found) < 1e-12 * lk.length_scale


def test_eightbar_combines_every_triad_root_with_both_dyad_branches():
    lk = example("eightbar.toml")
    dec = decompose(lk)
    assert [g.kind for g in dec.groups] == ["triad", "RRR"]
    phi = math.radians(40.0)
    found = configurations(lk, [phi])
    L = lk.length_scale
    for c in found:
        assert loop_closure(lk, c)[0] < 1e-12 * L
    # independently: for each ternary pose, the dyad E-G-F assembles where |E − F| ≤ l5 + l6
    six = configurations(example("class3_sixbar.toml"), [phi])
    tern = lk.links[lk.link_index("ternary")]
    F = lk.links[0].points["F"]
    expected = 0
    for c in six:
        t = 2  # ternary is link 2 in both files
        E = c.r[0, t] + c.e[0, t] * tern.points["E"]
        r = abs(E - F)
        expected += 2 if abs(90.0 - 110.0) < r < 90.0 + 110.0 else 0
    assert len(found) == expected == 12
    poses = np.array([np.concatenate([c.r[0], c.e[0]]) for c in found])
    gaps = [np.max(np.abs(poses[i] - poses[j])) for i in range(len(poses)) for j in range(i)]
    assert min(gaps) > 1e-6  # all distinct
    assert [c.choice for c in found][:4] == [(1, 1), (1, -1), (2, 1), (2, -1)]


def test_eightbar_sweep_velocities_match_finite_differences():
    lk = example("eightbar.toml")
    start = configurations(lk, [0.0])[5]
    phi = np.radians(np.arange(0.0, 360.0, 45.0))
    h = 1e-6
    grid = np.stack([phi - h, phi, phi + h], axis=1).ravel()[:, None]
    asm = assemble(lk, grid, start)
    assert not asm.status.any()
    m = linkage_motion(lk, asm)
    v = m.v.reshape(len(phi), 3, -1)
    r = asm.r.reshape(len(phi), 3, -1)
    fd = (r[:, 2] - r[:, 0]) / (2 * h)
    assert np.max(np.abs(fd - v[:, 1])) < 1e-6 * np.max(np.abs(v))
    acc = m.a.reshape(len(phi), 3, -1)
    fd2 = (v[:, 2] - v[:, 0]) / (2 * h)
    assert np.max(np.abs(fd2 - acc[:, 1])) < 1e-5 * np.max(np.abs(acc))


# -- random triads of every leg type ---------------------------------------------------------------

LEG_SETS = [
    ("RR", "RR", "RR"),
    ("RR", "PR", "RR"),
    ("RP", "RR", "RR"),
    ("PR", "RP", "RR"),
    ("RP", "PR", "PR"),
    ("PR", "PR", "RP"),
]


@pytest.mark.parametrize("legs", LEG_SETS, ids=["/".join(x) for x in LEG_SETS])
@settings(max_examples=15, deadline=None)
@given(
    values=st.lists(st.floats(0.0, 1.0, exclude_max=True), min_size=32, max_size=32),
    flips=st.lists(st.booleans(), min_size=6, max_size=6),
)
def test_random_triad(legs, values, flips):
    b = triad_linkage(list(legs), values, flips)
    lk = b.linkage()
    L = lk.length_scale
    drawn = b.assembly(lk)
    cond = linkage_motion(lk, drawn).condition[0]
    assume(cond > 1e-4)
    dec = decompose(lk)
    assert dec.groups[0].kind == "triad"
    found = configurations(lk, [b.phi0])
    assert 1 <= len(found) <= 6
    dist = [np.max(np.abs(c.r - drawn.r)) + L * np.max(np.abs(c.e - drawn.e)) for c in found]
    assert min(dist) < 1e-7 * L
    for c in found:
        assert loop_closure(lk, c)[0] < 1e-11 * L
    check_derivatives(lk, found[int(np.argmin(dist))], b.phi0)


def test_no_solution_and_status():
    lk = _fold_sixbar()
    lk_short = _fold_sixbar(legs=(1.0, 1.0, 1.0))
    assert configurations(lk_short, [0.0]) == []
    start = configurations(lk, [0.0])[0]
    asm = assemble(lk, np.radians([[0.0], [100.0]]), start)
    assert asm.status[1] & Status.NOT_ASSEMBLABLE and np.all(np.isfinite(asm.r))
