"""Measure (by hand, not a test) how many RPR six-bars rest at a coupler curve's support point
for a short rest at a small swing, beyond what the query's own sample of them reaches
(docs/query-coverage.md, "Short rests at a small swing").

Every ``--every``-th four-bar of the atlas with a transmission angle ≥ 30° and a 9 × 8 grid
of coupler points (u ∈ [−1, 2.5], v ∈ [−2, 2]) instead of the atlas lines' points: the
far-field test (synth.mechanism.support_rest.support_points) on 1° samples, slot pivots each
way (slot_pivots), the exact figures, and the ``--refine`` nearest misses that miss only the
dwell and swing refined as the query refines its near misses (refine(reach=True)).

    .venv/bin/python tests/synth/measure_support_rests.py std.sqlite [--dwell 10 --swing 10 --every 2 --refine 200]
"""

from __future__ import annotations

import argparse
import sqlite3
import time

import numpy as np

from kinematics.fourbar import fourbar_motion
from synth.mechanism.sixbar import OutputDyad, SixBar, crank_grid
from synth.mechanism.support_rest import slot_pivots, support_points
from synth.query.candidates import Request
from synth.query.evaluate import figures_of, meets, violations
from synth.query.refine import refine


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("db")
    ap.add_argument("--dwell", type=float, default=10.0)
    ap.add_argument("--swing", type=float, default=10.0)
    ap.add_argument("--every", type=int, default=2)
    ap.add_argument("--refine", type=int, default=200)
    args = ap.parse_args()
    request = Request.from_degrees(dwell=args.dwell, swing=args.swing, output="rpr")
    t0 = time.perf_counter()
    with sqlite3.connect(f"file:{args.db}?mode=ro", uri=True) as con:
        rows = np.array(con.execute("SELECT b, c, d, branch, transmission_min FROM linkage").fetchall())
    rows = rows[rows[:, 4] >= request.min_transmission][:: args.every]
    u, v = np.meshgrid(np.linspace(-1, 2.5, 8), np.linspace(-2, 2, 9))
    points = (u + 1j * v).ravel()
    phi = crank_grid(360)
    sixbars: list[SixBar] = []
    paths_n = 0
    for lo in range(0, len(rows), 500):
        part = rows[lo : lo + 500]
        b, c, d, branch = (part[:, j, None, None] for j in range(4))  # (four-bar, point, φ)
        m = fourbar_motion(1.0, b, c, d, phi[None, None], branch, order=0)
        whole = (m.status == 0).all(axis=(1, 2))
        part = part[whole]
        (paths,) = m.coupler_point(points.real[None, :, None], points.imag[None, :, None])
        paths = paths[whole].reshape(-1, phi.size)
        paths_n += len(paths)
        support = support_points(
            paths, dwell=request.dwell, dwell_tol=request.dwell_tol, swing=request.swing, band=request.band
        )
        r, k = np.nonzero(support >= 0)
        hits, pivots, _ = slot_pivots(paths[r], k, support[r, k], swing=request.swing)
        for h, p in zip(hits, pivots):
            b, c, d, branch, _ = part[r[h] // points.size]
            q = points[r[h] % points.size]
            sixbars.append(SixBar(1.0, b, c, d, int(branch), q.real, q.imag, OutputDyad.rpr(complex(p))))
    figures = figures_of(request, sixbars, footprint=False)
    met = sum(meets(request, f) for f in figures)
    print(f"four-bars {len(rows)}, paths {paths_n}, six-bars placed {len(sixbars)}, meeting as placed {met}")
    excess = [violations(request, f) for f in figures]
    near = [i for i, e in enumerate(excess) if all(x == 0 for n, x in e.items() if n not in ("dwell", "swing"))]
    near.sort(key=lambda i: excess[i]["dwell"] + excess[i]["swing"])
    near = near[: args.refine]
    out = refine(request, [sixbars[i] for i in near], [figures[i] for i in near], reach=True)
    good = [sixbars[i] for i, r in zip(near, out) if r.meets]
    print(
        f"refined {len(near)} (missing only the dwell and swing): {len(good)} meet the request, "
        f"{len({(s.b, s.c, s.d) for s in good})} four-bars; {time.perf_counter() - t0:.0f} s"
    )


if __name__ == "__main__":
    main()
