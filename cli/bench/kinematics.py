"""``dwell bench kinematics``: four-bar positions with three derivative orders per second.

Time and error side by side: throughput for n linkages × M crank angles, its ratio to the
plain numpy closed form of the positions alone timed in the same run (:mod:`cli.bench.plain`;
a ratio means the same on any machine), and the float64 error against the same closed form
evaluated in extended precision (numpy longdouble) plus the loop-closure residual |B − B0| − c.
"""

from __future__ import annotations

import json
import time

import click
import numpy as np

from cli.bench.machine import machine_facts
from cli.bench.plain import fourbar_positions
from cli.budget import check_memory, check_time
from cli.options import SEED
from kinematics.fourbar import fourbar_motion

#: Linkages per call when streaming a large sweep (what an atlas shard does): the output of
#: one call stays small enough that its pages are reused instead of faulted in afresh.
STREAM_BATCH = 2048
#: Each timed run covers at least this many positions, so that a 0.1 ms call is not timed alone.
MIN_POSITIONS_PER_RUN = 200_000
#: Peak memory of one order-3 call per position (bytes; 70 measured with tracemalloc, with
#: room for the plain-numpy yardstick's temporaries).
BYTES_PER_POSITION = 120
#: Fastest rate assumed in the time estimate (positions/s: ~3x the best measured), so the
#: estimate is a lower bound.
FASTEST_POSITIONS_PER_S = 1e8


def random_linkages(n: int, seed: int) -> tuple[np.ndarray, ...]:
    """n random crank-rockers, crank = 1 (b, c, d drawn until Grashof crank-rocker)."""
    rng = np.random.default_rng(seed)
    b, c, d = rng.uniform(1.5, 5.0, (3, 4 * n + 16))
    srt = np.sort(np.stack([np.ones_like(b), b, c, d]), axis=0)
    ok = (srt[0] + srt[3] < srt[1] + srt[2]) & (np.minimum.reduce([b, c, d]) > 1)
    b, c, d = b[ok][:n], c[ok][:n], d[ok][:n]
    return np.ones((n, 1)), b[:, None], c[:, None], d[:, None]


def sizes_option(sizes: str, most: int) -> list[int]:
    """``--n``: comma-separated whole numbers from 1 to ``most`` (else one line, exit 2)."""
    try:
        ns = [int(x) for x in sizes.split(",") if x.strip()]
    except ValueError:
        raise click.BadParameter(f"--n must be comma-separated whole numbers, got {sizes!r}") from None
    if not ns or min(ns) < 1 or max(ns) > most:
        raise click.BadParameter(f"--n values must be between 1 and {most}")
    return ns


def check_positions(
    ns: list[int], angles: int, repeat: int, bytes_per_position: float, passes: int, things: str
) -> None:
    """Refuse (cli.budget) a run whose one call over ``max(ns) × angles`` positions needs too
    much memory, or whose ``passes`` timed passes per repeat would take too long."""
    check_memory(
        max(ns) * angles * bytes_per_position,
        f"{max(ns):,} {things} × {angles:,} angles in one call",
        "lower --n or --angles",
    )
    runs = sum(max(n * angles, MIN_POSITIONS_PER_RUN) for n in ns) * passes
    check_time(
        runs / FASTEST_POSITIONS_PER_S,
        f"--n {','.join(map(str, ns))} × --angles {angles} × --repeat {repeat}",
        "lower --n, --angles or --repeat",
    )


def best_time(fn, repeat: int, loops: int = 1) -> float:
    """Best over ``repeat`` runs of the mean time of ``loops`` calls (timeit's method)."""
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        for _ in range(loops):
            fn()
        best = min(best, (time.perf_counter() - t) / loops)
    return best


def _accuracy(samples: int, angles: int, seed: int) -> dict[str, float]:
    """Largest float64 error, relative to 1 + |value|, against extended precision."""
    from kinematics.fourbar import solve_block  # the one closed form, run at higher precision

    a, b, c, d = random_linkages(samples, seed + 1)
    phi = np.linspace(0, 2 * np.pi, angles, endpoint=False)
    m = fourbar_motion(a, b, c, d, phi, 1, order=3)
    ld = np.longdouble
    shape = m.shape
    e_ref = np.empty(shape, np.clongdouble)
    st_ref = np.empty(shape, np.uint8)
    d_ref = [np.empty(shape, ld) for _ in range(6)]
    solve_block(*(np.asarray(x, ld) for x in (a, b, c, d, phi[None, :], np.ones((1, 1)))), 3, e_ref, st_ref, d_ref)
    ok = m.ok
    out = {"theta": float(np.max(np.abs(m.e_theta - e_ref)[ok]))}
    names = ["dtheta1", "dgamma1", "dtheta2", "dgamma2", "dtheta3", "dgamma3"]
    got = [m.dtheta[0], m.dgamma[0], m.dtheta[1], m.dgamma[1], m.dtheta[2], m.dgamma[2]]
    for name, x, ref in zip(names, got, d_ref):
        out[name] = float(np.max((np.abs(x - ref) / (1 + np.abs(ref)))[ok]))
    out["loop_residual"] = float(np.max(np.abs(np.abs(m.B - m.d) - m.c)[ok]))
    return out


@click.command("kinematics")
@click.option(
    "--n", "sizes", default="1,10,100,1000,10000,100000", show_default=True, help="Comma-separated numbers of linkages."
)
@click.option(
    "--angles", default=360, show_default=True, type=click.IntRange(1, 100_000), help="Crank angles per linkage."
)
@click.option(
    "--repeat", default=3, show_default=True, type=click.IntRange(1, 100), help="Timed runs per size (best is kept)."
)
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of the random linkages (>= 0).")
def kinematics(sizes: str, angles: int, repeat: int, seed: int) -> None:
    """Four-bar positions + 3 derivative orders per second (one core), with their error."""
    ns = sizes_option(sizes, 1_000_000)
    phi = np.linspace(0, 2 * np.pi, angles, endpoint=False)
    check_positions(ns, angles, repeat, BYTES_PER_POSITION, 2 * repeat + 1, "linkages")
    results = []
    for n in ns:
        a, b, c, d = random_linkages(n, seed)
        positions = n * angles
        # warm-up, then the single call over the whole n × M block
        fourbar_motion(a[:1], b[:1], c[:1], d[:1], phi, 1, order=3)
        loops = max(1, MIN_POSITIONS_PER_RUN // positions)  # small n: many calls per timed run
        t_single = best_time(lambda: fourbar_motion(a, b, c, d, phi, 1, order=3), repeat, loops)

        def streamed():
            for i in range(0, n, STREAM_BATCH):
                s = slice(i, i + STREAM_BATCH)
                fourbar_motion(a[s], b[s], c[s], d[s], phi, 1, order=3)

        t_stream = best_time(streamed, repeat, loops)
        t_plain = best_time(lambda: fourbar_positions(a, b, c, d, phi), repeat, loops)
        # the yardstick computes the same θ (all sweeps are crank-rockers: every position closes)
        theta = np.angle(fourbar_motion(a, b, c, d, phi, 1, order=0).e_theta)
        agree = float(np.max(np.abs(np.angle(np.exp(1j * (theta - fourbar_positions(a, b, c, d, phi)))))))
        results.append(
            {
                "n": n,
                "positions": positions,
                "calls_per_timed_run": loops,
                "single_call_s": t_single,
                "single_call_positions_per_s": positions / t_single,
                "streamed_s": t_stream,
                "streamed_positions_per_s": positions / t_stream,
                "plain_numpy_positions_only_per_s": positions / t_plain,
                "ratio_to_plain_numpy": t_plain / min(t_single, t_stream),
                "plain_numpy_max_abs_theta_difference_rad": agree,
            }
        )
        click.echo(
            f"n={n}: {positions / t_stream / 1e6:.2f} M positions/s streamed, "
            f"{positions / t_single / 1e6:.2f} M single call; plain numpy positions only "
            f"{positions / t_plain / 1e6:.2f} M (ratio {t_plain / min(t_single, t_stream):.2f})",
            err=True,
        )
    doc = {
        "benchmark": "kinematics",
        "what": "four-bar positions with theta, gamma and their 1st-3rd crank-angle derivatives; "
        "ratio_to_plain_numpy: the best of single call and streamed against the plain numpy "
        "law-of-cosines theta alone (cli/bench/plain.py), same run",
        "angles_per_linkage": angles,
        "stream_batch_linkages": STREAM_BATCH,
        "cores_used": 1,
        "floor_positions_per_s_per_core": 5_000_000,
        "results": results,
        "max_error_vs_extended_precision": _accuracy(200, angles, seed),
        "platform": machine_facts(),
    }
    click.echo(json.dumps(doc, indent=1))
