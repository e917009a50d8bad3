"""``dwell demo``: the main job on the embedded defaults.

Builds (or reuses) the ``demo`` atlas in a local SQLite file, answers one RRR request, one RPR
request and one double-dwell request, prints their best candidates and writes a report for
each (JSON, CSV, plots, drawings, DXF and an animated HTML page).
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path

import click

from atlas.pool import MAX_WORKERS
from cli.options import db_option, probe_folder
from cli.progress import Progress

#: The demo's requests, as the ``dwell query`` options a user would type.
DEMO_REQUESTS = {
    # the demo sweep is small: its RRR answers need rockers up to 20 cranks long
    "rrr": {"dwell": 60.0, "swing": 30.0, "output": "rrr", "max_link_ratio": 20.0},
    "rpr": {"dwell": 45.0, "swing": 40.0, "output": "rpr"},
    # 50°: the demo atlas's 30° double dwells all run the slider over its own pivot (--min-arm).
    # Its 50° ± 5° double dwells swing 5°–25° or 140°–160° (a slot pivot near the coupler
    # curve, peak output accelerations of thousands of rad/s² at 60 rpm): two rests 12° ± 2°
    # apart is the designer's request.
    "double": {"dwell": 50.0, "dwell_tol": 5.0, "swing": 12.0, "swing_tol": 2.0, "dwells": 2, "output": "rpr"},
}
TOP = 3


@click.command("demo")
@click.option(
    "--out",
    "out_dir",
    default="dwell-out",
    show_default=True,
    type=click.Path(file_okay=False),
    help="Folder for the reports (one sub-folder per request).",
)
@db_option(
    dest="target",
    default=None,
    envvar=None,
    help="Atlas to build or reuse [default: OUT/demo-atlas.sqlite]. $DWELL_ATLAS is not read here: the "
    "demo builds its own small atlas and must not write into yours.",
)
@click.option(
    "--workers",
    type=click.IntRange(1, MAX_WORKERS),
    default=None,
    help="Processes of the atlas build and of the reports' drawings [default: all CPUs].",
)
def demo(out_dir: str, target: str | None, workers: int | None) -> None:
    """Build the demo atlas, answer an RRR, an RPR and a double-dwell request, write reports."""
    from report.folder import check_report_folder

    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise click.BadParameter(f"{out_dir!r} exists and is not a folder", param_hint="--out")
    probe_folder(out, "--out")
    for name in DEMO_REQUESTS:  # report folders holding the user's own files: refused before the build
        check_report_folder(out / name, "--out")
    made = [p for p in (out, *out.parents) if not p.exists()]  # what mkdir makes, innermost first
    out.mkdir(parents=True, exist_ok=True)
    target = target or str(out / "demo-atlas.sqlite")
    # on a terminal a line once a part runs past a second; in a log a status line every 10 s
    with Progress("demo", log=True) as progress:
        _demo(out, made, target, workers, progress)


def _demo(out: Path, made: list[Path], target: str, workers: int | None, progress: Progress) -> None:
    """Build the atlas ``target``, answer the requests, write their reports under ``out``
    (``made``: the folders made for it, removed if the build is refused)."""
    from atlas.build import build_atlas
    from atlas.sweep import PRESETS
    from cli.progress import BuildBar
    from cli.query import answer, no_match_message, table
    from cli.report_pool import reports_pool
    from cli.shown_ids import remember_shown, report_settings
    from db.engine import display_target, open_atlas
    from report.export import write_report
    from synth.query.candidates import Request

    start = time.perf_counter()
    shown = display_target(target)  # command lines below never show a URL's password
    click.echo(f"$ dwell atlas build --db {shown} --preset demo")
    try:
        with BuildBar(progress=progress) as bar:
            summary = build_atlas(target, PRESETS["demo"], workers=workers or os.cpu_count() or 1, on_shard=bar)
    except BaseException:
        # a refused --db (or Ctrl-C before the first shard) leaves no empty folders behind
        for folder in made:
            try:
                folder.rmdir()
            except OSError:  # not empty: the interrupted atlas is in it, to resume
                break
        raise
    click.echo(
        f"atlas: {summary.linkages} linkages, {sum(summary.segments.values())} segments "
        f"({time.perf_counter() - start:.1f} s)"
    )
    engine = open_atlas(target, readonly=True)
    written = []
    try:
        # the three reports' candidates are drawn on one set of worker processes, started once
        with reports_pool(TOP * len(DEMO_REQUESTS), workers) as draw:
            for name, opts in DEMO_REQUESTS.items():
                args = " ".join(
                    f"--{k.replace('_', '-')} {v:g}" if isinstance(v, float) else f"--{k.replace('_', '-')} {v}"
                    for k, v in opts.items()
                )
                click.echo(f"\n$ dwell query --db {shown} {args} --top {TOP}")
                request = Request.from_degrees(**opts, top=TOP)
                progress.stage(f"answering the {name} request")
                result = answer(engine, request)
                if not result.candidates:
                    click.echo(no_match_message(result))
                    continue
                progress.stage("")  # the terminal's line ends before the table
                click.echo(table(result))
                remember_shown(result.candidates, report_settings(result.request, "mm"))
                best = result.candidates[0]
                dwell = " and ".join(f"{math.degrees(d.angle):.2f}°" for d in best.figures.dwells[: request.dwells])
                click.echo(
                    f"best: {best.id}: {best.sixbar.dyad.kind} output, dwell {dwell}, "
                    f"swing {math.degrees(best.figures.swing):.2f}°"
                )
                folder = out / name
                write_report(
                    result.candidates,
                    request,
                    folder,
                    option="--out",
                    on_candidate=progress.counter(f"writing the {name} report", "candidates"),
                    map_candidates=draw,
                )
                progress.stage("")
                written.append(folder / "index.html")
    finally:
        engine.dispose()
    click.echo(f"\nreports: {', '.join(str(p) for p in written)} ({time.perf_counter() - start:.1f} s in all)")
