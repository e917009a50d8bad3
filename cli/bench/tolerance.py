"""``dwell bench tolerance``: the cost of a candidate's toleranced deviation
(:func:`synth.mechanism.tolerance.toleranced_deviation`: ``--draws`` six-bars made within the tolerance,
simulated and measured as one batch) per candidate, beside how far its 95th percentile moves
with the seed of the draws (the estimate's own error).

The six-bars are the demo's best RRR 60°/30° and RPR 45°/40° answers (crank 1); the default
tolerance is 0.05 on a crank of 40 (``--tolerance 0.05 --crank 40``).
"""

from __future__ import annotations

import json
import math
import os
import platform
import time

import click
import numpy as np

from cli.options import Bounded
from synth.mechanism.sixbar import OutputDyad, SixBar

#: (name, six-bar, requested dwell in degrees)
SIXBARS = (
    (
        "rrr_60_30",
        SixBar(1.0, 3.542, 2.49, 3.938, 1, 3.645, -0.321, OutputDyad.rrr(complex(4.219, -0.5853), 0.4984, 2.807, 1)),
        60.0,
    ),
    ("rpr_45_40", SixBar(1.0, 4.072, 1.546, 4.173, 1, 3.794, -0.2963, OutputDyad.rpr(complex(1.982, 2.447))), 45.0),
)
#: Target per candidate at 256 draws (s), issue 44.
TARGET_S = 0.005


@click.command("tolerance")
@click.option(
    "--draws", default=256, show_default=True, type=click.IntRange(16, 4096), help="Six-bars drawn per candidate."
)
@click.option(
    "--tolerance",
    default=0.05 / 40,
    show_default=True,
    type=Bounded(0.0, 0.1, "a tolerance in cranks"),
    help="Tolerance in cranks.",
)
@click.option("--repeat", default=5, show_default=True, type=click.IntRange(1, 100), help="Timed runs (best is kept).")
@click.option(
    "--seeds",
    default=5,
    show_default=True,
    type=click.IntRange(1, 50),
    help="Seeds whose percentiles give the estimate's spread.",
)
def tolerance(draws: int, tolerance: float, repeat: int, seeds: int) -> None:
    """Cost per candidate of the toleranced deviation, and its spread over seeds (JSON)."""
    from synth.mechanism.figures import sixbar_figures
    from synth.mechanism.tolerance import SEED, toleranced_deviation

    results = []
    for name, sb, dwell_deg in SIXBARS:
        length = math.radians(dwell_deg)
        f = sixbar_figures(sb, band=math.radians(0.1), dwell_length=length)
        centres = [0.5 * (d.start + d.end) for d in f.dwells]
        value = toleranced_deviation(sb, tolerance, centres, length, draws=draws)  # compiles, warms
        best = math.inf
        for _ in range(repeat):
            t = time.perf_counter()
            toleranced_deviation(sb, tolerance, centres, length, draws=draws)
            best = min(best, time.perf_counter() - t)
        others = [
            toleranced_deviation(sb, tolerance, centres, length, draws=draws, seed=SEED + k) for k in range(1, seeds)
        ]
        finite = [math.degrees(x) for x in [value, *others] if x is not None]
        results.append(
            {
                "sixbar": name,
                "nominal_deviation_deg": math.degrees(max(f.deviations)),
                "toleranced_deviation_deg": None if value is None else math.degrees(value),
                "seconds_per_candidate": best,
                "percentile_spread_over_seeds_deg": (max(finite) - min(finite)) if finite else None,
            }
        )
        click.echo(
            f"{name}: {best * 1e3:.1f} ms per candidate ({draws} draws); deviation "
            f"{math.degrees(max(f.deviations)):.4f}° nominal, "
            + ("fails" if value is None else f"{math.degrees(value):.4f}°")
            + " toleranced",
            err=True,
        )
    doc = {
        "benchmark": "tolerance",
        "what": "synth.mechanism.tolerance.toleranced_deviation: the 95th percentile of the output deviation over six-bars "
        "made within +-tolerance of every length and fixed-pivot coordinate, simulated as one batch; "
        "spread: max - min of that percentile over seeds",
        "draws": draws,
        "tolerance_cranks": tolerance,
        "target_seconds_per_candidate_at_256": TARGET_S,
        "results": results,
        "platform": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "machine": platform.machine(),
            "cpus": os.cpu_count(),
        },
    }
    click.echo(json.dumps(doc, indent=1))
