"""``dwell bench query``: latency of ``dwell query`` on a fixed set of requests.

Every request of :data:`REQUESTS` is answered ``--repeat`` times by :func:`cli.query.answer`
— the whole query: indexed selection, dyad fitting, exact simulation of every fitted six-bar,
filtering and ranking — against one open atlas (as a server or a notebook would hold it; the
``dwell`` process start-up, about half a second of imports, is not part of a query). One
warm-up query runs first and is not counted. Reported: per request the median and worst
time, where the time goes (select, fit, simulate, rank, refine), how many segments were fitted
and six-bars simulated (and refined), and the best candidate; over all runs p50, p95 and max
against the floor (p95 ≤ 1500 ms with refinement, issue #13 item 7) and the goal (500 ms).
Every request is also answered ``--repeat`` times without refinement (``--no-refine``),
reported under ``without_refine`` against that query's floor (p95 ≤ 100 ms, issue #13 item 7) and
goal (50 ms, the floor of issue #16); ``--no-compare`` skips it. JSON on stdout; ``--plot FILE`` draws the per-request
breakdown (PNG).

The figures are meant for the ``standard`` atlas (``dwell atlas build --preset standard``);
any atlas is accepted and its preset is named in the output.
"""

from __future__ import annotations

import json
import math
import statistics
import time
from dataclasses import dataclass
from pathlib import Path

import click
import numpy as np

from cli.bench.machine import machine_facts
from cli.budget import check_time
from cli.options import db_option, writable_file

FLOOR_MS = 1500.0  # p95 per request with refinement, --top 10 (issue #13 item 7)
GOAL_MS = 500.0
PLAIN_FLOOR_MS = 100.0  # p95 per request without refinement, --top 10 (issue #13 item 7)
PLAIN_GOAL_MS = 50.0
STAGES = ("select", "fit", "simulate", "reseat", "rank", "refine")


@dataclass(frozen=True, slots=True)
class BenchRequest:
    """One fixed request, in the command's units (degrees)."""

    label: str
    dwell: float
    swing: float | None
    output: str = "any"
    dwells: int = 1
    dwell_tol: float = 2.0
    min_transmission: float = 30.0
    max_link_ratio: float = 10.0


#: The fixed request set: both output types over short to long dwells and small to large
#: swings, both together, two double dwells, and tighter constraints.
REQUESTS: tuple[BenchRequest, ...] = (
    BenchRequest("rpr 30/20", 30, 20, "rpr"),
    BenchRequest("rpr 45/40", 45, 40, "rpr"),
    BenchRequest("rpr 60/30", 60, 30, "rpr"),
    BenchRequest("rpr 90/45", 90, 45, "rpr"),
    BenchRequest("rpr 120/60", 120, 60, "rpr"),
    BenchRequest("rrr 30/20", 30, 20, "rrr"),
    BenchRequest("rrr 45/40", 45, 40, "rrr"),
    BenchRequest("rrr 60/30", 60, 30, "rrr"),
    BenchRequest("rrr 90/45", 90, 45, "rrr"),
    BenchRequest("rrr 120/30", 120, 30, "rrr"),
    BenchRequest("any 60/30", 60, 30, "any"),
    BenchRequest("any 75/50", 75, 50, "any"),
    BenchRequest("double 30±5/20", 30, 20, "rpr", dwells=2, dwell_tol=5),
    BenchRequest("double 60±5/20", 60, 20, "rpr", dwells=2, dwell_tol=5),
    BenchRequest("rrr 60/30 μ≥45°", 60, 30, "rrr", min_transmission=45),
    BenchRequest("any 45/40 ratio≤5", 45, 40, "any", max_link_ratio=5),
)


def _request(r: BenchRequest, top: int, refine: bool = True):
    from synth.query.candidates import Request

    return Request.from_degrees(
        dwell=r.dwell,
        dwell_tol=r.dwell_tol,
        swing=r.swing,
        output=r.output,
        dwells=r.dwells,
        min_transmission=r.min_transmission,
        max_link_ratio=r.max_link_ratio,
        top=top,
        refine=refine,
    )


def atlas_facts(engine) -> dict:
    from db.spec import last_spec
    from db.summary import row_counts

    linkages, segments, dwells = row_counts(engine)
    spec = last_spec(engine)
    preset = spec.get("name") if spec else None
    return {"preset": preset, "linkages": linkages, "segments": segments, "dwells": dwells}


def _percentile(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values), q)) if values else 0.0


@click.command("query")
@db_option()
@click.option("--repeat", type=click.IntRange(1, 1000), default=5, show_default=True, help="Runs of every request.")
@click.option("--top", type=click.IntRange(1, 1000), default=10, show_default=True, help="Candidates per query.")
@click.option(
    "--plot",
    type=click.Path(dir_okay=False),
    callback=writable_file(".png"),
    default=None,
    help="Write the per-request latency breakdown (PNG).",
)
@click.option(
    "--compare/--no-compare",
    default=True,
    show_default=True,
    help="Also time every request without refinement (--no-refine).",
)
def query(db, repeat, top, plot, compare):
    """Query latency: a fixed set of requests against an atlas, p50/p95 and where the time goes."""
    from cli.query import answer
    from db.engine import display_target, open_atlas
    from report.candidate_json import request_json

    engine = open_atlas(db, readonly=True)
    try:
        atlas = atlas_facts(engine)
        answer(engine, _request(REQUESTS[0], top))  # warm-up: imports, SQLite page cache
        # one timed answer of the first request, then the whole run's estimate against the budget
        t0 = time.perf_counter()
        answer(engine, _request(REQUESTS[0], top))
        check_time(
            (time.perf_counter() - t0) * repeat * len(REQUESTS) * (1.2 if compare else 1.0),
            f"--repeat {repeat} × {len(REQUESTS)} requests (--top {top}) on this atlas",
            "lower --repeat or --top",
        )
        if atlas["preset"] != "standard":
            click.echo(
                f"dwell: note: {display_target(db)} holds the {atlas['preset']!r} sweep; the floor is set for 'standard'",
                err=True,
            )
        rows, every, plain_every = [], [], []
        for r in REQUESTS:
            request = _request(r, top)
            runs = []
            for _ in range(repeat):
                t0 = time.perf_counter()
                result = answer(engine, request)
                runs.append((time.perf_counter() - t0, result))
            ms = [1000 * t for t, _ in runs]
            every += ms
            plain = []
            if compare:
                plain_request = _request(r, top, refine=False)
                for _ in range(repeat):
                    t0 = time.perf_counter()
                    plain_result = answer(engine, plain_request)
                    plain.append(1000 * (time.perf_counter() - t0))
                plain_every += plain
            result = runs[-1][1]
            best = result.candidates[0] if result.candidates else None
            rows.append(
                {
                    "label": r.label,
                    "request": request_json(result.request),
                    "ms_median": round(statistics.median(ms), 2),
                    "ms_max": round(max(ms), 2),
                    "ms_by_stage": {
                        s: round(statistics.median(1000 * res.seconds.get(s, 0.0) for _, res in runs), 2)
                        for s in STAGES
                    },
                    "ms_median_without_refine": round(statistics.median(plain), 2) if plain else None,
                    "candidates_without_refine": len(plain_result.candidates) if plain else None,
                    "segments_fitted": result.considered,
                    "sixbars_simulated": result.simulated,
                    "sixbars_refined": result.refined[0],
                    "sixbars_improved": result.refined[1],
                    "candidates": len(result.candidates),
                    "best": None
                    if best is None
                    else {
                        "id": best.id,
                        "dwell_deg": [round(math.degrees(d.angle), 3) for d in best.figures.dwells[: r.dwells]],
                        "swing_deg": round(math.degrees(best.figures.swing), 3),
                        "output_deviation_deg": round(math.degrees(max(best.figures.deviations)), 4)
                        if best.figures.deviations
                        else None,
                    },
                }
            )
    finally:
        engine.dispose()
    p95 = _percentile(every, 95)
    report = {
        "benchmark": "query",
        "atlas": atlas,
        "top": top,
        "repeat": repeat,
        "queries": len(every),
        "ms_p50": round(_percentile(every, 50), 2),
        "ms_p95": round(p95, 2),
        "ms_max": round(max(every), 2),
        "floor_ms_p95": FLOOR_MS,
        "goal_ms_p95": GOAL_MS,
        "meets_floor": bool(p95 <= FLOOR_MS),
        "meets_goal": bool(p95 <= GOAL_MS),
        "ms_by_stage_total": {s: round(sum(r["ms_by_stage"][s] for r in rows), 2) for s in STAGES},
        "without_refine": None
        if not compare
        else {
            "ms_p50": round(_percentile(plain_every, 50), 2),
            "ms_p95": round(_percentile(plain_every, 95), 2),
            "ms_max": round(max(plain_every), 2),
            "floor_ms_p95": PLAIN_FLOOR_MS,
            "goal_ms_p95": PLAIN_GOAL_MS,
            "meets_floor": bool(_percentile(plain_every, 95) <= PLAIN_FLOOR_MS),
        },
        "requests": rows,
        "machine": machine_facts(),
    }
    click.echo(json.dumps(report, indent=2, allow_nan=False))
    plain_note = (
        ""
        if not compare
        else (
            f"; without refinement p50 {report['without_refine']['ms_p50']:.1f} ms, p95 {report['without_refine']['ms_p95']:.1f} ms "
            f"(floor {PLAIN_FLOOR_MS:g} ms: {'met' if report['without_refine']['meets_floor'] else 'NOT met'})"
        )
    )
    click.echo(
        f"dwell bench query: {len(every)} queries with refinement, p50 {report['ms_p50']:.1f} ms, p95 {p95:.1f} ms "
        f"(floor {FLOOR_MS:g} ms: {'met' if report['meets_floor'] else 'NOT met'})" + plain_note,
        err=True,
    )
    if plot:
        _plot(report, Path(plot))


def _plot(report: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = report["requests"]
    fig, ax = plt.subplots(figsize=(8, 0.32 * len(rows) + 1.8), constrained_layout=True)
    y = np.arange(len(rows))
    left = np.zeros(len(rows))
    for stage in STAGES:
        width = np.array([r["ms_by_stage"][stage] for r in rows])
        ax.barh(y, width, left=left, label=stage)
        left += width
    ax.axvline(
        report["floor_ms_p95"], color="crimson", ls="--", lw=1, label=f"floor (p95) {report['floor_ms_p95']:g} ms"
    )
    ax.axvline(report["goal_ms_p95"], color="seagreen", ls=":", lw=1, label=f"goal {report['goal_ms_p95']:g} ms")
    ax.set_yticks(y, [f"{r['label']} ({r['candidates']})" for r in rows], fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("median milliseconds per query (candidates returned in brackets)")
    atlas = report["atlas"]
    ax.set_title(
        f"dwell query latency: {atlas['linkages']} linkages ({atlas['preset']}), top {report['top']}; "
        f"p95 {report['ms_p95']:.0f} ms",
        fontsize=10,
    )
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(True, axis="x", alpha=0.3)
    fig.savefig(path, dpi=120)
    plt.close(fig)
