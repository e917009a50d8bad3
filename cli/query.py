"""``dwell query``: ranked six-bars for a requested dwell, from an atlas.

Options → :class:`~synth.query.candidates.Request` → :func:`synth.query.answer` (the library stage,
reading the atlas through ``db.queries.AtlasSource``) → a table (``synth``'s figures, in
degrees) or JSON. The defaults shown in ``--help`` are the fields of ``Request``.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import click
from click.core import ParameterSource

from atlas.pool import MAX_WORKERS, default_workers
from cli.errors import InputError
from cli.options import (
    AUTO,
    LENGTH,
    RPM,
    SWING_TOL_DEG,
    BandOrAuto,
    Bounded,
    Count,
    check_engine,
    db_option,
    engine_options,
    request_errors,
    units_option,
)
from report.candidate_json import candidate_json, request_json
from report.query_table import legend_lines, short_table
from synth.kinds import OutputKind
from synth.query import FILL, QueryResult, RebuildError
from synth.query.candidates import OUTPUTS, Request
from synth.query.result import REACH_AMONG

if TYPE_CHECKING:
    from atlas.dask_cluster import DaskCluster

__all__ = [
    "BAD_INPUT",
    "FOUND",
    "NONE_FOUND",
    "answer",
    "answer_tightest",
    "band_search_json",
    "no_match_json",
    "no_match_message",
    "query",
    "rebuild",
    "table",
]

_DEFAULTS = {f.name: f.default for f in dataclasses.fields(Request)}


def default_deg(name: str) -> float:
    """The default of the angle field ``name`` of :class:`Request`, in degrees."""
    return round(math.degrees(_DEFAULTS[name]), 9)


def answer(
    engine,
    request: Request,
    *,
    progress: bool | None = False,
    workers: int = 1,
    cluster: DaskCluster | None = None,
    seeded=(),
) -> QueryResult:
    """:func:`synth.query.answer` on the atlas behind ``engine``; with ``progress`` (None: if
    stderr is a terminal) a line on stderr once it runs past a second (a complete search's
    rows as a bar; not a terminal: a complete search's status every 10 s, :mod:`cli.progress`).
    A complete search runs its batches on ``workers`` processes, or on ``cluster`` when given
    (the sampled query in this process). ``seeded``: six-bars that meet ``request`` found
    otherwise (``--band auto``'s), answered with the atlas's."""
    from cli.process import answering
    from cli.progress import Progress, SearchBar
    from db.queries import AtlasSource
    from synth.query import answer as answer_

    with (
        answering(),
        Progress("query", terminal=progress, log=progress is None and request.complete) as shown,
    ):
        shown.stage("answering the request")
        return answer_(
            request,
            AtlasSource(engine),
            on_progress=SearchBar(progress=shown),
            map_batches=batch_map(workers, cluster),
            seeded=seeded,
        )


def batch_map(workers: int, cluster: DaskCluster | None = None):
    """The ``map_batches`` of :func:`synth.query.search`: on ``cluster`` when given
    (:func:`atlas.dask_search.search_map`), else None (this process) for one worker, else a
    pool of ``workers`` processes (:func:`atlas.pool.pool_map`)."""
    if cluster is not None:
        from atlas.dask_search import search_map

        return search_map(cluster)
    if workers <= 1:
        return None
    from atlas.pool import pool_map

    return functools.partial(pool_map, workers=workers, preload=("synth.query",))


#: ``--workers`` of the complete search (``dwell query``, ``dwell bench coverage``).
workers_option = click.option(
    "--workers",
    type=click.IntRange(1, MAX_WORKERS),
    default=None,
    help=f"Worker processes of a complete search and of a --report of four or more candidates (default: all "
    f"CPUs, here {default_workers()}); the sampled query runs in one; a complete search ignores it with --engine "
    "dask, where the cluster's workers decide.",
)


def rebuild(engine, ids: list[str], request: Request):
    """:func:`synth.query.rebuild` on the atlas behind ``engine``; an id that cannot be rebuilt
    is the user's error (one line, exit 2)."""
    from db.queries import AtlasSource
    from synth.query import rebuild as rebuild_

    try:
        return rebuild_(ids, AtlasSource(engine), request)
    except RebuildError as exc:
        raise InputError(str(exc)) from None


def _sixbar_text(sb) -> str:
    """a b c d, P (u, v), D (x, y) and for an RRR L ρ: the whole six-bar on one line."""
    g = lambda x: f"{x:.4g}"  # noqa: E731
    text = f"{g(sb.a)} {g(sb.b)} {g(sb.c)} {g(sb.d)}  P({g(sb.u)}, {g(sb.v)})  D({g(sb.dyad.pivot.real)}, {g(sb.dyad.pivot.imag)})"
    if sb.dyad.kind == OutputKind.RRR:
        text += f"  L {g(sb.dyad.rocker)} ρ {g(sb.dyad.rod)}"
    return text


def _refined_note(result: QueryResult) -> str:
    """``; 6 of 7 refined (0.37 s)`` for the table's head ('' without refinement)."""
    tried, better = result.refined
    moved = (
        (
            f"; {result.reseated} with the output pivot moved off the fitted one "
            f"({result.seconds.get('reseat', 0.0):.2f} s)"
        )
        if result.reseated
        else ""
    )
    if not tried:
        return moved
    seconds = result.seconds.get("refine", 0.0)
    if result.from_misses:
        return f"; nothing in the atlas met the request: {better} of its {tried} nearest misses refined to meet it ({seconds:.2f} s)"
    if result.misses_met:
        return (
            f"{moved}; {better} of {tried} refined, {result.misses_met} of the six-bars near misses refined to meet "
            f"the request ({seconds:.2f} s)"
        )
    return f"{moved}; {better} of {tried} refined ({seconds:.2f} s)"


def _refined_text(c, req: Request) -> str:
    """``44.77→46.27 0.102→0.092``: the (first) dwell and the deviation before → after refinement."""
    before = c.refined_from
    if before is None:
        return "-"
    dwell = lambda f: f"{math.degrees(f.dwells[0].angle):.2f}" if f.dwells else "-"  # noqa: E731
    dev = lambda f: f"{math.degrees(max(f.deviations)):.3f}" if f.deviations else "-"  # noqa: E731
    return f"{dwell(before)}→{dwell(c.figures)} {dev(before)}→{dev(c.figures)}"


def refinement_json(result: QueryResult) -> dict | None:
    """What refinement did (``--json``): six-bars refined, how many came out better, whether
    they were the nearest misses of a request nothing met, how many of the returned six-bars
    are near misses refined to meet it (an answer with fewer than ``synth.query.FILL`` is
    topped up so) and how many have their output pivot moved off the fitted one
    (``synth.query.reseat``); None with --no-refine. (No time: the same request gives the same document;
    ``dwell bench query`` times it.)"""
    if not result.request.refine:
        return None
    tried, better = result.refined
    return {
        "sixbars_refined": tried,
        "sixbars_improved": better,
        "from_nearest_misses": result.from_misses,
        "near_misses_met": result.misses_met,
        "pivots_moved": result.reseated,
    }


def _searched(result: QueryResult) -> str:
    """``120 segments fitted, a sample: …`` or ``52310 segment levels searched: all``."""
    if result.request.complete:
        return f"{result.considered} segment levels searched: all"
    return f"{result.considered} segments fitted, a sample: --complete searches all"


def table(result: QueryResult, units: str = "", *, wide: bool = False) -> str:
    """The ranked candidates as a text table (lengths in the user's unit ``units``) with its
    legend: the default's 120 columns (:func:`report.query_table.short_table`), or with
    ``wide`` every column and the full ids."""
    req = result.request
    head = (
        f"{len(result.candidates)} six-bar(s) for {req.dwells} dwell(s) of {math.degrees(req.dwell):g}° ± "
        f"{math.degrees(req.dwell_tol):g}°"
        + ("" if req.swing is None else f", swing {math.degrees(req.swing):g}°")
        + f" (output band {math.degrees(req.band):g}°; {_searched(result)}, {result.simulated} simulated"
        + _refined_note(result)
        + ")"
    )
    if not wide:
        return short_table(result.candidates, req, head, units)
    lines = [head]
    width = max([26] + [len(c.id) for c in result.candidates])
    tol = f" {'tol dev °':>9}" if req.tolerance > 0 else ""
    cols = (
        f"{'rank':>4}  {'id':<{width}} {'out':<3} {'dwell °':>15} {'dev °':>7}{tol} {'swing °':>8} {'μ4 °':>6} {'μout °':>6} "
        f"{'ratio':>6} {'arm':>7} {'clear':>7} {'α rad/s²':>9}  {'refined: dwell, dev °':<28} six-bar"
    )
    lines.append(cols)
    for c in result.candidates:
        f, sb = c.figures, c.sixbar
        dw = "/".join(f"{math.degrees(d.angle):.2f}" for d in f.dwells[: req.dwells])
        dev = max(f.deviations) if f.deviations else 0.0
        b = f.build
        arm = "-" if b is None or b.arm is None else f"{b.arm:.4g}"
        clear = "-" if b is None else f"{b.clearance:.4g}"
        accel = "-" if b is None else f"{b.dynamics(req.rpm)[1]:.4g}"
        mu_out = "slot" if sb.dyad.kind == OutputKind.RPR else f"{math.degrees(f.transmission_output):.1f}"
        if req.tolerance > 0:
            t = c.toleranced_deviation
            tol = f" {'fails' if t is None else f'{math.degrees(t):.3f}':>9}"
        lines.append(
            f"{c.rank:>4}  {c.id:<{width}} {sb.dyad.kind:<3} {dw:>15} {math.degrees(dev):>7.3f}{tol} {math.degrees(f.swing):>8.2f} "
            f"{math.degrees(f.transmission_fourbar):>6.1f} {mu_out:>6} "
            f"{f.link_ratio:>6.2f} {arm:>7} {clear:>7} {accel:>9}  {_refined_text(c, req):<28} {_sixbar_text(sb)}"
        )
    unit = units or "your unit"
    legend = [("dev", "output deviation over the requested dwell")]
    if req.tolerance > 0:
        legend.append(
            (
                "tol dev",
                f"95th percentile of dev over 256 six-bars made within ±{req.tolerance:g} {unit} "
                "of each length and pivot coordinate, the ranking's deviation (fails: more than 5 % "
                "of them do not assemble)",
            )
        )
    legend += [
        ("μ4, μout", "smallest transmission angles (four-bar, output dyad; a slotted rocker's is 90°)"),
        ("arm", "slider to slot pivot (RPR)"),
        ("clear", "smallest clearance to a fixed pivot"),
        ("α", f"peak output acceleration at {req.rpm:g} rpm"),
        (
            "refined",
            "the dwell and dev before → after refinement (-: kept as retrieved; an id after ~ holds "
            "the refined dimensions)",
        ),
        (
            "six-bar",
            f"a b c d (crank, coupler, rocker, ground), P = coupler point (u, v) in the coupler frame, "
            f"D = output pivot, RRR rocker L and rod ρ; lengths in {unit} (crank = {req.crank:g})",
        ),
    ]
    lines += legend_lines(legend)
    return "\n".join(lines)


def answer_tightest(engine, request: Request, *, workers: int = 1, cluster: DaskCluster | None = None):
    """:func:`synth.query.band_search.answer_tightest` on the atlas behind ``engine``: the band
    measured on the six-bars of the sample at bands down to 1e-4° (and those moved to stiller
    rests), the request answered at the band reached as :func:`answer` answers it (a complete
    search with its progress bar, on ``workers`` or ``cluster``), with the six-bars met there.
    Its steps on one progress line (a terminal; a complete search's status in a log)."""
    from cli.process import answering
    from cli.progress import Progress, SearchBar
    from db.queries import AtlasSource
    from synth.query import answer as answer_
    from synth.query.band_search import answer_tightest as answer_tightest_

    source = AtlasSource(engine)
    with answering(), Progress("query", terminal=None, log=request.complete) as shown:
        return answer_tightest_(
            request,
            source,
            answer_at=lambda r, seeded=(): answer_(
                r, source, on_progress=SearchBar(progress=shown), map_batches=batch_map(workers, cluster), seeded=seeded
            ),
            on_stage=shown.stage,
        )


def tighter_band(engine, result: QueryResult):
    """:func:`synth.query.band_search.tighter_band` for the request of ``result`` (one sampled probe)."""
    from db.queries import AtlasSource
    from synth.query.band_search import tighter_band as tighter_band_

    return tighter_band_(result.request, AtlasSource(engine))


def band_search_json(searched) -> dict:
    """``band_search`` of ``--json`` with ``--band auto``: the band reached (°), whether it holds
    enough six-bars (false: the request's own band, unsearched), the six-bars the search fitted
    and moved to stiller rests, the bands it checked (band °, six-bars met) and per candidate
    its dwells at the band reached and at the reference band."""
    from synth.query.band_search import REFERENCE_BAND

    req = searched.result.request
    return {
        "band_deg": math.degrees(searched.band),
        "settled": searched.settled,
        "pooled": searched.pooled,
        "stiller": searched.stiller,
        "reference_band_deg": math.degrees(REFERENCE_BAND),
        "probes": [{"band_deg": math.degrees(p.band), "met": p.met} for p in searched.probes],
        "candidates": [
            {
                "id": c.id,
                "dwell_deg": [math.degrees(d.angle) for d in c.figures.dwells[: req.dwells]],
                "reference_dwell_deg": [math.degrees(x) for x in ref],
            }
            for c, ref in zip(searched.result.candidates, searched.reference_dwells)
        ],
    }


def band_search_text(searched) -> str:
    """The lines under the table with ``--band auto``: the band reached and how, then each
    candidate's dwell at that band and at the reference band (not when the two are one)."""
    from synth.query.band_search import REFERENCE_BAND, needed

    req = searched.result.request
    ref = f"{math.degrees(REFERENCE_BAND):g}°"
    searched_ = f"{searched.pooled} six-bars fitted, {searched.stiller} moved to stiller rests"
    if searched.settled:
        head = (
            f"band auto: {math.degrees(searched.band):.3g}°, the tightest at which {needed(req)} six-bars "
            f"meet the request ({searched_})"
        )
    else:
        head = (
            f"band auto: no band down to 1e-4° holds {needed(req)} six-bars ({searched_}); "
            f"answered at {math.degrees(searched.band):g}°"
        )
    if math.isclose(req.band, REFERENCE_BAND):  # answered at the reference band: the table's dwells
        return head
    lines = [head]
    for c, dwells in zip(searched.result.candidates, searched.reference_dwells):
        here = "/".join(f"{math.degrees(d.angle):.2f}°" for d in c.figures.dwells[: req.dwells])
        there = "/".join(f"{math.degrees(x):.2f}°" for x in dwells) or "none"
        lines.append(f"  {c.rank:>3} dwell {here} at {math.degrees(req.band):.3g}°, {there} at {ref}")
    return "\n".join(lines)


def tighter_text(tighter, request: Request) -> str:
    """The one line a query at the default band adds when a tighter band also answers it."""
    return (
        f"dwell: a stiller rest exists: {tighter.met} six-bars also meet the request within a "
        f"{math.degrees(tighter.band):g}° band (--band {math.degrees(tighter.band):g}, or --band auto "
        f"for the tightest)"
    )


#: How a no-match names each constraint (synth.query.CONSTRAINTS).
_CONSTRAINT_NAMES = {
    "assembly": "assembly (toggles, revolves or misses a dwell)",
    "dwell": "dwell angle",
    "swing": "swing",
    "step": "step between the rests (--step)",
    "transmission": "transmission angle",
    "link_ratio": "link ratio",
    "arm": "slider's torque arm (--min-arm)",
    "clearance": "clearance to the fixed pivots",
    "acceleration": "output acceleration",
}


def _options_changed(before: Request, after: Request) -> str:
    """The ``dwell query`` options that turn ``before`` into ``after``."""
    out = []
    for name, option, deg in (
        ("dwell", "--dwell", True),
        ("dwell_tol", "--dwell-tol", True),
        ("swing", "--swing", True),
        ("swing_tol", "--swing-tol", True),
        ("step", "--step", True),
        ("min_transmission", "--min-transmission", True),
        ("max_link_ratio", "--max-link-ratio", False),
        ("min_arm", "--min-arm", False),
        ("min_clearance", "--min-clearance", False),
        ("max_accel", "--max-accel", False),
    ):
        old, new = getattr(before, name), getattr(after, name)
        if new != old and new is not None:
            out.append(f"{option} {round(math.degrees(new) if deg else new, 3):g}")
    return " ".join(out)


def _figures_line(c, req: Request) -> str:
    f = c.figures
    dw = "/".join(f"{math.degrees(d.angle):.2f}°" for d in f.dwells[: req.dwells])
    mu = math.degrees(min(f.transmission_fourbar, f.transmission_output))
    return (
        f"{c.id}: {c.sixbar.dyad.kind}, dwell {dw}, swing {math.degrees(f.swing):.2f}°, "
        f"transmission {mu:.1f}°, link ratio {f.link_ratio:.2f}"
    )


def no_match_message(result: QueryResult) -> str:
    """Why nothing met the request: the constraint that failed with how many fitted six-bars
    each constraint rejected, the nearest six-bar and the request it would meet (a few lines)."""
    req = result.request
    head = f"no six-bar meets the request ({_searched(result)}, {result.simulated} simulated)"
    nm = result.no_match
    if nm is not None and nm.fitted:
        counts = ", ".join(f"{_CONSTRAINT_NAMES[k]} {n}" for k, n in nm.rejected.items() if n)
        lines = [
            f"{head}; the {_CONSTRAINT_NAMES[nm.failed]} failed most: of {nm.fitted} fitted six-bars, "
            f"rejected by {counts}"
        ]
        if nm.nearest is not None:
            lines.append(f"  nearest: {_figures_line(nm.nearest, req)}")
            change = _options_changed(req, nm.would_meet)
            if change:
                lines.append(f"  it meets: {change}")
        lines += _in_the_way(nm)
        if result.refined[0]:
            lines.append(f"  refined: its {result.refined[0]} nearest misses toward the request; none meets it")
        return "\n".join(lines)
    below, above = result.nearest
    near = [x for x in (below, above) if x is not None]
    if near and min(abs(x - req.dwell) for x in near) <= req.dwell_tol:
        # segments of that dwell exist: it is the dyads that fail the swing or the constraints
        return "\n".join(
            [
                f"{head}; the atlas holds segments of that dwell, but no output dyad fits them: try a larger "
                f"--max-link-ratio (now {req.max_link_ratio:g}), a lower --min-transmission "
                f"(now {math.degrees(req.min_transmission):g}°) or another --swing",
                *_in_the_way(nm),
            ]
        )
    hint = " and ".join(f"{math.degrees(x):.1f}°" for x in near)
    return "\n".join(
        [
            f"{head}; "
            + (f"the closest dwells the atlas holds are {hint}: " if near else "")
            + "try a wider --dwell-tol (the error allowed on the dwell angle) or a larger atlas; a wider "
            "--band would count a less still output as a dwell",
            *_in_the_way(nm),
        ]
    )


#: How the no-match's line names the six-bars its figure is the best of, per
#: ``synth.query.result.REACH_AMONG`` (``NoMatch.reach_among``).
_REACH_AMONG = dict(
    zip(
        REACH_AMONG,
        (
            "the fitted six-bars meeting every other limit",
            "the six-bars fitted to the segments near the request without that limit",
            "the stored four-bars near the request",
        ),
        strict=True,
    )
)


def _in_the_way(nm) -> list[str]:
    """The no-match's line on the one constraint in its way (``synth.query.NoMatch.reach``), if any."""
    if nm is None or nm.reach is None:
        return []
    key, best, limit = nm.reach
    return [
        f"  in the way: the {_CONSTRAINT_NAMES[key]} alone; the best of {_REACH_AMONG[nm.reach_among]} is "
        + _figure(key, best, limit)
    ]


def _figure(key: str, best: float, limit: float) -> str:
    """``135.4° (asked 180°)``: a constraint's best figure against the request's, in its unit."""
    unit = {"link_ratio": "", "acceleration": " rad/s²", "arm": " cranks", "clearance": " cranks"}.get(key, "°")
    return f"{best:.4g}{unit} (asked {limit:.4g}{unit})"


def short_text(result: QueryResult) -> str | None:
    """The one line an answer of fewer six-bars than it fills up to (``synth.query.FILL`` or
    --top) adds: the constraint in the way of more, per output type
    (``QueryResult.short_of``); None when the answer is not short or nothing is known."""
    if not result.candidates or not result.short_of:
        return None
    wanted = min(FILL, result.request.top)
    among = "the best of the other fitted six-bars meeting every other limit is"
    if len(result.short_of) == 1:
        _, key, best, limit = result.short_of[0]
        why = f"the {_CONSTRAINT_NAMES[key]} alone: {among} {_figure(key, best, limit)}"
    else:
        why = f"per output type, one constraint alone: {among}, " + "; ".join(
            f"{output.upper()}: {_CONSTRAINT_NAMES[key]} {_figure(key, best, limit)}"
            for output, key, best, limit in result.short_of
        )
    return f"dwell: {len(result.candidates)} six-bar(s) where {wanted} were sought; in the way of more, {why}"


def short_json(result: QueryResult) -> list[dict] | None:
    """``short_of`` of ``--json`` (the facts of :func:`short_text`): None when the answer is not short."""
    if not result.candidates or not result.short_of:
        return None
    return [dict(zip(("output", "constraint", "best", "asked"), s)) for s in result.short_of]


def no_match_json(result: QueryResult, units: str = "mm") -> dict:
    """The ``no_match`` object of ``--json`` (the same facts as :func:`no_match_message`)."""
    nm = result.no_match
    below, above = result.nearest
    doc = {
        "message": no_match_message(result),
        "segments_fitted": result.considered,
        "sixbars_fitted": 0 if nm is None else nm.fitted,
        "failed": None if nm is None else nm.failed,
        "rejected": {} if nm is None else dict(nm.rejected),
        "nearest": None,
        "would_meet": None,
        "nearest_stored_dwell_deg": [None if x is None else math.degrees(x) for x in (below, above)],
    }
    if nm is not None and nm.nearest is not None:
        doc["nearest"] = candidate_json(nm.nearest, result.request.rpm, units)
        doc["would_meet"] = request_json(nm.would_meet, units)
    doc["in_the_way"] = (
        None
        if nm is None or nm.reach is None
        else {**dict(zip(("constraint", "best", "asked"), nm.reach)), "among": nm.reach_among}
    )
    return doc


#: The request's values on the command line (degrees unless said): their ranges, shown in
#: --help. synth.query.candidates.Request checks the same meaning again for library callers; the
#: floors here keep a value meaningful (a 1e-320° swing is no mechanism) and the numerics quiet.
DWELL_DEG = Bounded(0.0, 360.0, "a dwell in degrees", low_open=True, high_open=True)
#: > 0: an exact dwell is never met (the dwell is a simulated interval), and asking for one ran
#: the whole refinement's reach for nothing.
DWELL_TOL_DEG = Bounded(0.0, 360.0, "a dwell error in degrees, > 0", low_open=True, high_open=True)
SWING_DEG = Bounded(0.01, 180.0, "a swing in degrees", high_open=True)
STEP_DEG = Bounded(0.01, 180.0, "a turn between two rests in degrees", high_open=True)
BAND_DEG = Bounded(1e-4, 180.0, "an output band in degrees", high_open=True)
#: ``dwell query --band``: the same, or auto (synth.query.band_search); ``dwell report`` takes a number.
BAND_OR_AUTO = BandOrAuto(BAND_DEG.min, BAND_DEG.max, BAND_DEG.what, high_open=True)
#: Transmission angles the RRR fit accepts (degrees): from 0.001° (5e-324° became 0 rad, which
#: the fit refuses; found by tests/cli/test_option_ranges.py) to below 90°.
TRANSMISSION_RANGE = Bounded(0.001, 90.0, "a transmission angle in degrees", high_open=True)
LINK_RATIO = Bounded(1.0, 1e6, "a longest/shortest link ratio")
CRANKS = Bounded(0.0, 1e3, "a length in crank lengths")
ACCEL_LIMIT = Bounded(1e-9, 1e100, "an angular acceleration in rad/s²")
TOP = Count(1, 1000, "candidates")


#: Exit statuses of ``dwell query`` (as grep's): six-bars found, none found, bad input.
FOUND, NONE_FOUND, BAD_INPUT = 0, 1, 2


@click.command(
    "query",
    epilog=f"Exit status: {FOUND} if six-bars were found, {NONE_FOUND} if none meets the request "
    f"(why, on stderr; with --json, the no_match object on stdout), {BAD_INPUT} for bad input "
    "(an option, a value or the atlas).",
)
@db_option(dest="target", required=True)
@click.option("--dwell", type=DWELL_DEG, required=True, help="Dwell angle (degrees of crank rotation).")
@click.option(
    "--dwell-tol",
    type=DWELL_TOL_DEG,
    default=default_deg("dwell_tol"),
    show_default=True,
    help="Allowed dwell-angle error (°).",
)
@click.option(
    "--swing",
    type=SWING_DEG,
    default=None,
    help="Output swing (°): the output's whole swing, max − min over the turn; required, for one dwell and for two.",
)
@click.option(
    "--step",
    type=STEP_DEG,
    default=None,
    help="Two dwells: the output's turn (°) between its two rests, ±--swing-tol (at most the swing). "
    "Two rests count as two only if the crank turns ≥ 5° and the output leaves both rests' "
    "bands by ≥ --swing-tol between them, each way round.",
)
@click.option(
    "--swing-tol",
    type=SWING_TOL_DEG,
    default=default_deg("swing_tol"),
    show_default=True,
    help="Allowed swing error (°).",
)
@click.option(
    "--output",
    type=click.Choice(OUTPUTS, case_sensitive=False),
    default=_DEFAULTS["output"],
    show_default=True,
    help="Output dyad.",
)
@click.option(
    "--dwells",
    type=Count(1, 2, "dwells per turn"),
    default=_DEFAULTS["dwells"],
    show_default=True,
    help="Dwells per turn: 1, or 2 (double Ball point, RPR).",
)
@click.option(
    "--band",
    type=BAND_OR_AUTO,
    default=default_deg("band"),
    show_default=True,
    help="Total width (°) of the output band that counts as a dwell (not --dwell-tol, the error "
    "allowed on the dwell angle); auto: the tightest band (down to 1e-4°) at which at least "
    "min(--top, 3) six-bars meet the request (docs/query.md).",
)
@click.option("--crank", type=LENGTH, default=_DEFAULTS["crank"], show_default=True, help="Crank length (your unit).")
@click.option(
    "--min-transmission",
    type=TRANSMISSION_RANGE,
    default=default_deg("min_transmission"),
    show_default=True,
    help="Smallest transmission angle (°).",
)
@click.option(
    "--max-link-ratio",
    type=LINK_RATIO,
    default=_DEFAULTS["max_link_ratio"],
    show_default=True,
    help="Largest link ratio: the longest link over the shortest, every link counted — crank, "
    "rocker, ground, the coupler as the plate it is (A-B, A-P and B-P, P the coupler point) "
    "and the output dyad's (RRR rocker and rod; RPR the slot's reach, the slider's farthest "
    "distance from its pivot).",
)
@click.option("--top", type=TOP, default=_DEFAULTS["top"], show_default=True, help="Candidates returned.")
@click.option(
    "--min-arm",
    type=CRANKS,
    default=_DEFAULTS["min_arm"],
    show_default=True,
    help="Smallest distance of an RPR slider from its slot pivot over the turn (crank lengths).",
)
@click.option(
    "--min-clearance",
    type=CRANKS,
    default=_DEFAULTS["min_clearance"],
    show_default=True,
    help="Smallest distance of a moving joint or output link from a fixed pivot (crank lengths).",
)
@click.option(
    "--tolerance",
    type=LENGTH,
    default=None,
    metavar="LEN",
    help="Manufacturing tolerance (your unit, like --crank): also rank by the output deviation "
    "95 % of six-bars made within ±LEN of every length and pivot coordinate keep.",
)
@click.option(
    "--rpm",
    type=RPM,
    default=_DEFAULTS["rpm"],
    show_default=True,
    help="Crank speed for the output's peak velocity, acceleration and jerk (rev/min).",
)
@click.option("--max-accel", type=ACCEL_LIMIT, default=None, help="Largest peak output acceleration (rad/s²) at --rpm.")
@click.option(
    "--refine/--no-refine",
    default=_DEFAULTS["refine"],
    show_default=True,
    help="Refine the returned six-bars (and, when nothing meets the request, the nearest misses) by a "
    "local optimisation with exact simulation in the loop.",
)
@click.option(
    "--complete/--sampled",
    default=_DEFAULTS["complete"],
    show_default=True,
    help="Search every stored segment at every tolerance level (every six-bar the atlas yields; "
    "seconds to minutes, with a progress bar) instead of the segments nearest the request.",
)
@workers_option
@engine_options(
    "a complete search's batches",
    "The atlas is read by this process either way: the rows travel to the workers.",
)
@click.option("--json", "as_json", is_flag=True, help="JSON on stdout instead of a table.")
@click.option(
    "--wide",
    is_flag=True,
    help="Every column of the table and the full ids (the default table fits 120 "
    "columns and shows short ids, which dwell report also takes).",
)
@click.option(
    "--report",
    "report_dir",
    type=click.Path(file_okay=False),
    default=None,
    help="Also write the report of the candidates to this folder.",
)
@units_option
def query(
    target,
    dwell,
    dwell_tol,
    swing,
    step,
    swing_tol,
    output,
    dwells,
    band,
    crank,
    min_transmission,
    max_link_ratio,
    top,
    min_arm,
    min_clearance,
    tolerance,
    rpm,
    max_accel,
    refine,
    complete,
    workers,
    engine,
    scheduler,
    as_json,
    wide,
    report_dir,
    units,
):
    """Ranked six-bars for a requested dwell and swing (docs/query.md)."""
    check_engine(engine, scheduler)
    if engine == "dask" and not complete:
        raise click.UsageError("--engine dask runs the complete search on a cluster: add --complete")
    auto = band == AUTO
    with request_errors():
        request = Request.from_degrees(
            dwell=dwell,
            dwell_tol=dwell_tol,
            swing=swing,
            swing_tol=swing_tol,
            output=output.lower(),
            dwells=dwells,
            band=None if auto else band,
            crank=crank,
            min_transmission=min_transmission,
            max_link_ratio=max_link_ratio,
            top=top,
            min_arm=min_arm,
            min_clearance=min_clearance,
            rpm=rpm,
            max_accel=max_accel,
            step=step,
            refine=refine,
            complete=complete,
            tolerance=tolerance,
        )
    if report_dir is not None:
        _check_report_dir(Path(report_dir))
    with _cluster(scheduler) as cluster:  # reached before the atlas is opened: a bad address reads nothing
        result, searched, tighter = _answered(target, request, auto, workers or default_workers(), cluster)
    if report_dir is not None:
        from kinematics.assur import LinkageFileError
        from report.linkage_toml import readable_linkages

        try:  # before anything is shown: the report would be refused after the table
            readable_linkages(result.candidates, units)
        except LinkageFileError as exc:
            raise InputError(f"--crank {crank:g}: {exc}; use a smaller --crank (or no --report)") from None
    request = result.request  # with --band auto, at the band reached
    if as_json:
        doc = {
            "request": request_json(request, units),
            "candidates": [candidate_json(c, request.rpm, units) for c in result.candidates],
            "refinement": refinement_json(result),
        }
        if searched is not None:
            doc["band_search"] = band_search_json(searched)
        if tighter is not None:
            doc["tighter_band_deg"] = math.degrees(tighter.band)
        if not result.candidates:
            doc["no_match"] = no_match_json(result, units)
        elif result.short_of:
            doc["short_of"] = short_json(result)
        click.echo(json.dumps(doc, indent=2, allow_nan=False))
    elif result.candidates:
        click.echo(table(result, units, wide=wide))
        if not wide:
            from cli.shown_ids import remember_shown, report_settings

            remember_shown(result.candidates, report_settings(request, units))
        if searched is not None:
            click.echo(band_search_text(searched))
        short = short_text(result)
        if short is not None:
            click.echo(short, err=True)
    if not result.candidates:
        click.echo(f"dwell: {no_match_message(result)}", err=True)
        click.get_current_context().exit(NONE_FOUND)  # a script tells "none" from "some" (as grep)
    if report_dir is not None and result.candidates:
        from cli.progress import Progress
        from cli.report_pool import report_pool
        from report.export import write_report

        with Progress("query") as shown:  # a line on a terminal once it runs past a second
            written = write_report(
                result.candidates,
                request,
                Path(report_dir),
                units=units,
                on_candidate=shown.counter("writing the report", "candidates"),
                map_candidates=report_pool(len(result.candidates), workers),
            )
        click.echo(f"report: {len(written)} files in {report_dir}", err=True)
    if tighter is not None and not as_json:  # last: an answer whose report failed says only why
        click.echo(tighter_text(tighter, request), err=True)


@contextmanager
def _cluster(scheduler: str | None) -> Iterator[DaskCluster | None]:
    """The cluster at ``scheduler`` (None: no cluster), connected now and closed after; what
    the cluster does wrong, here or during the search, is one line, exit 2."""
    if scheduler is None:
        yield None
        return
    from atlas.dask_cluster import ClusterError, DaskCluster

    try:
        with DaskCluster.connect(scheduler, log=lambda msg: click.echo(f"dwell: {msg}", err=True)) as cluster:
            yield cluster
    except ClusterError as exc:
        raise click.ClickException(str(exc)) from None


def _answered(target: str, request: Request, auto: bool, workers: int, cluster: DaskCluster | None):
    """(result, the band search or None, the tighter band or None) on the atlas ``target``."""
    from db.engine import open_atlas

    engine = open_atlas(target, readonly=True)
    try:
        if auto:
            searched = answer_tightest(engine, request, workers=workers, cluster=cluster)
            result = searched.result
        else:
            searched = None
            result = answer(engine, request, progress=None, workers=workers, cluster=cluster)
        # no --band given: one cheap probe names a stiller rest the atlas holds (docs/query.md)
        tighter = (
            tighter_band(engine, result)
            if searched is None
            and result.candidates
            and click.get_current_context().get_parameter_source("band") is ParameterSource.DEFAULT
            else None
        )
    finally:
        engine.dispose()
    return result, searched, tighter


def _check_report_dir(path: Path) -> None:
    if path.exists() and not path.is_dir():
        raise InputError(f"--report {str(path)!r} is a file, not a folder")
    parent = path if path.exists() else path.parent
    if not parent.exists():
        raise InputError(f"--report: folder {str(parent)!r} does not exist")
    from cli.options import probe_folder
    from report.folder import check_report_folder

    probe_folder(path, "--report")
    check_report_folder(path, "--report")  # a folder of the user's own files: refused before the query runs
