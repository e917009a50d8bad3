"""``dwell query``: ranked six-bars for a requested dwell, from an atlas.

Pipeline (:func:`answer`): one indexed SELECT of segments whose stored dwell (any tolerance
level) lies near the request → output dyads fitted to every segment in one batch per kind
(``synth.dyad``: RPR on straight segments, RPR at the lines' intersection for double Ball
points, RRR on arcs) → every fitted six-bar simulated exactly over the turn in one batch
(``synth.sixbar.sixbar_figures``) → candidates that meet the request and the constraints →
ranked (``synth.candidates.rank``). Lengths are crank-normalised until the end, then scaled
to ``--crank``.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import click
import numpy as np

from cli.errors import InputError
from synth.candidates import (
    Candidate,
    Request,
    candidate_id,
    candidate_json,
    parse_candidate_id,
    rank,
    screen,
)

__all__ = ["QueryResult", "answer", "query", "rebuild"]

#: Crank samples of the exact simulation (0.5°); the figures refine beyond it.
SAMPLES = 720
#: Crank samples of the path the dyads are fitted to (1°): a fitted swing is within ~0.01° of
#: the simulated one, which is what the request is checked against.
FIT_SAMPLES = 360
#: Segments taken from the atlas per kind and tolerance level, closest to that level's target first.
PER_LEVEL = 10
#: Output link lengths (crank lengths) tried in the band conversion of ``_select``.
REACHES = (2.0, 5.0, 12.0)


@dataclass(frozen=True, slots=True)
class QueryResult:
    request: Request
    candidates: list[Candidate]
    considered: int  #: segments fitted
    simulated: int  #: six-bars simulated
    nearest: tuple[float | None, float | None]  #: stored dwell angles (rad) around the request when empty
    seconds: dict[str, float]


def _select(engine, request: Request, kinds: tuple[str, ...]) -> list:
    """Segments worth fitting, per kind and tolerance level.

    A six-bar's dwell is measured with an output band (an angle), a segment's with a path band
    ε (a length): the output stands still while the coupler point stays within about
    ε* = R·band/2 of the segment's line or circle, R the output link's length (slot reach or
    rocker), a few cranks. Dwells grow like ε^¼ (four-point contact), so at level ε_ℓ the
    segment dwell that gives the requested six-bar dwell is about dwell·(ε_ℓ/ε*)^¼; each level
    is searched around its own target, generously — the simulation decides."""
    from db.queries import DwellWindow, select_segments, tolerance_levels

    windows = []
    # the stored dwells closest to the request at any level, then each level's own target
    width = request.dwell_tol + math.radians(10.0)
    windows.append(DwellWindow(None, request.dwell - width, request.dwell + width, request.dwell, 2 * PER_LEVEL))
    for (level, eps), reach in itertools.product(tolerance_levels(engine), REACHES):
        target = request.dwell * (eps / (reach * request.band / 2)) ** 0.25
        width = request.dwell_tol + 0.2 * target
        windows.append(DwellWindow(level, target - width, target + width, target, PER_LEVEL))
    # constraints the four-bar alone already decides (crank = 1, the shortest link); an arc's
    # radius becomes the rod, which must not be the link that breaks the ratio
    rows = []
    for kind in kinds:
        rows += select_segments(engine, (kind,), windows, min_transmission=request.min_transmission,
                                max_length=request.max_link_ratio, min_radius_ratio=1.0 / request.max_link_ratio)
    return rows


def _kinds(request: Request) -> tuple[str, ...]:
    if request.dwells == 2:
        return ("double_line",)
    return {"rpr": ("line",), "rrr": ("arc",), "any": ("line", "arc")}[request.output]


def _paths(rows, phi: np.ndarray) -> np.ndarray:
    from kinematics.fourbar import fourbar_motion

    b = np.array([r.b for r in rows])[:, None]
    c = np.array([r.c for r in rows])[:, None]
    d = np.array([r.d for r in rows])[:, None]
    br = np.array([r.branch for r in rows])[:, None]
    uv = np.array([complex(r.u, r.v) for r in rows])[:, None]
    motion = fourbar_motion(1.0, b, c, d, phi, br, order=0)
    return motion.A + motion.e_theta * uv


def _fit(request: Request, rows, kind: str) -> list[tuple[object, str, int, object, complex | None]]:
    """(row, output, slot, OutputDyad, dwell position) of every found dyad of ``rows``."""
    from synth.dyad import fit_rpr, fit_rrr, rpr_double
    from synth.sixbar import OutputDyad, crank_grid

    phi = crank_grid(FIT_SAMPLES)
    out = []
    if kind == "double_line":
        line1 = (np.array([complex(r.parts[0][2], r.parts[0][3]) for r in rows]), np.array([r.parts[0][4] for r in rows]))
        line2 = (np.array([complex(r.parts[1][2], r.parts[1][3]) for r in rows]), np.array([r.parts[1][4] for r in rows]))
        fit = rpr_double(line1, line2)
        for i, r in enumerate(rows):
            dyad = fit.dyad((i,))
            if dyad is not None:
                out.append((r, "dbl", 0, dyad, None))
        return out
    paths = _paths(rows, phi)
    start = np.array([r.parts[0][0] for r in rows])
    end = np.array([r.parts[0][1] for r in rows])
    point = np.array([complex(r.parts[0][2], r.parts[0][3]) for r in rows])
    if kind == "line":
        direction = np.array([r.parts[0][4] for r in rows])
        fit = fit_rpr(point, direction, phi, paths, (start, end), request.swing)
        for i, r in enumerate(rows):
            for slot in range(fit.found.shape[-1]):
                if fit.found[i, slot]:
                    out.append((r, "rpr", slot, OutputDyad.rpr(complex(fit.pivot[i, slot])), None))
    else:
        radius = np.array([r.parts[0][5] for r in rows])
        fit = fit_rrr(point, radius, phi, paths, (start, end), request.swing, request.min_transmission, keep=2)
        for i, r in enumerate(rows):
            for slot in range(fit.found.shape[-1]):
                if fit.found[i, slot]:
                    dyad = OutputDyad.rrr(complex(fit.pivot[i, slot]), float(fit.rocker[i, slot]),
                                          float(fit.rod[i, slot]), int(fit.branch[i, slot]))
                    out.append((r, "rrr", slot, dyad, complex(point[i])))
    return out


def _meets(request: Request, f) -> bool:
    if not f.acceptable or len(f.dwells) < request.dwells:
        return False
    if any(abs(d.angle - request.dwell) > request.dwell_tol for d in f.dwells[: request.dwells]):
        return False
    if request.swing is not None and abs(f.swing - request.swing) > request.swing_tol:
        return False
    if min(f.transmission_fourbar, f.transmission_output) < request.min_transmission:
        return False
    return f.link_ratio <= request.max_link_ratio


def _scaled_figures(f, scale: float):
    return dataclasses.replace(f, footprint=f.footprint * scale**2, bounds=tuple(x * scale for x in f.bounds))


def _simulate(request: Request, fitted) -> tuple[list[Candidate], int]:
    from synth.sixbar import SixBar, SixBars, sixbar_figures

    if not fitted:
        return [], 0
    sixbars = [SixBar(1.0, r.b, r.c, r.d, r.branch, r.u, r.v, dyad) for r, _, _, dyad, _ in fitted]
    # the full figures only for six-bars that pass the (necessary) test on the crank grid
    passed = screen(request, SixBars.from_sixbars(sixbars), SAMPLES)
    fitted = [f for f, p in zip(fitted, passed) if p]
    sixbars = [sb for sb, p in zip(sixbars, passed) if p]
    if not sixbars:
        return [], len(passed)
    figures = sixbar_figures(SixBars.from_sixbars(sixbars), band=request.band, dwell_length=request.dwell,
                             dwells=request.dwells, samples=SAMPLES)
    out = []
    for (r, output, slot, _, rest), sb, f in zip(fitted, sixbars, figures):
        if not _meets(request, f):
            continue
        out.append(
            Candidate(
                id=candidate_id(r.segment_id, output, slot, r.level, request.swing),
                segment_id=r.segment_id,
                sixbar=sb.scaled(request.crank),
                figures=_scaled_figures(f, request.crank),
                dwell_position=None if rest is None else rest * request.crank,
            )
        )
    return out, len(passed)


def answer(engine, request: Request) -> QueryResult:
    """Ranked candidates for ``request`` from the atlas behind ``engine`` (pure read)."""
    from db.queries import nearest_dwell_angles

    clock: dict[str, float] = {}
    t0 = time.perf_counter()
    kinds = _kinds(request)
    rows = _select(engine, request, kinds)
    t1 = time.perf_counter()
    clock["select"] = t1 - t0
    fitted = []
    for kind in kinds:
        mine = [r for r in rows if r.kind == kind]
        if mine:
            fitted += _fit(request, mine, kind)
    t2 = time.perf_counter()
    clock["fit"] = t2 - t1
    candidates, simulated = _simulate(request, fitted)
    t3 = time.perf_counter()
    clock["simulate"] = t3 - t2
    # one six-bar per segment and output type (the best-ranked fit), and one of a mirror pair:
    # the two assembly branches of a four-bar are mirror images with the same figures
    ranked = rank(request, candidates)
    seen: set = set()
    unique = []
    for c in ranked:
        sb = c.sixbar
        mirror = (round(sb.b, 9), round(sb.c, 9), round(sb.d, 9), sb.dyad.kind, round(sb.u, 3), round(abs(sb.v), 3))
        key = (c.segment_id, c.id.split("-")[1][:3])
        if key not in seen and mirror not in seen:
            seen.update((key, mirror))
            unique.append(c)
    top = [dataclasses.replace(c, rank=i + 1) for i, c in enumerate(unique[: request.top])]
    clock["rank"] = time.perf_counter() - t3
    nearest = (None, None) if top else nearest_dwell_angles(engine, kinds, request.dwell)
    return QueryResult(request, top, len({r.segment_id for r in rows}), simulated, nearest, clock)


def rebuild(engine, ids: list[str], request: Request) -> list[Candidate]:
    """The candidates named by ``ids`` (from an earlier query), re-fitted and re-simulated."""
    from sqlalchemy import select
    from sqlalchemy.orm import Session

    from db.queries import SegmentRow
    from db.schema import Dwell, Linkage, Segment

    out = []
    for text in ids:
        try:
            seg_id, output, slot, level, swing = parse_candidate_id(text)
        except ValueError as exc:
            raise InputError(str(exc)) from None
        req = dataclasses.replace(request, swing=swing, dwells=2 if output == "dbl" else 1,
                                  output="rpr" if output in ("rpr", "dbl") else "rrr")
        with Session(engine) as s:
            hit = s.execute(select(Segment, Linkage).join(Linkage, Segment.linkage_id == Linkage.id)
                            .where(Segment.id == seg_id)).first()
            if hit is None:
                raise InputError(f"no segment {seg_id} in this atlas (candidate {text!r})")
            seg, link = hit
            dwells = s.execute(select(Dwell).where(Dwell.segment_id == seg_id).order_by(Dwell.level, Dwell.part)).scalars().all()
        parts = tuple((dw.phi_start, dw.phi_end, dw.x, dw.y, dw.direction, dw.radius)
                      for dw in dwells if dw.level == level)
        found = None
        if parts:
            row = SegmentRow(seg.id, seg.kind, level, dwells[0].tolerance, link.b, link.c, link.d, link.branch,
                             seg.u, seg.v, seg.phi_gen, parts, link.transmission_min)
            fitted = [f for f in _fit(req, [row], seg.kind) if f[1] == output and f[2] == slot]
            # the figures of the rebuilt six-bar are shown whatever they are: no request filter
            loose = dataclasses.replace(req, dwell_tol=2 * math.pi - req.dwell - 1e-9, swing_tol=math.pi - 1e-9,
                                        min_transmission=0.0, max_link_ratio=1e12)
            cands, _ = _simulate(loose, fitted)
            found = dataclasses.replace(cands[0], id=text.strip()) if cands else None
        if found is None:
            raise InputError(f"candidate {text!r} cannot be rebuilt from this atlas (no fit for that slot and level)")
        out.append(dataclasses.replace(found, rank=len(out) + 1))
    return out


def request_from_options(dwell, dwell_tol, swing, swing_tol, output, dwells, dwell_tolerance, crank,
                         min_transmission, max_link_ratio, top) -> Request:
    # the deviation window must hold at least two samples of the simulation's crank grid
    if math.isfinite(dwell) and 0 < dwell < 720.0 / SAMPLES:
        raise InputError(f"--dwell must be at least {720.0 / SAMPLES:g}° (the simulation samples the turn "
                         f"every {360.0 / SAMPLES:g}°), got {dwell:g}")
    try:
        return Request(
            dwell=math.radians(dwell), dwell_tol=math.radians(dwell_tol),
            swing=None if swing is None else math.radians(swing), swing_tol=math.radians(swing_tol),
            output=output, dwells=dwells, band=math.radians(dwell_tolerance), crank=crank,
            min_transmission=math.radians(min_transmission), max_link_ratio=max_link_ratio, top=top,
        )
    except ValueError as exc:
        raise InputError(str(exc)) from None


def _table(result: QueryResult) -> str:
    req = result.request
    head = (f"{len(result.candidates)} six-bar(s) for {req.dwells} dwell(s) of {math.degrees(req.dwell):g}° ± "
            f"{math.degrees(req.dwell_tol):g}°" + ("" if req.swing is None else f", swing {math.degrees(req.swing):g}°")
            + f" (output band {math.degrees(req.band):g}°; {result.considered} segments fitted, {result.simulated} simulated)")
    lines = [head]
    cols = f"{'rank':>4}  {'id':<26} {'out':<3} {'dwell °':>15} {'dev °':>7} {'swing °':>8} {'μ4 °':>6} {'μout °':>6} {'ratio':>6}  a b c d"
    lines.append(cols)
    for c in result.candidates:
        f, sb = c.figures, c.sixbar
        dw = "/".join(f"{math.degrees(d.angle):.2f}" for d in f.dwells[: req.dwells])
        dev = max(f.deviations) if f.deviations else 0.0
        lines.append(
            f"{c.rank:>4}  {c.id:<26} {sb.dyad.kind:<3} {dw:>15} {math.degrees(dev):>7.3f} {math.degrees(f.swing):>8.2f} "
            f"{math.degrees(f.transmission_fourbar):>6.1f} {math.degrees(f.transmission_output):>6.1f} "
            f"{f.link_ratio:>6.2f}  {sb.a:.4g} {sb.b:.4g} {sb.c:.4g} {sb.d:.4g}"
        )
    return "\n".join(lines)


def no_match_message(result: QueryResult) -> str:
    req = result.request
    below, above = result.nearest
    head = f"no six-bar meets the request ({result.considered} segments fitted, {result.simulated} simulated)"
    near = [x for x in (below, above) if x is not None]
    if near and min(abs(x - req.dwell) for x in near) <= req.dwell_tol:
        # segments of that dwell exist: it is the dyads that fail the swing or the constraints
        return (f"{head}; the atlas holds segments of that dwell, but none of their six-bars meets the swing and "
                f"constraints: try a larger --max-link-ratio (now {req.max_link_ratio:g}), a lower --min-transmission "
                f"(now {math.degrees(req.min_transmission):g}°), a wider --swing-tol or a larger --dwell-tolerance")
    hint = " and ".join(f"{math.degrees(x):.1f}°" for x in near)
    return (f"{head}; " + (f"the closest dwells the atlas holds are {hint}: " if near else "")
            + "try a wider --dwell-tol, a larger --dwell-tolerance, or a larger atlas")


@click.command("query")
@click.option("--db", "target", required=True, help="Atlas: SQLite file path or SQLAlchemy URL.")
@click.option("--dwell", type=float, required=True, help="Dwell angle (degrees of crank rotation).")
@click.option("--dwell-tol", type=float, default=2.0, show_default=True, help="Allowed dwell-angle error (°).")
@click.option("--swing", type=float, default=None, help="Output swing (°); required for one dwell.")
@click.option("--swing-tol", type=float, default=0.5, show_default=True, help="Allowed swing error (°).")
@click.option("--output", type=str, default="any", show_default=True, help="Output dyad: rpr, rrr or any.")
@click.option("--dwells", type=int, default=1, show_default=True, help="Dwells per turn: 1, or 2 (double Ball point, RPR).")
@click.option("--dwell-tolerance", type=float, default=0.1, show_default=True,
              help="Total width (°) of the output band that counts as a dwell.")
@click.option("--crank", type=float, default=1.0, show_default=True, help="Crank length (your unit).")
@click.option("--min-transmission", type=float, default=30.0, show_default=True, help="Smallest transmission angle (°).")
@click.option("--max-link-ratio", type=float, default=10.0, show_default=True, help="Largest longest/shortest link ratio.")
@click.option("--top", type=int, default=10, show_default=True, help="Candidates returned.")
@click.option("--json", "as_json", is_flag=True, help="JSON on stdout instead of a table.")
@click.option("--report", "report_dir", type=click.Path(file_okay=False), default=None,
              help="Also write the report of the candidates to this folder.")
def query(target, dwell, dwell_tol, swing, swing_tol, output, dwells, dwell_tolerance, crank, min_transmission,
          max_link_ratio, top, as_json, report_dir):
    """Ranked six-bars for a requested dwell and swing (see README: ranking)."""
    request = request_from_options(dwell, dwell_tol, swing, swing_tol, output.lower(), dwells, dwell_tolerance, crank,
                                   min_transmission, max_link_ratio, top)
    if report_dir is not None:
        _check_report_dir(Path(report_dir))
    from db.engine import open_atlas

    engine = open_atlas(target, readonly=True)
    try:
        result = answer(engine, request)
    finally:
        engine.dispose()
    if as_json:
        click.echo(json.dumps({"request": request.to_json(), "candidates": [candidate_json(c) for c in result.candidates]},
                              indent=2, allow_nan=False))
    elif result.candidates:
        click.echo(_table(result))
    if not result.candidates:
        click.echo(f"dwell: {no_match_message(result)}", err=True)
    if report_dir is not None and result.candidates:
        from report.export import write_report

        written = write_report(result.candidates, request, Path(report_dir))
        click.echo(f"report: {len(written)} files in {report_dir}", err=True)


def _check_report_dir(path: Path) -> None:
    if path.exists() and not path.is_dir():
        raise InputError(f"--report {str(path)!r} is a file, not a folder")
    parent = path if path.exists() else path.parent
    if not parent.exists():
        raise InputError(f"--report: folder {str(parent)!r} does not exist")
    from cli.options import probe_folder

    probe_folder(path, "--report")
