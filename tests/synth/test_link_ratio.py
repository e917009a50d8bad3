"""The link ratio (synth.mechanism.link_ratio) as the figures, the screen and the refinement use it:
longest over shortest of every link, the coupler plate's sides included, against the links
written out one by one."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from synth.mechanism.figures import link_ratios, sixbar_figures
from synth.mechanism.link_ratio import SHORTEST_FLOOR, link_ratio, segment_link_ratio, segment_shortest
from synth.mechanism.sixbar import OutputDyad, SixBar, SixBars, crank_grid, simulate

#: A crank-rocker (Grashof, crank shortest) with a coupler point on the plate.
FOURBAR = dict(a=1.0, b=3.0, c=2.5, d=3.0, branch=1)


def _links_written_out(sb: SixBar, samples: int = 720) -> list[float]:
    """Every link of ``sb`` by name, the RPR reach from its own simulation."""
    p = complex(sb.u, sb.v)
    links = [sb.a, sb.b, sb.c, sb.d, abs(p), abs(p - sb.b)]
    if sb.dyad.kind == "RPR":
        z = simulate(sb, crank_grid(samples), order=0).z[0]
        links.append(float(np.abs(z - sb.dyad.pivot).max()))
    else:
        links += [sb.dyad.rocker, sb.dyad.rod]
    return links


def test_a_far_coupler_point_sets_the_ratio():
    # the case of the issue: P 17.5 cranks from A on a four-bar whose own links are within 3:1
    sb = SixBar(**FOURBAR, u=17.5, v=0.0, dyad=OutputDyad.rrr(complex(20.0, 5.0), 4.0, 6.0, 1))
    f = sixbar_figures(sb, band=math.radians(0.1))
    assert f.link_ratio == pytest.approx(17.5)  # |AP| over the crank
    assert segment_link_ratio(1.0, 3.0, 2.5, 3.0, 17.5, 0.0) == pytest.approx(17.5)


def test_a_short_plate_side_sets_the_ratio():
    # P 0.05 from B: |BP| is the shortest link, |AP| ≈ b
    sb = SixBar(**FOURBAR, u=3.0, v=0.05, dyad=OutputDyad.rrr(complex(1.0, 4.0), 2.0, 2.0, 1))
    f = sixbar_figures(sb, band=math.radians(0.1))
    assert f.link_ratio == pytest.approx(math.hypot(3.0, 0.05) / 0.05)
    assert segment_shortest(1.0, 3.0, 2.5, 3.0, 3.0, 0.05) == pytest.approx(0.05)


def test_a_coupler_point_on_a_joint_gives_a_finite_ratio():
    assert link_ratio([3.0, 0.0, 1.0]) == pytest.approx(1 / SHORTEST_FLOOR)
    assert np.isfinite(segment_link_ratio(1.0, 3.0, 2.5, 3.0, 0.0, 0.0))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    u=st.floats(-6.0, 6.0),
    v=st.floats(-6.0, 6.0),
    x=st.floats(-8.0, 8.0),
    y=st.floats(-8.0, 8.0),
    rocker=st.floats(0.2, 12.0),
    rod=st.floats(0.2, 12.0),
    rrr=st.booleans(),
)
@example(u=1.5, v=0.0, x=1.5, y=0.0, rocker=1.0, rod=1.0, rrr=False)  # the slider through its pivot
@example(u=0.0, v=0.0, x=0.0, y=0.0, rocker=1.0, rod=1.0, rrr=False)  # P on A: a zero side
@example(u=0.0, v=0.0, x=0.0, y=0.0, rocker=1.0, rod=7.43359375, rrr=True)  # 1 / floor rounds below 1e12
def test_the_figures_ratio_is_every_link_written_out(u, v, x, y, rocker, rod, rrr):
    dyad = OutputDyad.rrr(complex(x, y), rocker, rod, 1) if rrr else OutputDyad.rpr(complex(x, y))
    sb = SixBar(**FOURBAR, u=u, v=v, dyad=dyad)
    links = _links_written_out(sb)
    expected = max(links) / max(min(links), SHORTEST_FLOOR * max(links))
    batch = SixBars.from_sixbars([sb])
    got = float(link_ratios(batch, simulate(batch, crank_grid(720), order=0))[0])
    assert got == pytest.approx(expected, rel=1e-12)
    assert np.isfinite(got) and got >= 1.0
    # the segment's links alone bound it from below, whatever the dyad
    assert got >= float(segment_link_ratio(1.0, 3.0, 2.5, 3.0, u, v)) * (1 - 1e-12)
    # and every link is within the ratio times the segment's shortest (the prunes' premise),
    # unless the floor stands in for a zero side: then the ratio is beyond any limit
    if got < 0.5 / SHORTEST_FLOOR:  # (the floor's own ratio may round a few ulps below 1 / floor)
        assert max(links) <= got * float(segment_shortest(1.0, 3.0, 2.5, 3.0, u, v)) * (1 + 1e-12)
