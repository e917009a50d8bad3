"""``dwell analyze``: kinematic analysis of the classic mechanisms."""

from __future__ import annotations

import click

from cli.lazy import LazyGroup

SUBCOMMANDS = {
    "fourbar": "cli.analyze.fourbar:fourbar",
    "slider-crank": "cli.analyze.slider_crank:slider_crank",
    "shaper": "cli.analyze.shaper:shaper",
    "linkage": "cli.analyze.linkage:linkage",
}


@click.group(cls=LazyGroup, lazy=SUBCOMMANDS)
def analyze() -> None:
    """Position, velocity and acceleration of a classic mechanism over crank angles."""
