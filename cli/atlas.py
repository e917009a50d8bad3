"""``dwell atlas build`` and ``dwell atlas info``.

The atlas is ``--db PATH|URL``: an SQLite file path (default ``atlas.sqlite`` in the current
folder, or ``$DWELL_ATLAS``) or any SQLAlchemy URL (``postgresql://…``). Heavy imports (SQLAlchemy,
scipy, tqdm) happen inside the commands: ``dwell --help`` loads this module.
"""

from __future__ import annotations

import json
from typing import Any

import click

from atlas.pool import MAX_WORKERS, default_workers
from atlas.sweep import PRESETS, SAMPLES_RANGE, SHARD_SIZE_RANGE, SWEEP_BYTES_PER_SAMPLE
from cli.budget import check_memory
from cli.options import PROPORTION, RAYS, SEARCH_STEP_DEG, SEED, Bounded, Count, check_engine, db_option, engine_options

__all__ = ["atlas", "sweep_spec_from_options"]


@click.group("atlas")
def atlas() -> None:
    """Build and inspect atlases of nearly straight and circular coupler-curve segments."""


def parse_range(value: tuple[float, float] | None) -> tuple[float, float] | None:
    return None if value is None or len(value) == 0 else (float(value[0]), float(value[1]))


def sweep_spec_from_options(preset: str, overrides: dict[str, Any]):  # -> atlas.SweepSpec
    """The preset ``preset`` with the given overrides (None values are left out).

    Raises ``SweepSpecError`` (a ValueError, exit 2) naming the bad field or preset. A spec
    with overrides is named ``<preset>+custom`` (the name does not enter the spec digest).
    """
    from atlas.sweep import PRESETS, SweepSpecError

    if preset not in PRESETS:
        raise SweepSpecError(f"unknown preset {preset!r} (choose from {', '.join(sorted(PRESETS))})")
    changes = {k: v for k, v in overrides.items() if v is not None}
    spec = PRESETS[preset]
    if not changes:
        return spec
    return spec.replace(name=f"{preset}+custom", **changes)


def parse_tolerances(text: str | None) -> tuple[float, ...] | None:
    from atlas.sweep import SweepSpecError

    if text is None:
        return None
    try:
        return tuple(float(t) for t in text.split(","))
    except ValueError:
        raise SweepSpecError(f"--tolerances must be comma-separated numbers (crank lengths), got {text!r}") from None


@atlas.command("build")
@db_option()
@click.option(
    "--preset",
    type=click.Choice(sorted(PRESETS)),
    default="demo",
    show_default=True,
    help="Named sweep: demo (seconds), standard (~20 000 linkages), large (> 1 000 000).",
)
@click.option(
    "--samples",
    type=Count(*SAMPLES_RANGE, "Sobol points"),
    default=None,
    help="Sobol points drawn, before the crank-rocker filter.",
)
@click.option("--seed", type=SEED, default=None, help="Scrambling seed of the sweep.")
@click.option(
    "--b",
    "b_range",
    nargs=2,
    type=PROPORTION,
    default=None,
    metavar="LOW HIGH",
    help="Coupler length range (crank = 1).",
)
@click.option(
    "--c",
    "c_range",
    nargs=2,
    type=PROPORTION,
    default=None,
    metavar="LOW HIGH",
    help="Rocker length range (crank = 1).",
)
@click.option(
    "--d",
    "d_range",
    nargs=2,
    type=PROPORTION,
    default=None,
    metavar="LOW HIGH",
    help="Ground length range (crank = 1).",
)
@click.option(
    "--crank-step", type=SEARCH_STEP_DEG, default=None, metavar="DEG", help="Crank-angle step of the candidate search."
)
@click.option("--rays", type=RAYS, default=None, help="Scan rays through the pole per crank step.")
@click.option("--tolerances", default=None, metavar="T1,T2,..", help="Band half-widths (crank lengths), increasing.")
@click.option(
    "--min-dwell",
    type=Bounded(0.0, 360.0, "a dwell in degrees", low_open=True, high_open=True),
    default=None,
    metavar="DEG",
    help="Shortest dwell kept.",
)
@click.option(
    "--shard-size",
    type=Count(*SHARD_SIZE_RANGE, "proportions per shard"),
    default=None,
    help="Proportions per shard (unit of work, commit and resume).",
)
@click.option("--all-linkages", is_flag=True, help="Keep every proportion, not only crank-rockers.")
@click.option(
    "--workers",
    type=click.IntRange(1, MAX_WORKERS),
    default=None,
    help=f"Worker processes of the local engine (default: all CPUs, here {default_workers()}); "
    "ignored with --engine dask, where the cluster's workers decide.",
)
@engine_options("shards", "The database is written by this process either way.")
@click.option(
    "--replace",
    is_flag=True,
    help="Delete what the atlas holds (any sweep) and build from scratch; needed for a different sweep.",
)
@click.option("--progress/--no-progress", default=None, help="Progress bar on stderr (default: if it is a terminal).")
def build(
    db,
    preset,
    samples,
    seed,
    b_range,
    c_range,
    d_range,
    crank_step,
    rays,
    tolerances,
    min_dwell,
    shard_size,
    all_linkages,
    workers,
    engine,
    scheduler,
    replace,
    progress,
):
    """Build an atlas, or resume an interrupted build of the same sweep.

    Ctrl-C or a kill loses nothing that was committed: run the same command again to resume
    (with either engine); the result is identical to an uninterrupted build.
    """
    from atlas.build import build_atlas
    from cli.progress import BuildBar

    check_engine(engine, scheduler)
    spec = sweep_spec_from_options(
        preset,
        {
            "samples": samples,
            "seed": seed,
            "b": parse_range(b_range),
            "c": parse_range(c_range),
            "d": parse_range(d_range),
            "crank_step_deg": crank_step,
            "rays": rays,
            "tolerances": parse_tolerances(tolerances),
            "min_dwell_deg": min_dwell,
            "shard_size": shard_size,
            "crank_rockers_only": False if all_linkages else None,
        },
    )
    check_memory(
        spec.samples * SWEEP_BYTES_PER_SAMPLE,
        f"drawing {spec.samples:,} Sobol points",
        "lower --samples (the large preset draws 2 097 152)",
    )
    with BuildBar(progress) as bar:
        if engine == "local":
            summary = build_atlas(
                db, spec, workers=workers or default_workers(), replace=replace, on_shard=bar, log=_log
            )
        else:
            summary = _build_on_dask(db, spec, scheduler, replace=replace, on_shard=bar)
    click.echo(summary.line())


def _log(msg: str) -> None:
    """A build's one-line notes, on stderr."""
    click.echo(f"dwell: {msg}", err=True)


def _build_on_dask(db: str, spec, scheduler: str, *, replace: bool, on_shard):  # -> BuildSummary
    """``build_atlas`` with the dask engine. The scheduler is reached before the atlas is
    opened, so a bad address writes nothing; cluster problems are one line, exit 2."""
    from atlas.build import build_atlas
    from atlas.dask_engine import ClusterError, DaskRunner

    try:
        with DaskRunner.connect(scheduler, log=_log) as runner:
            return build_atlas(db, spec, runner=runner, replace=replace, on_shard=on_shard, log=_log)
    except ClusterError as exc:
        raise click.ClickException(str(exc)) from None


@atlas.command("info")
@db_option()
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
@click.option(
    "--verify",
    is_flag=True,
    help="Also check every row: SQLite's integrity check, rows whose parent is missing, and each complete "
    "build's content digest recomputed against the stored one (reads the whole atlas). A mismatch "
    "is one error line, exit status 2.",
)
def info(db, as_json, verify):
    """What an atlas holds: linkages, segments per kind, dwell-angle coverage, build, digest."""
    from sqlalchemy.exc import DatabaseError

    from db.engine import damaged, open_atlas
    from db.summary import atlas_summary, format_summary, quick_check, verify_atlas

    engine = open_atlas(db, readonly=True, check_structure=False)  # the whole check follows
    try:
        checked = verify_atlas(engine) if verify else None
        broken = None if verify else quick_check(engine)  # --verify runs the full integrity check
        if broken:
            raise damaged(db, broken)
        summary = atlas_summary(engine)
    except DatabaseError as exc:
        # a page found damaged while reading rows: one line naming the atlas
        text = str(getattr(exc, "orig", None) or exc).strip()
        raise damaged(db, text.splitlines()[0] if text else type(exc).__name__) from None
    except ValueError as exc:  # a damaged value the driver could not convert
        raise damaged(db, str(exc).splitlines()[0]) from None
    finally:
        engine.dispose()
    if checked is not None and checked.problems:
        raise damaged(db, "; ".join(checked.problems))
    if as_json:
        doc = summary.to_dict()
        if checked is not None:
            doc["verify"] = checked.to_dict()
        click.echo(json.dumps(doc, indent=2))
    else:
        click.echo(format_summary(summary, db))
        if checked is not None:
            click.echo(checked.line())
