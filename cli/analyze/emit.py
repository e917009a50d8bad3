"""How every ``dwell analyze`` subcommand shows its result: table or JSON, plot, drawing."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import click
import numpy as np

from report.drawing import Sketch, draw_sketch
from report.motion_table import MotionTable
from report.plots import plot_motion

#: Crank angles of the motion diagrams [deg]: 1° steps look smooth and cost nothing.
PLOT_STEP_DEG = 1.0


def emit_motion(
    table: MotionTable,
    *,
    as_json: bool,
    plot: Path | None,
    draw: Path | None,
    plot_columns: list[str],
    evaluate: Callable[[np.ndarray], MotionTable],
    sketch: Callable[[], Sketch],
    title: str,
) -> None:
    """Print ``table`` (text or JSON) and write the requested files.

    ``evaluate`` recomputes the table at other crank angles (degrees) for a smooth plot;
    ``sketch`` builds the drawing at the first crank angle. Files are written only after
    everything has been computed, so bad input leaves nothing behind.
    """
    dense = None
    if plot is not None:
        phi = table.columns[0].values
        lo, hi = float(phi.min()), float(phi.max())
        step = float(np.min(np.diff(phi))) if phi.size > 1 else 360.0
        if hi - lo + step >= 360.0 - 1e-9:  # a whole turn (or a single angle): plot the turn
            hi = lo + 360.0
        dense = evaluate(np.arange(lo, hi + PLOT_STEP_DEG / 2, PLOT_STEP_DEG))
    drawing = sketch() if draw is not None else None

    if as_json:
        click.echo(json.dumps(table.to_json(), indent=1, allow_nan=False))
    else:
        click.echo(title)
        for key, value in table.mechanism.items():
            click.echo(f"  {key}: {value}")
        click.echo("")
        click.echo(table.to_text())
        if table.summary:
            click.echo("")
            for key, value in table.summary.items():
                click.echo(f"{key}: {_plain(value)}")
    if dense is not None and plot is not None:
        plot_motion(dense, plot_columns, plot, title=title)
        click.echo(f"wrote {plot}", err=True)
    if drawing is not None and draw is not None:
        draw_sketch(drawing, draw, title=title)
        click.echo(f"wrote {draw}", err=True)


def _plain(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.7g}"
    if isinstance(value, dict):
        return ", ".join(f"{k}={_plain(v)}" for k, v in value.items())
    if isinstance(value, list):
        return "; ".join(_plain(v) for v in value)
    return str(value)
