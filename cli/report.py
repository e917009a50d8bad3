"""``dwell report``: export chosen candidates (ids from ``dwell query``) from an atlas."""

from __future__ import annotations

import math
import re
from pathlib import Path

import click
from click.core import ParameterSource

from cli.errors import InputError
from cli.options import LENGTH, RPM, db_option, probe_folder, request_errors, units_option
from cli.query import BAND_DEG, DWELL_DEG, TRANSMISSION_RANGE
from report.escape import terminal
from synth.query.candidates import Request

#: A candidate id as `dwell query` prints it, in ASCII: <segment>-<rpr|rrr|dbl><slot>.<level>@<swing
#: or free>, optionally ~<refined dimensions, base64url>. Python's int() and float() would also
#: take "+12", full-width digits and "4_0" — and the report would echo them as typed.
_ID = re.compile(
    r"[0-9]+-(rpr|rrr|dbl)[0-9]+\.[0-9]+@(free|[0-9]+(\.[0-9]+)?([eE]-?[0-9]+)?)(~[A-Za-z0-9_-]+)?", re.ASCII
)


def canonical_id(text: str) -> str:
    """``text`` as the id ``dwell query`` would print for the same six-bar: a full id, or the
    one a short id stands for (:func:`cli.shown_ids.resolve`); an id in any other spelling is
    refused in one line (the report shows and files ids: they must be the query's)."""
    from cli.shown_ids import resolve
    from synth.query.candidate_ids import REFINED_MARK, candidate_id, parse_candidate_id

    shown = resolve(text)
    text = text if shown is None else shown.full
    if len(text) > 200 or not _ID.fullmatch(text):
        raise InputError(
            f"--candidates: {terminal(repr(text[:80]))} is not a candidate id as `dwell query` prints "
            "them (e.g. 1234500007-rrr0.1@30)"
        )
    try:
        segment, output, slot, level, swing = parse_candidate_id(text)
    except ValueError as exc:
        raise InputError(f"--candidates: {terminal(exc)}") from None
    base = candidate_id(segment, output, slot, level, swing)
    refined = text.partition(REFINED_MARK)[2]
    return f"{base}{REFINED_MARK}{refined}" if refined else base


@click.command("report")
@db_option(dest="target", required=True)
@click.option(
    "--candidates",
    "ids",
    required=True,
    multiple=True,
    help="Candidate id(s) from `dwell query`, full or short (repeat the option or separate with spaces).",
)
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False), help="Folder for the report.")
@click.option("--dwell", type=DWELL_DEG, default=None, help="Requested dwell (°) for the output deviation window.")
@click.option(
    "--band",
    type=BAND_DEG,
    default=0.1,
    show_default=True,
    help="Total width (°) of the output band that counts as a dwell.",
)
@click.option("--crank", type=LENGTH, default=1.0, show_default=True, help="Crank length (your unit).")
@click.option(
    "--min-transmission",
    type=TRANSMISSION_RANGE,
    default=30.0,
    show_default=True,
    help="The query's smallest transmission angle (°): RRR fits are rebuilt with it.",
)
@click.option(
    "--rpm",
    type=RPM,
    default=60.0,
    show_default=True,
    help="Crank speed for the output's peak velocity, acceleration and jerk (rev/min).",
)
@click.option(
    "--tolerance",
    type=LENGTH,
    default=None,
    metavar="LEN",
    help="Manufacturing tolerance (your unit, like --crank): also give each six-bar's output deviation "
    "95 % of six-bars made within ±LEN of every length and pivot coordinate keep (as `dwell query --tolerance`).",
)
@units_option
@click.argument("more_ids", nargs=-1)
def report(target, ids, out_dir, dwell, band, crank, min_transmission, rpm, tolerance, units, more_ids):
    """Write JSON, CSV, plots, drawings, DXF and an animated HTML page for the candidates."""
    from cli.shown_ids import resolve
    from report.folder import ReportFolderError, check_report_folder

    texts = [t for item in (*ids, *more_ids) for t in item.replace(",", " ").split()]
    if not texts:
        raise InputError("--candidates: give at least one candidate id")
    looked = [resolve(t) for t in texts]
    names = [canonical_id(t if s is None else s.full) for t, s in zip(texts, looked)]
    taken = as_shown(click.get_current_context(), looked)
    dwell, band, crank = taken.get("dwell", dwell), taken.get("band", band), taken.get("crank", crank)
    min_transmission, rpm = taken.get("min_transmission", min_transmission), taken.get("rpm", rpm)
    tolerance, units = taken.get("tolerance", tolerance), taken.get("units", units)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out_dir!r} is a file, not a folder")
    if not (out if out.exists() else out.parent).exists():
        raise InputError(f"--out: folder {str(out.parent)!r} does not exist")
    try:
        check_report_folder(out, "--out")  # a folder with the user's own files is refused first
    except ReportFolderError as exc:
        raise InputError(str(exc)) from None
    probe_folder(out, "--out")
    line = taken_text(click.get_current_context(), taken)
    if line:
        click.echo(f"dwell: {line}", err=True)
    # the deviation window: the requested dwell, or the rebuilt six-bar's own dwell
    # (a swing to make it a whole request, and no link-ratio limit: the ids name the six-bars)
    with request_errors():
        request = Request.from_degrees(
            dwell=dwell if dwell is not None else 60.0,
            swing=30.0,
            band=band,
            crank=crank,
            min_transmission=min_transmission,
            max_link_ratio=1e12,
            top=len(names),
            rpm=rpm,
            tolerance=tolerance,
        )
    from cli.progress import Progress

    with Progress("report") as shown:  # a line on a terminal once it runs past a second
        candidates, written = _report(target, names, request, out, units, crank, shown)
    for c in candidates:
        dw = " and ".join(f"{math.degrees(d.angle):.2f}°" for d in c.figures.dwells)
        tol = ""
        if request.tolerance > 0:
            t = c.toleranced_deviation
            tol = ", toleranced deviation " + (
                "fails (over 5 % of draws do not assemble)" if t is None else f"{math.degrees(t):.4f}°"
            )
        click.echo(
            f"{c.rank}. {c.id}: {c.sixbar.dyad.kind}, dwell {dw}, swing {math.degrees(c.figures.swing):.2f}°{tol}"
        )
    click.echo(f"wrote {len(written)} files to {out.resolve()} (open index.html)")


def as_shown(ctx: click.Context, looked: list) -> dict:
    """The report options not given on the command line, set as the query that showed the
    ids did (``cli.shown_ids.Shown.settings``, by option name): only when every id is a short
    id whose table kept its settings (a full id is reported at the report's own options). Ids
    shown at different values of an option are one line (exit 2) asking for it; settings that
    are not the options' values (a hand-edited file) count as none."""
    from cli.shown_ids import REPORT_SETTINGS
    from kinematics.assur.linkage_file import plain_text_problem

    if not looked or any(s is None or s.settings is None for s in looked):
        return {}
    params = {p.name: p for p in ctx.command.params}
    taken = {}
    for name in REPORT_SETTINGS:
        if ctx.get_parameter_source(name) is not ParameterSource.DEFAULT:
            continue  # the user's own option wins
        values = {_option_value(s.settings[name]) for s in looked}
        if len(values) > 1:
            raise InputError(
                f"--{name.replace('_', '-')}: the ids were shown by queries at different values of it "
                f"({', '.join(sorted(values))}); give --{name.replace('_', '-')}"
            )
        value = looked[0].settings[name]
        try:
            if name == "units":
                if plain_text_problem(value):
                    return {}
            elif value is not None:
                value = params[name].type.convert(value, params[name], ctx)
        except click.BadParameter:
            return {}
        taken[name] = value
    return taken


def _option_value(value) -> str:
    """An option's value as the command line would give it (29.999999999999996° is 30)."""
    return f"{value:g}" if isinstance(value, float | int) else terminal(str(value))


def taken_text(ctx: click.Context, taken: dict) -> str | None:
    """The line naming the options :func:`as_shown` took that differ from the report's
    defaults (None if none does)."""
    params = {p.name: p for p in ctx.command.params}
    changed = [
        f"--{k.replace('_', '-')} {_option_value(v)}"
        for k, v in taken.items()
        if v is not None and (params[k].default is None or _option_value(v) != _option_value(params[k].default))
    ]
    return f"as the query that showed them: {' '.join(changed)} (an option given here wins)" if changed else None


def _toleranced(request, candidates: list) -> list:
    """Each rebuilt candidate with its toleranced deviation over every dwell it has (a double
    RPR's two: the report's request asks for one, the id says how many)."""
    import dataclasses

    from synth.query.evaluate import toleranced

    return [toleranced(dataclasses.replace(request, dwells=max(1, len(c.figures.dwells))), [c])[0] for c in candidates]


def _report(target, names: list[str], request, out: Path, units: str, crank: float, shown) -> tuple[list, list[Path]]:
    """The candidates ``names`` rebuilt from the atlas ``target`` and the files of their report
    written into ``out``, the progress shown on ``shown`` (:class:`cli.progress.Progress`)."""
    from cli.query import rebuild
    from cli.report_pool import report_pool
    from db.engine import damaged, open_atlas
    from db.summary import quick_check
    from kinematics.assur import LinkageFileError
    from report.export import write_report
    from report.linkage_toml import readable_linkages

    shown.stage("rebuilding the candidates")
    engine = open_atlas(target, readonly=True)
    try:
        # a report reads a few rows, which may all lie outside a damaged stretch of the file:
        # SQLite's structure check (0.04 s on the demo atlas, small beside the report's plots)
        # refuses a damaged atlas whatever the candidates read
        broken = quick_check(engine)
        if broken:
            raise damaged(target, broken)
        candidates = rebuild(engine, names, request)
    finally:
        engine.dispose()
    if request.tolerance > 0:
        shown.stage("toleranced deviations")
        candidates = _toleranced(request, candidates)
    try:  # every file is written or none: the linkage files are checked first
        readable_linkages(candidates, units)
    except LinkageFileError as exc:
        raise InputError(f"--crank {crank:g}: {exc}; use a smaller --crank") from None
    written = write_report(
        candidates,
        request,
        out,
        option="--out",
        units=units,  # all files or none (report/folder.py)
        on_candidate=shown.counter("writing the report", "candidates"),
        map_candidates=report_pool(len(candidates)),
    )
    return candidates, written
