"""``dwell bench tolerance``: the CPU cost of a candidate's toleranced deviation
(:func:`synth.mechanism.tolerance.toleranced_deviation`: ``--draws`` six-bars made within the tolerance,
simulated and measured as one batch) per candidate — min/median/max over ``--repeat`` runs,
the process's CPU time (every thread's), beside the wall time and the whole-turn reference
path's cost and figure — and how far its 95th percentile moves with the seed of the draws
(the estimate's own error). With ``--answers``, the same for every candidate of query
answers (each timed ``--repeat`` times, its median), over all and per answers file.

The six-bars are the demo's best RRR 60°/30° and RPR 45°/40° answers (crank 1); the default
tolerance is 0.05 on a crank of 40 (``--tolerance 0.05 --crank 40``).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from typing import Any

import click
import numpy as np

from cli.bench.machine import machine_facts
from cli.errors import InputError
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
#: Target CPU time per candidate at 256 draws (s), issue 44.
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
@click.option(
    "--answers",
    multiple=True,
    type=click.Path(exists=True, dir_okay=False),
    help="Also every candidate of these `dwell query --json` files: its cost (median of --repeat runs) and "
    "its figure against the whole-turn path's.",
)
@click.option("--repeat", default=9, show_default=True, type=click.IntRange(1, 100), help="Timed runs per six-bar.")
@click.option(
    "--seeds",
    default=5,
    show_default=True,
    type=click.IntRange(1, 50),
    help="Seeds whose percentiles give the estimate's spread.",
)
def tolerance(draws: int, tolerance: float, answers: tuple[str, ...], repeat: int, seeds: int) -> None:
    """CPU cost per candidate of the toleranced deviation, and its spread over seeds (JSON)."""
    from synth.mechanism.figures import sixbar_figures
    from synth.mechanism.tolerance import SEED, clear_of_limits, deviation_draws, toleranced_deviation

    given = _read_answers(answers)
    results = []
    for name, sb, dwell_deg in SIXBARS:
        length = math.radians(dwell_deg)
        f = sixbar_figures(sb, band=math.radians(0.1), dwell_length=length)
        centres = [0.5 * (d.start + d.end) for d in f.dwells]
        value = toleranced_deviation(sb, tolerance, centres, length, draws=draws)  # compiles, warms
        cpu, wall = _timed(lambda: toleranced_deviation(sb, tolerance, centres, length, draws=draws), repeat)
        # the whole-turn path the dwell windows stand in for: its cost and its figure
        turn_cpu, _ = _timed(
            lambda: deviation_draws(sb, tolerance, centres, length, draws=draws, whole_turn=True), max(1, repeat // 3)
        )
        turn = deviation_draws(sb, tolerance, centres, length, draws=draws, whole_turn=True)
        turn_value = float(np.percentile(turn, 95.0)) if np.isfinite(turn).all() else None
        others = [
            toleranced_deviation(sb, tolerance, centres, length, draws=draws, seed=SEED + k) for k in range(1, seeds)
        ]
        finite = [math.degrees(x) for x in [value, *others] if x is not None]
        results.append(
            {
                "sixbar": name,
                "dwell_windows_only": clear_of_limits(sb, tolerance),
                "nominal_deviation_deg": math.degrees(max(f.deviations)),
                "toleranced_deviation_deg": None if value is None else math.degrees(value),
                "whole_turn_toleranced_deviation_deg": None if turn_value is None else math.degrees(turn_value),
                "cpu_ms_per_candidate": _spread(cpu),
                "wall_ms_per_candidate": _spread(wall),
                "whole_turn_cpu_ms_per_candidate": _spread(turn_cpu),
                "percentile_spread_over_seeds_deg": (max(finite) - min(finite)) if finite else None,
            }
        )
        click.echo(
            f"{name}: {np.median(cpu) * 1e3:.2f} ms CPU per candidate (median of {repeat}, {draws} draws; "
            f"whole turn {np.median(turn_cpu) * 1e3:.1f} ms); deviation "
            f"{math.degrees(max(f.deviations)):.4f}° nominal, "
            + ("fails" if value is None else f"{math.degrees(value):.4f}°")
            + " toleranced",
            err=True,
        )
    doc = {
        "benchmark": "tolerance",
        "what": "synth.mechanism.tolerance.toleranced_deviation: the 95th percentile of the output deviation over six-bars "
        "made within +-tolerance of every length and fixed-pivot coordinate, simulated as one batch; "
        "cost: CPU time of the process (every thread) per candidate, min/median/max over the runs; "
        "whole_turn: the same draws simulated over the whole turn (the reference path); "
        "spread: max - min of that percentile over seeds",
        "draws": draws,
        "tolerance_cranks": tolerance,
        "target_cpu_ms_per_candidate_at_256": TARGET_S * 1e3,
        "results": results,
        **({"answers": _answers(given, tolerance, draws, repeat)} if answers else {}),
        "platform": machine_facts(),
    }
    click.echo(json.dumps(doc, indent=1))


def _timed(run: Callable[[], object], repeat: int) -> tuple[list[float], list[float]]:
    """CPU seconds (this process, every thread) and wall seconds of each of ``repeat`` runs."""
    cpu, wall = [], []
    for _ in range(repeat):
        c, w = time.process_time(), time.perf_counter()
        run()
        cpu.append(time.process_time() - c)
        wall.append(time.perf_counter() - w)
    return cpu, wall


def _spread(seconds: list[float]) -> dict[str, float]:
    """min/median/max of ``seconds``, in milliseconds."""
    return {"min": 1e3 * min(seconds), "median": 1e3 * float(np.median(seconds)), "max": 1e3 * max(seconds)}


def _read_answers(paths: tuple[str, ...]) -> list[tuple[str, SixBar, list[float], float]]:
    """Each candidate of the query answers ``paths`` (``dwell query --json``) as (its file,
    six-bar in its file's unit, dwell middles in rad, requested dwell in rad); a file that is
    not one is the user's error, before anything is run."""
    from report.candidate_json import sixbar_from_json

    out = []
    for path in paths:
        try:
            with open(path, encoding="utf-8") as f:
                doc = json.load(f)
            length = math.radians(float(doc["request"]["dwell_deg"]))
            for c in doc["candidates"]:
                centres = [math.radians(float(d["interval_deg"][0]) + 0.5 * float(d["dwell_deg"])) for d in c["dwells"]]
                out.append((path, sixbar_from_json(c), centres, length))
        except (OSError, UnicodeDecodeError, ValueError, KeyError, IndexError, TypeError) as exc:
            raise InputError(
                f"--answers {path!r}: not the JSON of `dwell query --json` ({type(exc).__name__})"
            ) from None
    return out


def _answers(answers: list[tuple[str, SixBar, list[float], float]], tolerance: float, draws: int, repeat: int) -> dict:
    """Each candidate of ``answers`` (:func:`_read_answers`): its toleranced deviation
    (``tolerance`` cranks; its CPU and wall time, each the median of ``repeat`` runs after one
    untimed) against the whole-turn path's (one run's CPU time), summarised over all and per
    file; and each file's candidates in one :func:`~synth.mechanism.tolerance.toleranced_deviations`
    call, as a query takes them (``batch``: CPU and wall time per candidate, the median of
    ``repeat`` runs, and whether its figures are the one-by-one ones)."""
    from synth.mechanism.tolerance import clear_of_limits, deviation_draws, toleranced_deviation

    rows = []
    values = []
    for path, sb, centres, length in answers:
        t = tolerance * sb.a
        value = toleranced_deviation(sb, t, centres, length, draws=draws)
        cpu, wall = _timed(lambda: toleranced_deviation(sb, t, centres, length, draws=draws), repeat)
        turn, turn_seconds = _timed_value(lambda: deviation_draws(sb, t, centres, length, draws=draws, whole_turn=True))
        reference = float(np.percentile(turn, 95.0)) if np.isfinite(turn).all() else None
        both = value is not None and reference is not None
        values.append(value)
        rows.append(
            {
                "file": path,
                "dwell_deg": math.degrees(length),
                "windows": clear_of_limits(sb, t),
                "cpu": float(np.median(cpu)),
                "wall": float(np.median(wall)),
                "turn_cpu": turn_seconds,
                "diff": abs(math.degrees(value - reference)) if both else None,
                "rel": abs(value - reference) / reference if both else None,
            }
        )
    batches = _batches(answers, values, tolerance, draws, repeat)
    files = list(dict.fromkeys(r["file"] for r in rows))
    return {
        **_summary(rows),
        "batch": _batch_summary(list(batches.values())),
        "per_file": [
            {"file": f, **_summary([r for r in rows if r["file"] == f]), "batch": _batch_summary([batches[f]])}
            for f in files
        ],
    }


def _batches(
    answers: list[tuple[str, SixBar, list[float], float]],
    values: list[float | None],
    tolerance: float,
    draws: int,
    repeat: int,
) -> dict[str, tuple[int, float, float, bool]]:
    """Per answers file: (candidates, median CPU s, median wall s of ``repeat`` runs after one
    untimed, whether the figures are ``values``') of one
    :func:`~synth.mechanism.tolerance.toleranced_deviations` call over its candidates (the
    file's crank: its first candidate's)."""
    from synth.mechanism.tolerance import toleranced_deviations

    out = {}
    for path in dict.fromkeys(a[0] for a in answers):
        k = [i for i, a in enumerate(answers) if a[0] == path]
        sixbars, centres = [answers[i][1] for i in k], [answers[i][2] for i in k]
        t, length = tolerance * sixbars[0].a, answers[k[0]][3]
        got = toleranced_deviations(sixbars, t, centres, length, draws=draws)
        cpu, wall = _timed(lambda: toleranced_deviations(sixbars, t, centres, length, draws=draws), repeat)
        out[path] = (len(k), float(np.median(cpu)), float(np.median(wall)), got == [values[i] for i in k])
    return out


def _batch_summary(batches: list[tuple[int, float, float, bool]]) -> dict:
    """CPU and wall ms per candidate over :func:`_batches`' files, and whether every figure is
    the one-by-one one."""
    n = sum(b[0] for b in batches)
    return {
        "cpu_ms_per_candidate": 1e3 * sum(b[1] for b in batches) / n,
        "wall_ms_per_candidate": 1e3 * sum(b[2] for b in batches) / n,
        "same_figures": all(b[3] for b in batches),
    }


def _summary(rows: list[dict]) -> dict:
    """The figures of :func:`_answers` over ``rows``."""
    diff = [r["diff"] for r in rows if r["diff"] is not None]
    rel = [r["rel"] for r in rows if r["rel"] is not None]
    return {
        "candidates": len(rows),
        "dwell_deg": sorted({round(r["dwell_deg"], 6) for r in rows}),
        "dwell_windows_only": sum(r["windows"] for r in rows),
        "largest_difference_deg": max(diff, default=None),
        "median_difference_deg": float(np.median(diff)) if diff else None,
        "largest_relative_difference": max(rel, default=None),
        "cpu_ms_per_candidate": _spread([r["cpu"] for r in rows]) if rows else None,
        "wall_ms_per_candidate": _spread([r["wall"] for r in rows]) if rows else None,
        "whole_turn_cpu_ms_per_candidate": _spread([r["turn_cpu"] for r in rows]) if rows else None,
    }


def _timed_value(run: Callable[[], Any]) -> tuple[Any, float]:
    """``run()``'s value and its CPU seconds (this process, every thread)."""
    c = time.process_time()
    value = run()
    return value, time.process_time() - c
