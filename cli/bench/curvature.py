"""``dwell bench curvature``: instants per second of the curvature engine, with its error.

One instant is one (linkage, crank angle): the four-bar solve with three derivative orders,
the pole, the inflection circle, Ball's point and ``--rays`` conjugate pairs by line
scanning (circle point in both frames, centre point, radius, flags). Linkages are processed
in batches (what an atlas shard does) so that the per-ray output stays a few tens of MB.
The time per stage says where it goes. The double-Ball-point search is timed per linkage.
Errors: the largest residual of the unflagged results of a sample of the same workload
against the extended-precision reference (:func:`cli.bench.reference.residuals`).
"""

from __future__ import annotations

import json
import time

import click
import numpy as np

from cli.bench import reference
from cli.bench.machine import machine_facts
from cli.budget import check_memory, check_time
from cli.options import SEED
from kinematics.fourbar import fourbar_motion
from synth.curvature.ball import ball_point
from synth.curvature.double_ball import double_ball_points
from synth.curvature.inflection import inflection_circle
from synth.curvature.line_scan import line_scan
from synth.curvature.pole import pole

STAGES = ("fourbar_motion", "pole", "inflection_circle", "ball_point", "line_scan")
FLOOR = 500_000
#: Peak memory per conjugate pair of one call (bytes; 60–75 measured with tracemalloc).
BYTES_PER_PAIR = 100


def crank_rockers(n: int, seed: int) -> tuple[np.ndarray, ...]:
    """n random Grashof crank-rockers with crank 1 (b, c, d uniform in [1.2, 6])."""
    rng = np.random.default_rng(seed)
    rows = [np.empty((0, 3))]  # n may be 0
    while sum(len(r) for r in rows) < n:
        b, c, d = rng.uniform(1.2, 6.0, (3, 4 * n + 8))
        srt = np.sort(np.stack([np.ones_like(b), b, c, d]), axis=0)
        rows.append(np.stack([b, c, d], axis=1)[srt[0] + srt[3] < srt[1] + srt[2]])
    b, c, d = np.concatenate(rows)[:n].T
    return np.ones(n), b, c, d


def _instants(a, b, c, d, phi, alpha, clock: dict[str, float] | None = None) -> dict[str, object]:
    """The whole per-instant workload on linkages (n, 1, 1) × angles (m, 1) × rays (k,)."""
    stamps = [time.perf_counter()]
    motion = fourbar_motion(a, b, c, d, phi, 1, order=3)
    stamps.append(time.perf_counter())
    pl = pole(motion)
    stamps.append(time.perf_counter())
    circle = inflection_circle(pl)
    stamps.append(time.perf_counter())
    ball = ball_point(pl)
    stamps.append(time.perf_counter())
    scan = line_scan(pl, alpha)
    stamps.append(time.perf_counter())
    if clock is not None:
        for name, t0, t1 in zip(STAGES, stamps, stamps[1:]):
            clock[name] += t1 - t0
    return {"pole": pl, "inflection_circle": circle, "ball_point": ball, "line_scan": scan}


def _run(links, phi, alpha, batch: int, clock: dict[str, float] | None = None) -> float:
    a, b, c, d = links
    t = time.perf_counter()
    for i in range(0, a.size, batch):
        s = slice(i, i + batch)
        col = lambda x: x[s, None, None]  # noqa: E731
        _instants(col(a), col(b), col(c), col(d), phi, alpha, clock)
    return time.perf_counter() - t


def _errors(seed: int, rays: int) -> dict[str, float]:
    a, b, c, d = crank_rockers(40, seed + 1)
    rng = np.random.default_rng(seed + 2)
    phi = rng.uniform(0, 2 * np.pi, (40, 25))
    alpha = np.pi * np.arange(rays) / rays
    col = lambda x: x[:, None, None]  # noqa: E731
    res = _instants(col(a), col(b), col(c), col(d), phi[..., None], alpha)
    jet = reference.loop_jet(col(a), col(b), col(c), col(d), 1.0, phi[..., None])
    beta = rng.uniform(0, 2 * np.pi, (40, 25, 2))
    out = reference.residuals(jet, col(a), res, circle_angles=beta)
    return {k: float(v.max()) if v.size else 0.0 for k, v in out.items()}


@click.command("curvature")
@click.option(
    "--linkages",
    type=click.IntRange(1, 1_000_000),
    default=400,
    show_default=True,
    help="Random crank-rockers (crank 1).",
)
@click.option(
    "--angles", type=click.IntRange(1, 100_000), default=720, show_default=True, help="Crank angles per linkage."
)
@click.option(
    "--rays",
    type=click.IntRange(1, 10_000),
    default=36,
    show_default=True,
    help="Conjugate pairs per instant (rays over 180 deg).",
)
@click.option(
    "--batch",
    type=click.IntRange(1, 1_000_000),
    default=64,
    show_default=True,
    help="Linkages per call (bounds memory: batch x angles x rays pairs).",
)
@click.option(
    "--repeat",
    type=click.IntRange(1, 100),
    default=3,
    show_default=True,
    help="Timed runs (the best is kept: the machine is shared).",
)
@click.option(
    "--double-ball-linkages",
    "n_double",
    type=click.IntRange(0, 100_000),
    default=20,
    show_default=True,
    help="Linkages for the double-Ball-point search timing.",
)
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of the random cases (>= 0).")
def curvature(linkages, angles, rays, batch, repeat, n_double, seed):
    """Instants/s (pole + inflection circle + Ball point + conjugate pairs) and double-Ball time (JSON)."""
    check_memory(
        min(batch, linkages) * angles * rays * BYTES_PER_PAIR,
        f"--batch {batch} × --angles {angles} × --rays {rays} conjugate pairs per call",
        "lower --batch or --rays",
    )
    links = crank_rockers(linkages, seed)
    phi = np.linspace(0, 2 * np.pi, angles, endpoint=False)[:, None]
    alpha = np.pi * np.arange(rays) / rays
    instants = linkages * angles
    _run(tuple(x[:1] for x in links), phi, alpha, batch)  # warm-up
    # one batch timed, the whole run estimated from it (repeat timed runs + staged run + errors)
    first = min(batch, linkages)
    seconds = _run(tuple(x[:first] for x in links), phi, alpha, batch) * (linkages / first) * (repeat + 2)
    check_time(
        seconds,
        f"--linkages {linkages} × --angles {angles} × --rays {rays} × --repeat {repeat}",
        "lower --linkages, --angles, --rays or --repeat",
    )
    best = min(_run(links, phi, alpha, batch) for _ in range(repeat))
    clock = dict.fromkeys(STAGES, 0.0)
    _run(links, phi, alpha, batch, clock)
    staged = sum(clock.values())
    click.echo(f"{instants / best:,.0f} instants/s with {rays} conjugate pairs each", err=True)

    double = None
    if n_double:
        a, b, c, d = crank_rockers(n_double, seed + 3)
        double_ball_points(a[:1], b[:1], c[:1], d[:1])  # warm-up (imports shapely)
        t = time.perf_counter()
        found = double_ball_points(a, b, c, d)
        elapsed = time.perf_counter() - t
        counts = np.bincount(found.linkage_index, minlength=n_double)
        double = {
            "linkages": n_double,
            "samples_per_turn": 4096,
            "seconds_per_linkage": elapsed / n_double,
            "points_per_linkage": {"min": int(counts.min()), "mean": float(counts.mean()), "max": int(counts.max())},
            "false_crossings_rejected": int(found.false_crossings.sum()),
            "unconverged": int(found.unconverged.sum()),
        }
        click.echo(f"double Ball points: {elapsed / n_double * 1e3:.1f} ms per linkage", err=True)

    doc = {
        "benchmark": "curvature",
        "what": "per instant: four-bar solve (3 derivative orders), pole, inflection circle, Ball's point, "
        f"{rays} conjugate pairs (circle point xy+uv, centre point, radius, flags)",
        "linkages": linkages,
        "angles_per_linkage": angles,
        "rays": rays,
        "instants": instants,
        "batch_linkages": batch,
        "cores_used": 1,
        "seconds": best,
        "instants_per_s": instants / best,
        "floor_instants_per_s_per_core": FLOOR,
        "meets_floor": instants / best >= FLOOR,
        "time_share": {k: v / staged for k, v in clock.items()},
        "ns_per_instant": {k: v / instants * 1e9 for k, v in clock.items()},
        "double_ball": double,
        "max_residual_vs_extended_precision": _errors(seed, rays),
        "platform": machine_facts(),
    }
    click.echo(json.dumps(doc, indent=1))
