"""``dwell bench atlas``: run time against error of the segment search, at several resolutions.

The same sweep (the first ``--proportions`` of a preset, on both branches) is searched at each
(crank step, rays) resolution, in this process (one core). Reported per resolution:

* ``linkages_per_s`` and ``segments_per_s`` (the search and row building, no database);
* ``dwell_error_deg``: the largest difference between a stored dwell angle and the same
  interval measured independently — a dense walk (0.02°) along the exact path from inside
  the interval to where it leaves the stored band, then bisection (a sample of dwells);
* ``best_dwell_shortfall``: per linkage, kind and level, how much shorter the longest dwell
  found is than at the reference resolution (``--reference-step``/``--reference-rays``),
  relative (median and 90th percentile): what a coarser search misses.

With ``--build N``, the real build (processes + database) of the preset's resolution is
timed too: a sweep of N samples with the preset's settings into a temporary SQLite atlas, in
linkages/s (floor 400, issue #16) and bytes per linkage (floor 8 000). With ``--ingest N``, the
single writer alone: N samples' shards computed first, then written with compute removed (the
writes, the build's digest and the file's packing), in linkages/s (floor 3 000).
JSON on stdout; ``--plot FILE`` draws the time–error chart (PNG).
"""

from __future__ import annotations

import json
import math
import tempfile
import time
from pathlib import Path

import click
import numpy as np

from atlas.pool import MAX_WORKERS
from atlas.sweep import PRESETS, sweep_linkages
from cli.bench.machine import machine_facts
from cli.budget import check_time
from cli.options import RAYS, SEARCH_STEP_DEG, writable_file
from db.rows import linkage_columns, segment_columns
from kinematics.fourbar import fourbar_motion
from synth.kinds import SEGMENT_KINDS, SegmentKind
from synth.linkage import FourBar
from synth.segment_search.minimum_zone import path_deviation
from synth.segment_search.segments import SegmentSearch, find_segments

DEFAULT_RESOLUTIONS = "4:18,3:24,2:36,1.5:48"
FLOOR = 400.0  # linkages/s on 2 cores at the standard resolution, writes and digest included (issue #16)
INGEST_FLOOR = 3000.0  # linkages/s through the single writer with compute removed (issue #16)
STORAGE_FLOOR = 8000  # bytes per linkage (issue #16)


#: Fastest build rate assumed when estimating ``--build`` (linkages/s per worker): about 5x
#: the measured rate, so the estimate is a lower bound on the time.
FASTEST_BUILD_RATE = 1000.0


def _resolutions(text: str) -> list[tuple[float, int]]:
    """``"4:18,3:24"`` → [(4.0, 18), (3.0, 24)], each step and ray count in the search's ranges."""
    out = []
    items = text.split(",")
    if len(items) > 64:
        raise click.BadParameter(f"at most 64 STEP:RAYS pairs, got {len(items)}", param_hint="--resolutions")
    for item in items:
        step, sep, rays = item.partition(":")
        if not sep:
            raise click.BadParameter(
                f"expected STEP:RAYS pairs separated by commas, got {item!r}", param_hint="--resolutions"
            )
        out.append((SEARCH_STEP_DEG.convert(step, None, None), RAYS.convert(rays, None, None)))
    return out


def _independent_dwell(b, c, d, br, found, i, level, part) -> float:
    """The dwell (rad) of stored geometry (i, level, part), measured by a dense walk and bisection."""
    k = found.linkage[i]
    eps = found.tolerances[level]
    geometry = (found.fit_point[i, level, part], found.fit_direction[i, level, part], found.fit_radius[i, level, part])
    kind = SegmentKind.ARC.code if SEGMENT_KINDS[found.kind[i]] is SegmentKind.ARC else SegmentKind.LINE.code
    uv = found.uv[i]

    def outside(phi):
        m = fourbar_motion(1.0, b[k], c[k], d[k], np.atleast_1d(phi), br[k], order=0)
        return np.abs(path_deviation(m.coupler_point(uv.real, uv.imag)[0], kind, *geometry)) > eps

    mid = 0.5 * (found.phi_start[i, level, part] + found.phi_end[i, level, part])
    ends = []
    for sign in (-1, 1):
        phis = mid + sign * np.radians(np.arange(0.0, 180.0, 0.02))
        j = int(np.argmax(outside(phis)))
        lo, hi = phis[max(j - 1, 0)], phis[j]
        for _ in range(40):
            m = 0.5 * (lo + hi)
            if outside(m)[0]:
                hi = m
            else:
                lo = m
        ends.append(lo)
    return ends[1] - ends[0]


def _best(found, n_links: int, levels: int) -> np.ndarray:
    best = np.zeros((n_links, len(SEGMENT_KINDS), levels))
    dwell = np.where(found.has_dwell[..., 0], found.phi_end[..., 0] - found.phi_start[..., 0], 0.0)
    for kind in range(len(SEGMENT_KINDS)):
        sel = found.kind == kind
        for level in range(levels):
            np.maximum.at(best[:, kind, level], found.linkage[sel], dwell[sel, level])
    return best


@click.command("atlas")
@click.option("--preset", type=click.Choice(sorted(PRESETS)), default="standard", show_default=True)
@click.option(
    "--proportions",
    type=click.IntRange(1, 100_000),
    default=32,
    show_default=True,
    help="Proportions of the sweep searched (each on both branches).",
)
@click.option(
    "--resolutions",
    default=DEFAULT_RESOLUTIONS,
    show_default=True,
    help="STEP:RAYS pairs (degrees, rays; each in the ranges of --reference-step and --reference-rays).",
)
@click.option(
    "--reference-step",
    type=SEARCH_STEP_DEG,
    default=0.75,
    show_default=True,
    help="Crank step (°) of the reference search.",
)
@click.option("--reference-rays", type=RAYS, default=96, show_default=True, help="Rays of the reference search.")
@click.option(
    "--dwell-samples",
    type=click.IntRange(0, 10_000),
    default=60,
    show_default=True,
    help="Stored dwells re-measured independently per resolution.",
)
@click.option(
    "--build",
    "build_samples",
    type=click.IntRange(0, 2**24),
    default=0,
    show_default=True,
    help="Also time a real build of N samples at the preset's resolution (0: skip).",
)
@click.option(
    "--ingest",
    "ingest_samples",
    type=click.IntRange(0, 2**24),
    default=0,
    show_default=True,
    help="Also time the single writer alone on N samples: their shards computed first, then written "
    "(writes, digest, packing) with compute removed (0: skip).",
)
@click.option(
    "--workers",
    type=click.IntRange(1, MAX_WORKERS),
    default=2,
    show_default=True,
    help="Workers of the timed build (and of computing --ingest's shards).",
)
@click.option(
    "--plot",
    type=click.Path(dir_okay=False),
    callback=writable_file(".png"),
    default=None,
    help="Write the time–error chart (PNG).",
)
def atlas(
    preset,
    proportions,
    resolutions,
    reference_step,
    reference_rays,
    dwell_samples,
    build_samples,
    ingest_samples,
    workers,
    plot,
):
    """Atlas build: linkages/s and segments/s against dwell error, per search resolution."""
    spec = PRESETS[preset]
    try:
        pairs = _resolutions(resolutions)
    except click.BadParameter as exc:
        exc.param_hint = "--resolutions"
        raise
    sweep = sweep_linkages(spec)
    for option, samples in (("--build", build_samples), ("--ingest", ingest_samples)):
        if samples:
            linkages = samples * len(sweep) / spec.samples * len(spec.branches)
            check_time(
                linkages / (FASTEST_BUILD_RATE * workers),
                f"{option} {samples} (about {linkages:,.0f} linkages)",
                f"lower {option} (the standard atlas is 32 768 samples)",
            )
    n = min(proportions, len(sweep))
    b, c, d = (np.repeat(x[:n], len(spec.branches)) for x in (sweep.b, sweep.c, sweep.d))
    br = np.tile(np.asarray(spec.branches), n)
    levels = len(spec.tolerances)
    fourbars = FourBar(b=b, c=c, d=d, branch=br)
    links = linkage_columns(0, np.arange(b.size), fourbars, np.zeros(b.size, int), np.zeros((b.size, 1)))

    def search(step: float, rays: int):
        s = SegmentSearch.from_spec(spec.replace(crank_step_deg=step, rays=rays))
        t0 = time.perf_counter()
        found = find_segments(b, c, d, br, s)
        rows = [table.rows() for table in segment_columns(found, links)]
        return found, rows, time.perf_counter() - t0

    ref, _, ref_seconds = search(reference_step, reference_rays)
    ref_best = _best(ref, b.size, levels)
    rng = np.random.default_rng(0)
    results = []
    for step, rays in pairs:
        found, (segments, _), seconds = search(step, rays)
        best = _best(found, b.size, levels)
        has = ref_best > 0
        shortfall = np.clip((ref_best - best)[has] / ref_best[has], 0.0, None)
        triples = [
            (i, lv, p)
            for i in range(len(found))
            for lv in range(levels)
            for p in range(2 if SEGMENT_KINDS[found.kind[i]] is SegmentKind.DOUBLE_LINE else 1)
            if found.has_dwell[i, lv, p]
        ]
        pick = rng.choice(len(triples), size=min(dwell_samples, len(triples)), replace=False) if triples else []
        errors = [
            abs(
                _independent_dwell(b, c, d, br, found, *triples[j])
                - (found.phi_end[triples[j]] - found.phi_start[triples[j]])
            )
            for j in pick
        ]
        results.append(
            {
                "crank_step_deg": step,
                "rays": rays,
                "linkages": int(b.size),
                "seconds": round(seconds, 4),
                "linkages_per_s": round(b.size / seconds, 2),
                "segments": len(segments),
                "segments_per_s": round(len(segments) / seconds, 1),
                "segments_by_kind": {k: int(np.count_nonzero(found.kind == j)) for j, k in enumerate(SEGMENT_KINDS)},
                "dwell_error_deg": float(np.degrees(max(errors))) if errors else None,
                "dwells_checked": len(errors),
                "best_dwell_shortfall_median": float(np.median(shortfall)) if shortfall.size else None,
                "best_dwell_shortfall_p90": float(np.percentile(shortfall, 90)) if shortfall.size else None,
            }
        )
    report = {
        "benchmark": "atlas",
        "preset": preset,
        "proportions": n,
        "branches": list(spec.branches),
        "tolerances": list(spec.tolerances),
        "reference": {
            "crank_step_deg": reference_step,
            "rays": reference_rays,
            "seconds": round(ref_seconds, 3),
            "linkages_per_s": round(b.size / ref_seconds, 2),
        },
        "resolutions": results,
        "machine": machine_facts(),
    }
    if build_samples:
        report["build"] = timed_build(spec, build_samples, workers)
    if ingest_samples:
        report["ingest"] = timed_ingest(spec, ingest_samples, workers)
    click.echo(json.dumps(report, indent=2))
    if plot:
        _plot(report, Path(plot))


def timed_build(spec, samples: int, workers: int) -> dict:
    from atlas.build import build_atlas
    from db.engine import open_atlas
    from db.summary import storage_bytes

    small = spec.replace(samples=samples)
    with tempfile.TemporaryDirectory() as tmp:
        target = str(Path(tmp) / "bench.sqlite")
        t0 = time.perf_counter()
        summary = build_atlas(target, small, workers=workers)
        seconds = time.perf_counter() - t0
        engine = open_atlas(target, readonly=True)
        try:
            size = storage_bytes(engine)
        finally:
            engine.dispose()
    linkages = int(getattr(summary, "linkages", 0))
    rate = linkages / seconds if seconds > 0 else math.inf
    per_linkage = size / linkages if size and linkages else None
    return {
        "samples": samples,
        "workers": workers,
        "linkages": linkages,
        "segments": int(sum(summary.segments.values())),
        "seconds": round(seconds, 2),
        "linkages_per_s": round(rate, 1),
        "floor_linkages_per_s": FLOOR,
        "meets_floor": bool(rate >= FLOOR),
        "storage_bytes": size,
        "bytes_per_linkage": None if per_linkage is None else round(per_linkage, 1),
        "floor_bytes_per_linkage": STORAGE_FLOOR,
        "meets_storage_floor": None if per_linkage is None else bool(per_linkage <= STORAGE_FLOOR),
    }


def timed_ingest(spec, samples: int, workers: int) -> dict:
    """The single writer's rate: the shards of ``samples`` computed first (``workers``
    processes, not timed) and packed as a worker hands them over (:func:`atlas.shard.handed_over`,
    also with one worker), then handed to :func:`atlas.build.build_atlas` as if computed —
    what is timed is the driver alone: the shards' writes, the build's digest and the file's
    packing, into a new SQLite atlas."""
    from atlas.build import build_atlas, run_shards
    from atlas.shard import ShardResult, handed_over

    small = spec.replace(samples=samples)
    sweep = sweep_linkages(small)
    t0 = time.perf_counter()
    cached = {
        r.shard_index: handed_over(r) if isinstance(r, ShardResult) else r
        for r in run_shards(small, sweep, range(sweep.n_shards(small.shard_size)), workers)
    }
    computed = time.perf_counter() - t0

    def replay(spec, sweep, indices, workers, *, tick=None):
        return (cached[i] for i in indices)

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        summary = build_atlas(str(Path(tmp) / "ingest.sqlite"), small, runner=replay)
        seconds = time.perf_counter() - t0
    rate = summary.linkages / seconds if seconds > 0 else math.inf
    return {
        "samples": samples,
        "shards": len(cached),
        "linkages": int(summary.linkages),
        "dwell_rows": int(summary.dwells),
        "compute_seconds": round(computed, 2),
        "seconds": round(seconds, 3),
        "linkages_per_s": round(rate, 1),
        "floor_linkages_per_s": INGEST_FLOOR,
        "meets_floor": bool(rate >= INGEST_FLOOR),
    }


def _plot(report: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = report["resolutions"]
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    x = [r["linkages_per_s"] for r in rows]
    y = [100 * (r["best_dwell_shortfall_median"] or 0.0) for r in rows]
    y90 = [100 * (r["best_dwell_shortfall_p90"] or 0.0) for r in rows]
    ax.plot(x, y, "o-", label="median shortfall of the best dwell")
    ax.plot(x, y90, "s--", label="90th percentile")
    for r, xi, yi in zip(rows, x, y90):
        ax.annotate(
            f"{r['crank_step_deg']:g}°, {r['rays']} rays",
            (xi, yi),
            textcoords="offset points",
            xytext=(4, 6),
            fontsize=8,
        )
    ax.set_xlabel("linkages per second (one core, search only)")
    ax.set_ylabel(f"% shorter than at {report['reference']['crank_step_deg']:g}°/{report['reference']['rays']} rays")
    err = max((r["dwell_error_deg"] or 0.0) for r in rows)
    ax.set_title(
        f"Atlas search: speed against error ({report['preset']} sweep, {report['proportions']} proportions)\n"
        f"stored dwell angles vs independent measurement: max error {err:.1e}°",
        fontsize=10,
    )
    ax.grid(True, alpha=0.3)
    ax.margins(x=0.15, y=0.15)  # room for the point labels
    ax.legend()
    fig.savefig(path, dpi=120)
    plt.close(fig)
