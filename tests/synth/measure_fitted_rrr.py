"""Measurements behind docs/complete-query.md §8 (not a test: run by hand on a built atlas).

    .venv/bin/python tests/synth/measure_fitted_rrr.py ATLAS [SWING_DEG ...]

For the RRR dyads the complete search fits (Q resting at the row's circle centre C₀, rod = its
radius ρ), on 150 rows of every batch of 4 000 arc rows at every level of ATLAS (request: dwell
60°, the query's defaults otherwise), per swing (default 10 30 60 90):

* for six-bars whose dwell holds the middle of the row's stored interval (the stretch), the
  dwell against the longest crank interval around that middle on which the path stays within
  2L·sin(β/2) of the row's own circle — not a bound: Q rests off C₀ when the path misses the
  circle by the level's tolerance, and the count of six-bars longer than it says how often;
* how many six-bars have their longest band interval elsewhere;
* the rocker L against its lower bound max|r| / (2 sin(S/2)), r = |P − C₀| − ρ;

and, on the first batch of every level, the share of rows with a feasible direction in
``fit_rrr``'s coarse scan, and how many rows a stretch seen from C₀ under more than
π − 2μ_min excludes.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from db.engine import open_atlas
from db.queries import AtlasSource
from synth import query
from synth.mechanism import dyad as fits
from synth.mechanism.sixbar import crank_grid
from synth.query.candidates import Request

DEG = math.pi / 180
BATCH = 4000
PER_BATCH = 150
SAMPLES = 3600


def _stats(x: np.ndarray) -> str:
    return "min %.3f p10 %.3f median %.3f p90 %.3f max %.3f" % (x.min(), *np.percentile(x, [10, 50, 90]), x.max())


def _rows(source, request, level, rng=None):
    limits = dict(
        min_transmission=request.min_transmission,
        max_length=request.max_link_ratio,
        min_radius_ratio=1 / request.max_link_ratio,
    )
    for batch in source.scan_segments("arc", level, batch=BATCH, **limits):
        if rng is None:
            yield batch
        else:
            yield [batch[i] for i in rng.choice(len(batch), min(len(batch), PER_BATCH), replace=False)]


def own_circle(source, swing_deg: float) -> None:
    request = Request.from_degrees(dwell=60, swing=swing_deg, output="rrr", refine=False, complete=True)
    rng = np.random.default_rng(1)
    rows = [r for level, _ in source.tolerance_levels() for batch in _rows(source, request, level, rng) for r in batch]
    fitted = query.fit(request, rows, "arc")
    phi = crank_grid(SAMPLES)
    path = query.coupler_paths([f.row for f in fitted], phi)
    r = np.abs(path - np.array([f.rest for f in fitted])[:, None]) - np.array([f.dyad.rod for f in fitted])[:, None]
    rocker = np.array([f.dyad.rocker for f in fitted])
    figures = query.figures_of(request, [f.sixbar() for f in fitted], footprint=False)
    through, elsewhere, ratio_L = [], [], []
    for k, f in enumerate(figures):
        if not f.dwells or not f.acceptable:
            continue
        dwell = f.dwells[0]
        ratio_L.append(rocker[k] / (np.abs(r[k]).max() / (2 * math.sin(f.swing / 2))))
        # through the stretch: the six-bar's dwell holds the middle of the row's stored interval
        start, end = fitted[k].row.parts[0][:2]
        middle = 0.5 * (start + end)
        if (middle - dwell.start) % (2 * math.pi) > dwell.angle:
            elsewhere.append((dwell.angle, rocker[k]))
            continue
        ok = np.abs(r[k]) <= 2 * rocker[k] * math.sin(request.band / 2)
        i0 = int(round(middle % (2 * math.pi) / (2 * math.pi) * SAMPLES)) % SAMPLES
        run = np.roll(ok, -i0)
        ahead = SAMPLES if run.all() else int(np.argmin(run))
        behind = SAMPLES if run.all() else int(np.argmin(run[::-1]))
        bound = min(2 * math.pi, (ahead + behind + 2) * 2 * math.pi / SAMPLES)  # + one step each side
        through.append((dwell.angle, bound, rocker[k]))
    t, e = np.array(through), np.array(elsewhere)
    print(
        f"swing {swing_deg:g}°: {len(rows)} rows, {len(fitted)} dyads, {len(t) + len(e)} six-bars that assemble and rock"
    )
    print(
        "  dwell through the stretch:",
        len(t),
        "— own-circle run / dwell",
        _stats(t[:, 1] / t[:, 0]),
        "; dwells longer than it",
        int(np.sum(t[:, 1] < t[:, 0] - 0.01 * DEG)),
    )
    if len(e):
        print(
            "  longest band interval elsewhere:",
            len(e),
            "— dwell (deg)",
            _stats(e[:, 0] / DEG),
            "; rocker median %.2f" % np.median(e[:, 1]),
        )
    print("  rocker / (max|r| / (2 sin(S/2)))", _stats(np.array(ratio_L)))


def coarse_scan(source, swing_deg: float = 30.0) -> None:
    request = Request.from_degrees(dwell=60, swing=swing_deg, output="rrr", refine=False, complete=True)
    phi = crank_grid(query.FIT_SAMPLES)
    for level, _ in source.tolerance_levels():
        rows = next(_rows(source, request, level))
        part = [np.array([r.parts[0][i] for r in rows]) for i in (0, 1, 2, 3, 5)]
        start, end, x, y, radius = part
        lead, z, (C0, rho, s0, s1, target) = fits._rows(
            query.coupler_paths(rows, phi), x + 1j * y, radius, start, end, request.swing
        )
        phi0, h, m = fits.grid_step(phi)
        mask, mid = fits._dwell_mask(phi0, h, m, s0, s1), fits._mid_sample(phi0, h, m, s0, s1)
        w = z - C0[:, None]
        R = len(rows)
        _, peak_ok = fits._rrr_coarse_scan(
            w, rho, math.cos(request.min_transmission), w[np.arange(R), mid], target, m, 24, 2
        )
        live = peak_ok.any(axis=1)
        seen = np.angle(w * np.conj(w[np.arange(R), mid])[:, None])
        span = np.array([np.ptp(seen[i][mask[i]]) for i in range(R)])
        wide = span > math.pi - 2 * request.min_transmission
        print(
            f"level {level}: {R} rows, {int(live.sum())} with a feasible coarse direction; stretch wider than "
            f"π − 2μ_min: {int(wide.sum())} ({int((wide & live).sum())} of them feasible); span median "
            f"{np.degrees(np.median(span[live])):.0f}° (feasible), {np.degrees(np.median(span[~live])):.0f}° (not)"
        )


if __name__ == "__main__":
    engine = open_atlas(sys.argv[1], readonly=True)
    source = AtlasSource(engine)
    coarse_scan(source)
    for swing in [float(s) for s in sys.argv[2:]] or [10.0, 30.0, 60.0, 90.0]:
        own_circle(source, swing)
