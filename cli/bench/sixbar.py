"""``dwell bench sixbar``: six-bar (four-bar + RRR dyad) positions per second, as a ratio to
a plain numpy closed form timed in the same run (:mod:`cli.bench.plain`), so the figure means
the same on any machine; the two are checked to agree (largest |Δψ|) before either is timed.

Issue 16's floors: the product's exact simulation (:func:`synth.mechanism.sixbar.simulate`, order 0:
positions, status flags, transmission angles, continuous ψ — the compiled kernel of
:mod:`synth.mechanism.sixbar_kernel`) at N = 10 000 × 360 should reach at least the plain closed form's
rate (ratio ≥ 1), and at N = 1 twice pylinkage's. The numpy path it replaced at order 0 (still
the reference, and the path of derivative orders 1–2) is timed beside it.

The ratio is one core against one core (the kernel held to one thread,
:func:`synth.parallel_rows.set_threads`); where the process may use more cores, the kernel's
rate on all of them (its batches split over threads, as the product runs it) is reported
beside it (``*_threads``).
"""

from __future__ import annotations

import json

import click
import numpy as np

from cli.bench.kinematics import MIN_POSITIONS_PER_RUN, best_time, check_positions, random_linkages, sizes_option
from cli.bench.machine import machine_facts
from cli.bench.plain import sixbar_rrr_positions
from cli.options import SEED
from synth import parallel_rows
from synth.mechanism.sixbar import SixBars, simulate, simulate_numpy

#: Peak memory of simulate(order=0) per position (bytes; 229 measured with tracemalloc).
SIXBAR_BYTES_PER_POSITION = 300


def random_rrr_sixbars(n: int, seed: int) -> SixBars:
    """``n`` crank-rocker four-bars (crank 1) with a coupler point and an RRR dyad that
    assembles over the whole turn: D three path extents away from the coupler curve's centre,
    L + ρ = 1.1·max|P − D| and |L − ρ| = 0.9·min|P − D|."""
    rng = np.random.default_rng(seed)
    a, b, c, d = (x[:, 0] for x in random_linkages(n, seed))
    u, v = rng.uniform(-1.0, 2.0, (2, n))
    phi = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    from kinematics.fourbar import fourbar_motion

    m = fourbar_motion(a[:, None], b[:, None], c[:, None], d[:, None], phi, 1, order=0)
    P = m.coupler_point(u[:, None], v[:, None], 0)[0]
    centre = P.mean(axis=1)
    extent = np.abs(P - centre[:, None]).max(axis=1)
    D = centre + 3.0 * extent * np.exp(1j * rng.uniform(0, 2 * np.pi, n))
    r = np.abs(P - D[:, None])
    hi, lo = 1.1 * r.max(axis=1), 0.9 * r.min(axis=1)
    rocker, rod = (hi + lo) / 2, (hi - lo) / 2
    ones = np.ones(n)
    return SixBars(a, b, c, d, ones, u, v, np.zeros(n, bool), D.astype(complex), rocker, rod, ones.copy())


def _plain(s: SixBars, phi):
    col = lambda x: x[:, None]  # noqa: E731
    return sixbar_rrr_positions(
        col(s.a), col(s.b), col(s.c), col(s.d), col(s.u), col(s.v), col(s.pivot), col(s.rocker), col(s.rod), phi
    )


@click.command("sixbar")
@click.option("--n", "sizes", default="1,100,10000", show_default=True, help="Comma-separated numbers of six-bars.")
@click.option(
    "--angles", default=360, show_default=True, type=click.IntRange(1, 3600), help="Crank angles per six-bar."
)
@click.option(
    "--repeat", default=3, show_default=True, type=click.IntRange(1, 100), help="Timed runs per size (best is kept)."
)
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of the random six-bars.")
def sixbar(sizes: str, angles: int, repeat: int, seed: int) -> None:
    """Six-bar positions per second (one core, and all the cores the product uses), as a ratio to
    plain numpy in the same run."""
    ns = sizes_option(sizes, 100_000)
    cores = parallel_rows.threads()
    phi = np.linspace(0, 2 * np.pi, angles, endpoint=False)
    check_positions(ns, angles, repeat, SIXBAR_BYTES_PER_POSITION, 2 * repeat, "six-bars")
    results = []
    for n in ns:
        six = random_rrr_sixbars(n, seed)
        ours = simulate(six, phi, order=0)
        plain = _plain(six, phi)
        agree = float(np.max(np.abs(np.angle(np.exp(1j * (ours.psi - plain))))))
        assembled = int(np.count_nonzero(ours.status == 0))
        one = six[0] if n == 1 else None
        positions = n * angles
        loops = max(1, MIN_POSITIONS_PER_RUN // positions)
        run = (lambda: simulate(one, phi, order=0)) if one is not None else (lambda: simulate(six, phi, order=0))
        try:  # one core against one core; then the product's own split over the cores
            parallel_rows.set_threads(1)
            t_ours = best_time(run, repeat, loops)
        finally:
            parallel_rows.set_threads(cores)
        t_threads = best_time(run, repeat, loops) if cores > 1 else t_ours
        t_plain = best_time(lambda: _plain(six, phi), repeat, loops)
        single = one is not None
        t_numpy = best_time(
            lambda: simulate_numpy(SixBars.from_sixbars([one]) if single else six, single, phi, 0, "flag"),
            repeat,
            loops,
        )
        results.append(
            {
                "n": n,
                "positions": positions,
                "assembled_positions": assembled,
                "max_abs_psi_difference_rad": agree,
                "ours_positions_per_s": positions / t_ours,
                "plain_numpy_positions_per_s": positions / t_plain,
                "ratio_to_plain_numpy": t_plain / t_ours,
                "numpy_path_positions_per_s": positions / t_numpy,
                "numpy_path_ratio_to_plain_numpy": t_plain / t_numpy,
                "ours_threads_positions_per_s": positions / t_threads,
                "ratio_to_plain_numpy_threads": t_plain / t_threads,
            }
        )
        click.echo(
            f"n={n}: {positions / t_ours / 1e6:.2f} M positions/s, plain numpy "
            f"{positions / t_plain / 1e6:.2f} M (ratio {t_plain / t_ours:.2f}; the numpy path "
            f"{t_plain / t_numpy:.2f}; on {cores} threads {t_plain / t_threads:.2f}); |Δψ| ≤ {agree:.1e}",
            err=True,
        )
    doc = {
        "benchmark": "sixbar",
        "what": "four-bar + RRR dyad positions: synth.mechanism.sixbar.simulate(order=0) (compiled kernel; status flags, "
        "transmission angles, continuous psi) against the plain numpy law-of-cosines closed form "
        "(cli/bench/plain.py); numpy_path_*: the same simulation on the numpy reference path",
        "angles_per_sixbar": angles,
        "cores_used": 1,
        "threads": cores,
        "floor_ratio_to_plain_numpy_at_10000": 1.0,
        "results": results,
        "platform": machine_facts(),
    }
    click.echo(json.dumps(doc, indent=1))
