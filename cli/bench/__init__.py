"""``dwell bench``: speed and accuracy, side by side, as machine-readable JSON."""

from __future__ import annotations

import click

from cli.lazy import LazyGroup

SUBCOMMANDS = {
    "kinematics": "cli.bench.kinematics:kinematics",
    "curvature": "cli.bench.curvature:curvature",
    "stability": "cli.bench.stability:stability",
    "atlas": "cli.bench.atlas:atlas",
    "query": "cli.bench.query:query",
    "faults": "cli.bench.faults:faults",
    "coverage": "cli.bench.coverage:coverage",
    "sixbar": "cli.bench.sixbar:sixbar",
    "tolerance": "cli.bench.tolerance:tolerance",
}


@click.group(cls=LazyGroup, lazy=SUBCOMMANDS)
def bench() -> None:
    """Benchmarks: run time and error side by side (JSON on stdout)."""
