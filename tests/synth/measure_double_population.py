"""The atlas's double Ball point population (docs/query-double-dwell.md, coverage): every double
line with both stretches at a tolerance level, slot pivot at the lines' crossing (the query's
fit, :func:`synth.mechanism.dyad.rpr_double`), its output on the fit's 1° grid: the swing and the two
separated rests (band 0.1°, separation 0.5°, :func:`synth.mechanism.output_range.dwell_intervals` on
the grid, ends to ±1°). Per swing S ± tol: how many have both rests within d ± 5° for each
dwell d of the coverage grid, and the longest shorter rest there.

    .venv/bin/python tests/synth/measure_double_population.py /work/data/std.sqlite LEVEL
"""

import json
import math
import sys

import numpy as np

from db.engine import open_atlas
from db.queries import AtlasSource
from synth.mechanism.dyad import rpr_double
from synth.mechanism.output_range import dwell_intervals
from synth.mechanism.sixbar import crank_grid
from synth.query import FIT_SAMPLES, coupler_paths

db, level = sys.argv[1], int(sys.argv[2])
src = AtlasSource(open_atlas(db, readonly=True))
phi = crank_grid(FIT_SAMPLES)
swings, shorter, longer = [], [], []
for batch in src.scan_segments(
    "double_line", level, min_transmission=math.radians(30), max_length=10.0, min_radius_ratio=0.1, batch=4096
):
    two = np.flatnonzero(batch.has_parts == 2)
    if not two.size:
        continue
    found = rpr_double(
        (batch.point(0)[two], batch.part(0, "direction")[two]), (batch.point(1)[two], batch.part(1, "direction")[two])
    )
    ok = found.found
    rows = two[ok]
    D = found.pivot[ok]
    P = coupler_paths(batch, phi)[rows]
    psi = np.unwrap(np.angle(P - D[:, None]), axis=1)
    rock = np.abs(psi[:, -1] - psi[:, 0]) < math.pi
    psi, D = psi[rock], D[rock]
    w = dwell_intervals(phi, psi, math.radians(0.1), count=2, leave=math.radians(0.5))
    both = w.found.all(axis=1)
    sw = np.ptp(psi, axis=1)
    swings += np.degrees(sw[both]).tolist()
    shorter += np.degrees(w.angle[both].min(axis=1)).tolist()
    longer += np.degrees(w.angle[both].max(axis=1)).tolist()
sw, lo, hi = map(np.array, (swings, shorter, longer))
out = {"level": level, "crossings_with_two_rests": int(sw.size)}
for S, tol in ((20, 0.5), (45, 0.5), (20, 2.0), (45, 2.0)):
    m = np.abs(sw - S) <= tol
    cells = {d: int(np.sum(m & (lo >= d - 5) & (hi <= d + 5))) for d in (10, 20, 30, 45, 60, 75, 90, 120)}
    out[f"swing {S}±{tol}"] = {
        "n": int(m.sum()),
        "longest_shorter_rest": None if not m.any() else round(float(lo[m].max()), 1),
        "cells": cells,
    }
hist = np.histogram(sw, bins=[0, 10, 20, 30, 45, 60, 90, 120, 150, 180])
out["swing_hist"] = dict(zip([f"{a}-{b}" for a, b in zip(hist[1][:-1], hist[1][1:])], hist[0].tolist()))
print(json.dumps(out, indent=1))
