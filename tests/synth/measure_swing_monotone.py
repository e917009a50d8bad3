"""Measurements behind docs/complete-query.md §9 (not a test: run by hand on a built atlas).

    .venv/bin/python tests/synth/measure_swing_monotone.py ATLAS line|arc [ROWS_PER_LEVEL]

Could the fitted six-bars' figures be indexed ahead of the request (§8's last paragraph)? A
request's swing S is free, so such an index would store each row's six-bar dwell at grid
swings and bracket the dwell at S between its neighbours — sound only if the dwell is
monotone in the swing. For ROWS_PER_LEVEL rows drawn (seeded) from the first 40 000 of every
level of ATLAS (line: RPR, arc: RRR; the query's defaults: band 0.1°, μ ≥ 30°, link ratio ≤ 10),
the query's own fits (:func:`synth.query.fit`) at swings 10°, 12.5° … 90°, each simulated
(:func:`synth.query.figures_of`): per (row, slot) the dwell as a function of the swing (acceptable
six-bars that meet the swing to 0.5°). Printed: how many series rise as the swing grows, the
largest rises (and whether the longest band interval holds the stretch's middle at both
swings), and the share of series a bracket of the two grid swings around S (widened by a
margin) would let a request skip.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import random
import sys

import numpy as np

from db.engine import open_atlas
from db.queries import AtlasSource
from synth.query import figures_of, fit
from synth.query.candidates import Request

DEG = math.pi / 180
SWINGS = np.arange(10.0, 90.1, 2.5)
POOL = 40_000


def dwell_series(path: str, kind: str, per_level: int) -> dict[tuple, dict[float, tuple[float, bool]]]:
    """(segment, level, output, slot) → {swing °: (dwell °, whether it holds the stretch's middle)}."""
    src = AtlasSource(open_atlas(path, readonly=True))
    base = Request.from_degrees(dwell=60, swing=30, output="rpr" if kind == "line" else "rrr", refine=False)
    limits = dict(
        min_transmission=base.min_transmission, max_length=base.max_link_ratio, min_radius_ratio=1 / base.max_link_ratio
    )
    rng = random.Random(1)
    rows = []
    for level, _ in src.tolerance_levels():
        pool = []
        for batch in src.scan_segments(kind, level, batch=4000, **limits):
            pool.extend(batch)
            if len(pool) >= POOL:
                break
        rows += rng.sample(pool, min(per_level, len(pool)))
    series: dict[tuple, dict[float, tuple[float, bool]]] = collections.defaultdict(dict)
    for swing in SWINGS:
        request = dataclasses.replace(base, swing=float(swing) * DEG)
        fits = fit(request, rows, kind)
        for f, g in zip(fits, figures_of(request, [f.sixbar() for f in fits], footprint=False) if fits else []):
            if g.acceptable and g.dwells and abs(g.swing - request.swing) < 0.5 * DEG:
                d = g.dwells[0]
                mid = 0.5 * (f.row.parts[0][0] + f.row.parts[0][1])
                series[(f.row.segment_id, f.row.level, f.output, f.slot)][float(swing)] = (
                    math.degrees(d.angle),
                    (mid - d.start) % (2 * math.pi) <= d.angle,
                )
    return series


def main(path: str, kind: str, per_level: int) -> None:
    series = dwell_series(path, kind, per_level)
    rises, steps, rising = [], 0, 0
    for d in series.values():
        s = sorted(d)
        pairs = [(a, b) for a, b in zip(s, s[1:]) if b - a < 2.6]
        up = [(d[b][0] - d[a][0], a, b, d[a][1] and d[b][1]) for a, b in pairs if d[b][0] - d[a][0] > 1e-6]
        steps, rising, rises = steps + len(pairs), rising + bool(up), rises + up
    n = len(series)
    print(
        f"{kind}: {n} (row, slot) series, {steps} steps of 2.5°; the dwell grows with the swing in {len(rises)} "
        f"steps of {rising} series"
    )
    for rise, a, b, through in sorted(rises, reverse=True)[:12]:
        print(f"  +{rise:.3f}° from {a:g}° to {b:g}°" + ("" if through else " (longest interval elsewhere)"))
    print("share of series a bracket of the grid swings around S would skip, by margin (°):")
    for S in (21.25, 31.25, 46.25, 61.25):
        a, b = S - 1.25, S + 1.25
        both = sum(1 for d in series.values() if a in d and b in d)
        for D in (30, 60, 90, 120):
            cells = []
            for margin in (0, 5, 25):
                keep = sum(
                    1
                    for d in series.values()
                    if a not in d
                    or b not in d
                    or not (max(d[a][0], d[b][0]) + margin < D - 2 or min(d[a][0], d[b][0]) - margin > D + 2)
                )
                cells.append(f"{margin}: {100 * (1 - keep / n):.0f}%")
            print(f"  S {S:g}° D {D}°: " + ", ".join(cells) + f"  (a dwell at both grid swings: {100 * both / n:.0f}%)")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 300)
