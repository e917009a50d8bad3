"""``dwell bench coverage``: which requests an atlas answers, over the grid of issues #13 and #41.

Single dwells (RPR and RRR): dwell {10, 20, 30, 45, 60, 75, 90, 105, 120, 150, 180}° × swing
{10, 20, 30, 45, 60, 90}° (issue #41's grid); double dwells (RPR, ``--dwells 2 --dwell-tol 5``):
dwell {10, 20, 30, 45, 60, 75, 90, 120}° × swing {20, 45}° (two rests with motion between them);
``--dwell`` keeps some rows. Every cell is one :func:`synth.query.answer` with the query's default
constraints and ``--top``, against one open atlas (as ``dwell bench query``). Reported per cell:
the candidates found, the best output deviation over the requested dwell (degrees), the
constraint a no-match names and the time; per family the cells with ≥ 1 and ≥ 3 candidates. A
table on stdout, or ``--json``;
``--plot FILE.png`` draws the grids as heat maps. ``--complete`` answers every cell with the
complete search and measures the default (sampled) query against it: the share of the
complete answer's coupler curves the sample finds. The cells of one swing (and family) read
the atlas once and share its fitted dyads (:func:`synth.query.search_many`), on ``--workers``
processes; each cell's time is its share of that walk plus its own ranking.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import click

from atlas.pool import default_workers
from cli.options import Bounded, db_option, writable_file
from cli.query import batch_map, workers_option

SINGLE_DWELLS = (10, 20, 30, 45, 60, 75, 90, 105, 120, 150, 180)
SWINGS = (10, 20, 30, 45, 60, 90)
DOUBLE_DWELLS = (10, 20, 30, 45, 60, 75, 90, 120)
DOUBLE_SWINGS = (20, 45)
DOUBLE_TOL = 5.0
FAMILIES = ("rpr", "rrr", "double")


@dataclass(frozen=True, slots=True)
class Cell:
    """One request of the grid, in the command's units (degrees)."""

    family: str
    dwell: float
    swing: float | None

    def request(self, top: int, refine: bool = True, complete: bool = False):
        from synth.query.candidates import Request

        if self.family == "double":
            return Request.from_degrees(
                dwell=self.dwell,
                dwell_tol=DOUBLE_TOL,
                swing=self.swing,
                output="rpr",
                dwells=2,
                top=top,
                refine=refine,
                complete=complete,
            )
        return Request.from_degrees(
            dwell=self.dwell, swing=self.swing, output=self.family, top=top, refine=refine, complete=complete
        )


def cells(families: tuple[str, ...] = FAMILIES, dwells: tuple[float, ...] = ()) -> list[Cell]:
    """The grid of ``families``, family by family, dwell-major (only the rows of ``dwells``, °,
    if any are given)."""
    out = [Cell(fam, d, s) for fam in ("rpr", "rrr") if fam in families for d in SINGLE_DWELLS for s in SWINGS]
    out += [Cell("double", d, s) for d in DOUBLE_DWELLS for s in DOUBLE_SWINGS if "double" in families]
    return [c for c in out if not dwells or c.dwell in dwells]


def _row(cell: Cell, result, seconds: float, top: int) -> dict:
    shown = result.candidates[:top]
    devs = [max(c.figures.deviations) for c in shown if c.figures.deviations]
    return {
        "family": cell.family,
        "dwell_deg": cell.dwell,
        "swing_deg": cell.swing,
        "candidates": len(shown),
        "best_deviation_deg": None if not devs else round(math.degrees(min(devs)), 5),
        "best": shown[0].id if shown else None,
        "failed": None if result.no_match is None else result.no_match.failed,
        # the one constraint in the way, its best figure and the request's (synth.query.NoMatch.reach)
        "in_the_way": None
        if result.no_match is None or result.no_match.reach is None
        else [result.no_match.reach[0], round(result.no_match.reach[1], 4), round(result.no_match.reach[2], 4)],
        # a cell answered short of FILL: the one constraint in the way of more (QueryResult.short_of)
        "short_of": None
        if not shown or not result.short_of
        else [[k, round(best, 4), round(limit, 4)] for _, k, best, limit in result.short_of],
        "refined": sum(c.refined_from is not None for c in shown),
        "ms": round(1000 * seconds, 1),
    }


def _curve(c) -> tuple:
    """A candidate's coupler curve and output type, the same for both mirror images (the two
    assembly branches): both answers keep one six-bar per segment and of a mirror pair, not
    always at the same tolerance level or fit slot."""
    sb = c.sixbar
    return (round(sb.b, 6), round(sb.c, 6), round(sb.d, 6), round(sb.u, 3), round(abs(sb.v), 3), sb.dyad.kind)


def _recall(cell: Cell, complete, source) -> dict:
    """What the sampled query finds of the complete answer ``complete`` (unrefined, one
    six-bar per coupler curve and output type): how many curves each answer holds, and the
    share of the complete ones the sample holds (None when there are none)."""
    from synth.query import answer

    sampled = answer(cell.request(1000, refine=False), source)
    every = {_curve(c) for c in complete.candidates}
    found = {_curve(c) for c in sampled.candidates} & every
    return {
        "complete": len(every),
        "sampled": len(sampled.candidates),
        "recall": None if not every else round(len(found) / len(every), 4),
    }


def summary(rows: list[dict]) -> dict:
    """Per family: cells, cells with ≥ 1 and with ≥ 3 candidates; after a complete search,
    the six-bars it found and the share of them the sampled query finds (pooled)."""
    out = {}
    for fam in dict.fromkeys(r["family"] for r in rows):
        mine = [r for r in rows if r["family"] == fam]
        out[fam] = {
            "cells": len(mine),
            "answered": sum(r["candidates"] >= 1 for r in mine),
            "three_or_more": sum(r["candidates"] >= 3 for r in mine),
        }
        if mine and "recall" in mine[0]:
            every = sum(r["complete"] for r in mine)
            found = sum(round(r["recall"] * r["complete"]) for r in mine if r["recall"] is not None)
            out[fam].update(complete=every, recall=None if not every else round(found / every, 4))
    return out


@click.command("coverage")
@db_option()
@click.option("--top", type=click.IntRange(1, 1000), default=10, show_default=True, help="Candidates per query.")
@click.option(
    "--refine/--no-refine",
    default=True,
    show_default=True,
    help="Refine the candidates (and the nearest misses) as `dwell query` does.",
)
@click.option(
    "--family",
    "families",
    type=click.Choice(FAMILIES),
    multiple=True,
    help="Only this family's cells (repeat for several; default: all three).",
)
@click.option(
    "--complete",
    is_flag=True,
    help="Answer every cell with the complete search (`dwell query --complete`, unrefined, all its "
    "six-bars kept) and report, per cell, the share of them the default sampled query finds.",
)
@click.option(
    "--dwell",
    "dwells",
    type=Bounded(0.0, 360.0, "a dwell in degrees", low_open=True, high_open=True),
    multiple=True,
    help="Only the grid's rows of this dwell (degrees; repeat for several; default: every row).",
)
@workers_option
@click.option("--json", "as_json", is_flag=True, help="JSON on stdout instead of a table.")
@click.option(
    "--plot",
    type=click.Path(dir_okay=False),
    callback=writable_file(".png"),
    default=None,
    help="Write the grids as heat maps of the candidates found (PNG).",
)
def coverage(db, top, refine, families, complete, dwells, workers, as_json, plot):
    """Coverage of the dwell × swing grid (RPR, RRR) and the double-dwell row: candidates, best deviation, time."""
    from cli.bench.query import atlas_facts
    from cli.progress import SearchBar
    from db.engine import open_atlas
    from db.queries import AtlasSource
    from synth.query import answer, fit_key, search_many

    grid = cells(tuple(families) or FAMILIES, tuple(dwells))
    if not grid:
        raise click.BadParameter(
            f"no row of the grid has a dwell of {', '.join(f'{d:g}' for d in dwells)}°", param_hint="'--dwell'"
        )
    engine = open_atlas(db, readonly=True)
    try:
        atlas = atlas_facts(engine)
        source = AtlasSource(engine)
        rows = []
        start = time.perf_counter()
        if complete:
            # the complete search keeps all its six-bars (unrefined) for the recall; the
            # cells of one swing share one walk of the atlas and its fits, and each is
            # charged an equal share of that time
            requests = [cell.request(1000, False, True) for cell in grid]
            groups: dict[tuple, list[int]] = {}
            for k, request in enumerate(requests):
                groups.setdefault(fit_key(request), []).append(k)
            done: dict[int, dict] = {}
            for members in groups.values():
                t0 = time.perf_counter()
                with SearchBar(None) as bar:
                    found = search_many(
                        [requests[k] for k in members],
                        source,
                        on_progress=bar,
                        map_batches=batch_map(workers or default_workers()),
                    )
                share = (time.perf_counter() - t0) / len(members)
                for k, searched in zip(members, found):
                    t1 = time.perf_counter()
                    result = answer(requests[k], source, searched=searched)
                    done[k] = _row(grid[k], result, share + time.perf_counter() - t1, top)
                    done[k].update(_recall(grid[k], result, source))
            rows = [done[k] for k in range(len(grid))]
        else:
            for cell in grid:
                t0 = time.perf_counter()
                result = answer(cell.request(top, refine), source)
                rows.append(_row(cell, result, time.perf_counter() - t0, top))
        total = time.perf_counter() - start
    finally:
        engine.dispose()
    report = {
        "benchmark": "coverage",
        "atlas": atlas,
        "top": top,
        "refine": refine and not complete,
        "complete": complete,
        "seconds": round(total, 2),
        "summary": summary(rows),
        "cells": rows,
    }
    if as_json:
        click.echo(json.dumps(report, indent=2, allow_nan=False))
    else:
        click.echo(table(report))
    s = report["summary"]
    click.echo(
        "dwell bench coverage: "
        + ", ".join(
            f"{fam} {v['three_or_more']}/{v['cells']} cells with ≥ 3 ({v['answered']} with ≥ 1"
            + (
                ""
                if v.get("recall") is None
                else f"; the sampled query finds {100 * v['recall']:.1f}% of {v['complete']} six-bars"
            )
            + ")"
            for fam, v in s.items()
        )
        + f" in {total:.1f} s",
        err=True,
    )
    if plot:
        _plot(report, Path(plot))


def table(report: dict) -> str:
    """Per family a grid: rows dwell, columns swing, each cell ``candidates/best deviation``;
    then each cell's time."""
    lines = [
        f"coverage of {report['atlas']['preset']} ({report['atlas']['linkages']} linkages), top {report['top']}: "
        "candidates found, best output deviation (°) [ms]"
    ]
    rows = report["cells"]
    for fam in report["summary"]:
        mine = [r for r in rows if r["family"] == fam]
        cols = sorted({r["swing_deg"] for r in mine})
        head = "swing →" if fam != "double" else f"±{DOUBLE_TOL:g}° swing →"
        lines.append("")
        lines.append(f"{fam.upper():<8}{head:>8}" + "".join(f"{f'{c:g}°':>20}" for c in cols))
        for d in sorted({r["dwell_deg"] for r in mine}):
            cells_ = {r["swing_deg"]: r for r in mine if r["dwell_deg"] == d}
            text = []
            for c in cols:
                r = cells_[c]
                dev = "-" if r["best_deviation_deg"] is None else f"{r['best_deviation_deg']:.3f}"
                text.append(f"{r['candidates']:>3}/{dev:<6}[{r['ms']:>5.0f}]")
            lines.append(f"dwell {d:>4g}°     " + "".join(f"{t:>20}" for t in text))
        v = report["summary"][fam]
        lines.append(
            f"{fam}: {v['three_or_more']}/{v['cells']} cells with ≥ 3 candidates, {v['answered']} with ≥ 1"
            + (
                ""
                if v.get("recall") is None
                else f"; the sampled query finds {100 * v['recall']:.1f}% of the {v['complete']} coupler curves"
            )
        )
    return "\n".join(lines)


def _plot(report: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    rows = report["cells"]
    top = report["top"]
    families = list(report["summary"])
    widths = [2.4 if fam == "double" else 6.0 for fam in families]
    fig, axes = plt.subplots(
        1,
        len(families),
        figsize=(12 * sum(widths) / 13.6 + 1.0, 4.2),
        width_ratios=widths,
        constrained_layout=True,
        squeeze=False,
    )
    axes = axes[0]
    for ax, fam in zip(axes, families):
        mine = [r for r in rows if r["family"] == fam]
        dwells = sorted({r["dwell_deg"] for r in mine})
        swings = sorted({r["swing_deg"] for r in mine})
        grid = np.zeros((len(dwells), len(swings)))
        for r in mine:
            grid[dwells.index(r["dwell_deg"]), swings.index(r["swing_deg"])] = r["candidates"]
        im = ax.imshow(grid, cmap="viridis", vmin=0, vmax=top, aspect="auto", origin="lower")
        for i in range(len(dwells)):
            for j in range(len(swings)):
                n = int(grid[i, j])
                ax.text(j, i, str(n), ha="center", va="center", fontsize=8, color="white" if n < 0.6 * top else "black")
        ax.set_yticks(range(len(dwells)), [f"{d:g}°" for d in dwells])
        ax.set_xticks(range(len(swings)), [f"{s:g}°" for s in swings])
        ax.set_xlabel("swing" if fam != "double" else f"swing, two dwells ±{DOUBLE_TOL:g}°")
        v = report["summary"][fam]
        ax.set_title(f"{fam.upper()}: ≥3 in {v['three_or_more']}/{v['cells']}", fontsize=10)
    axes[0].set_ylabel("dwell")
    fig.colorbar(im, ax=axes, shrink=0.8, label=f"candidates (top {top})")
    atlas = report["atlas"]
    fig.suptitle(f"dwell query coverage: {atlas['linkages']} linkages ({atlas['preset']})", fontsize=11)
    fig.savefig(path, dpi=120)
    plt.close(fig)
