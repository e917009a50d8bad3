"""Report export of candidate six-bars (issue #6): JSON, CSV, plots, drawings, DXF and one
self-contained HTML page, written into a folder.

:func:`write_report` is pure of the database: the candidates already carry their six-bar in the
user's units, its figures from the exact simulation, rank and id. Every number written comes
from that six-bar's exact simulation (:func:`synth.mechanism.sixbar.simulate`); no file holds NaN or inf
(JSON has ``null`` where a value does not exist, the CSV an empty cell).

Files (``NN`` the rank, zero-padded; ``ID`` the candidate id made filesystem-safe):

* ``candidates.json`` — ``{"request": …, "candidates": [candidate_json(c) + {"cycle": …}]}``,
  the cycle table at ``step_deg`` crank steps (:data:`report.cycle.CYCLE_COLUMNS`);
* ``candidates.csv`` — one row per candidate, the columns of :data:`CSV_COLUMNS`;
* ``README.txt`` — what every file and every CSV and cycle column holds (units);
* ``NN-ID-motion``, ``-coupler``, ``-transmission`` ``.png`` and ``.svg`` — the plots
  (:data:`report.sixbar_plots.PLOTS`);
* ``NN-ID-drawing.svg`` and ``NN-ID-drawing.dxf`` — the six-bar at mid-dwell, labelled;
* ``NN-ID.toml`` — the six-bar as a linkage file for ``dwell analyze linkage``;
* ``index.html`` — the candidates with animations, plots and dimensions.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from report.candidate_json import candidate_json, request_json
from report.cycle import CYCLE_COLUMNS, Cycle, cycle_json, sixbar_cycle
from report.escape import terminal
from synth.kinds import OutputKind
from synth.query.candidates import Candidate, Request

__all__ = [
    "CSV_COLUMNS",
    "MAX_DWELLS",
    "candidate_row",
    "csv_cell",
    "csv_header",
    "report_json",
    "safe_stem",
    "write_report",
]

#: Dwells per turn a report has columns for (a double Ball point gives two).
MAX_DWELLS = 2


def _dwell_columns(k: int) -> tuple[tuple[str, str, str], ...]:
    return (
        (f"dwell{k}_deg", "deg", f"length of dwell {k} (crank angle over which ψ stays within the band)"),
        (f"dwell{k}_start_deg", "deg", f"crank angle where dwell {k} starts, in [0, 360)"),
        (
            f"dwell{k}_end_deg",
            "deg",
            f"crank angle where dwell {k} ends, in [0, 360) (less than the start when it passes 0)",
        ),
        (
            f"dwell{k}_deviation_deg",
            "deg",
            f"output deviation (peak-to-peak ψ) over a window of the requested dwell length around dwell {k}",
        ),
    )


#: The CSV's columns, in order: (name, unit, meaning). Lengths are in the request's unit
#: (crank = ``Request.crank``); an empty cell means "does not apply" (an RPR has no rocker
#: or rod, a single dwell no second one).
CSV_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("rank", "", "rank of the candidate, 1 = best"),
    ("id", "", "candidate id (<segment>-<rpr|rrr|dbl><slot>@<swing>), rebuilds it from the atlas"),
    ("segment_id", "", "atlas segment the candidate was fitted to"),
    ("output_type", "", "output dyad: RPR (slotted rocker) or RRR (rod and rocker)"),
    ("a", "length", "crank A0-A"),
    ("b", "length", "coupler A-B"),
    ("c", "length", "rocker B0-B"),
    ("d", "length", "ground A0-B0 (A0 = (0, 0), B0 = (d, 0))"),
    ("branch", "", "four-bar assembly branch (+1: B left of the line A->B0, -1 right)"),
    ("u", "length", "coupler point P, x in the coupler frame (origin A, x-axis along A->B)"),
    ("v", "length", "coupler point P, y in the coupler frame"),
    ("pivot_x", "length", "output pivot D, x (fixed frame)"),
    ("pivot_y", "length", "output pivot D, y (fixed frame)"),
    ("rocker", "length", "RRR output rocker D-Q (empty for RPR)"),
    ("rod", "length", "RRR rod P-Q (empty for RPR)"),
    ("dyad_branch", "", "RRR dyad branch (+1: Q left of the line P->D; empty for RPR)"),
    ("rest_x", "length", "RRR: Q's rest position during the dwell, x (empty if not known or RPR)"),
    ("rest_y", "length", "RRR: Q's rest position during the dwell, y"),
    *(col for k in range(1, MAX_DWELLS + 1) for col in _dwell_columns(k)),
    ("swing_deg", "deg", "output swing, max ψ - min ψ over the turn"),
    ("output_deviation_deg", "deg", "largest of the dwells' output deviations (the ranking's objective)"),
    (
        "toleranced_deviation_deg",
        "deg",
        "with --tolerance: 95th percentile of output_deviation_deg over 256 six-bars "
        "made within it (the ranking's objective then; empty otherwise)",
    ),
    ("transmission_fourbar_min_deg", "deg", "smallest four-bar transmission angle over the turn, in [0, 90]"),
    (
        "transmission_output_min_deg",
        "deg",
        "smallest output transmission angle over the turn (RRR; empty for RPR, whose slot transmits at 90)",
    ),
    ("link_ratio", "", "longest over shortest link length"),
    ("footprint", "length^2", "area of the convex hull of the pivots and joint paths"),
)


def csv_header() -> list[str]:
    """The CSV's column names, in order."""
    return [name for name, _, _ in CSV_COLUMNS]


def safe_stem(candidate: Candidate) -> str:
    """``NN-ID``: the rank zero-padded and the id with every character outside
    ``[A-Za-z0-9._-]`` replaced by ``_`` (at most 60 characters), safe on every filesystem;
    the rank keeps stems unique."""
    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", candidate.id).strip("._") or "candidate"
    return f"{int(candidate.rank):02d}-{safe[:60]}"


# --------------------------------------------------------------------------------------------
# JSON and CSV
# --------------------------------------------------------------------------------------------


def _finite(x: float | None) -> float | None:
    """Plain float, or None for a missing or non-finite value (JSON/CSV never hold NaN)."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _clean(value: Any) -> Any:
    """``value`` with every non-finite float replaced by None (nested lists/dicts)."""
    if isinstance(value, float):
        return _finite(value)
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    return value


def report_json(
    request: Request, candidates: Sequence[Candidate], cycles: Sequence[Cycle], step_deg: float = 1.0, units: str = ""
) -> dict:
    """The ``candidates.json`` document: the request, and per candidate the query's JSON shape
    (:func:`report.candidate_json.candidate_json`, lengths in ``units``) plus its ``cycle`` table."""
    items = []
    for c, cyc in zip(candidates, cycles, strict=True):
        doc = candidate_json(c, request.rpm, units)
        doc["cycle"] = {"step_deg": float(step_deg), **cycle_json(cyc, c.sixbar.dyad.kind)}
        items.append(doc)
    return _clean(
        {
            "request": request_json(request, units),
            "conventions": {
                "lengths": "request unit (crank = request.crank)",
                "angles": "degrees; psi derivatives per radian of crank",
                "frame": "A0 = (0, 0), B0 = (d, 0), y up; coupler point in the coupler frame (origin A, x along A->B)",
                "cycle_columns": {key: {"unit": unit, "meaning": meaning} for key, unit, meaning in CYCLE_COLUMNS},
            },
            "candidates": items,
        }
    )


def json_document_text(doc: dict) -> str:
    """``doc`` indented for reading, except each cycle column, which stays on one line (a
    column per line keeps the file a few times smaller and still diffable). Strict JSON: a
    NaN or inf raises instead of being written."""
    cycles = [c.pop("cycle") for c in doc["candidates"]]
    try:
        for k, c in enumerate(doc["candidates"]):
            c["cycle"] = f"@@cycle{k}@@"
        text = json.dumps(doc, indent=1, allow_nan=False, ensure_ascii=False)
    except ValueError:
        raise ValueError(f"the report would hold a non-finite number at {_non_finite(doc)}: nothing written") from None
    finally:
        for c, cyc in zip(doc["candidates"], cycles):
            c["cycle"] = cyc
    for k, cyc in enumerate(cycles):
        inner = ",\n".join(f"   {json.dumps(key)}: {_compact(v)}" for key, v in cyc.items())
        text = text.replace(f'"@@cycle{k}@@"', "{\n" + inner + "\n  }", 1)
    return text


def _compact(value: Any) -> str:
    try:
        return json.dumps(value, separators=(",", ":"), allow_nan=False, ensure_ascii=False)
    except ValueError:
        raise ValueError(
            f"the report would hold a non-finite number at {_non_finite(value)}: nothing written"
        ) from None


def _non_finite(value: Any, where: str = "") -> str | None:
    """The JSON path of the first NaN or infinity in ``value`` (None if there is none)."""
    if isinstance(value, float) and not math.isfinite(value):
        return where or "top level"
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list | tuple) else ()
    for key, v in items:
        found = _non_finite(v, f"{where}/{key}")
        if found:
            return found
    return None


def candidate_row(c: Candidate) -> dict[str, Any]:
    """One CSV row (column name → value; None for an empty cell), :data:`CSV_COLUMNS` order."""
    sb, f, dy = c.sixbar, c.figures, c.sixbar.dyad
    rrr = dy.kind == OutputKind.RRR
    rest = c.dwell_position if rrr else None
    row: dict[str, Any] = {
        "rank": int(c.rank),
        "id": c.id,
        "segment_id": int(c.segment_id),
        "output_type": dy.kind,
        "a": sb.a,
        "b": sb.b,
        "c": sb.c,
        "d": sb.d,
        "branch": int(sb.branch),
        "u": sb.u,
        "v": sb.v,
        "pivot_x": dy.pivot.real,
        "pivot_y": dy.pivot.imag,
        "rocker": dy.rocker if rrr else None,
        "rod": dy.rod if rrr else None,
        "dyad_branch": int(dy.branch) if rrr else None,
        "rest_x": None if rest is None else rest.real,
        "rest_y": None if rest is None else rest.imag,
    }
    for k in range(1, MAX_DWELLS + 1):
        d = f.dwells[k - 1] if k <= len(f.dwells) else None
        dev = f.deviations[k - 1] if k <= len(f.deviations) else None
        row[f"dwell{k}_deg"] = None if d is None else math.degrees(d.angle)
        row[f"dwell{k}_start_deg"], row[f"dwell{k}_end_deg"] = (None, None) if d is None else d.ends_deg()
        row[f"dwell{k}_deviation_deg"] = None if dev is None else math.degrees(dev)
    row |= {
        "swing_deg": math.degrees(f.swing),
        "output_deviation_deg": math.degrees(max(f.deviations)) if f.deviations else None,
        "toleranced_deviation_deg": None if c.toleranced_deviation is None else math.degrees(c.toleranced_deviation),
        "transmission_fourbar_min_deg": math.degrees(f.transmission_fourbar),
        "transmission_output_min_deg": None if dy.kind == "RPR" else math.degrees(f.transmission_output),
        "link_ratio": f.link_ratio,
        "footprint": f.footprint,
    }
    return {k: _finite(v) if isinstance(v, float) else v for k, v in row.items()}


#: First characters that make a spreadsheet read a cell as a formula (or a command: DDE).
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def csv_cell(value: Any) -> str:
    """One CSV cell: ``repr`` of a float (round-trips exactly), ``""`` for None; text that a
    spreadsheet would evaluate (starting with ``= + - @``, tab or CR: a candidate id read from
    an atlas is not ours to trust) gets a leading ``'``, which makes it text, and control
    characters are shown as escapes (:func:`report.escape.terminal`)."""
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    text = str(value)
    if text.startswith(_FORMULA_START):
        text = "'" + text
    return terminal(text)


def _csv_text(candidates: Sequence[Candidate]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(csv_header())
    for c in candidates:
        row = candidate_row(c)
        writer.writerow([csv_cell(row[k]) for k in csv_header()])
    return buf.getvalue()


def _heading(text: str) -> list[str]:
    return [text, "-" * len(text)]


def _readme(request: Request, stems: Sequence[str], units: str) -> str:
    from report.dxf import LAYERS
    from report.sixbar_plots import PLOTS

    lines = [
        "Dwell Atlas report",
        "==================",
        "",
        f"Request: {json.dumps(request_json(request, units), allow_nan=False)}",
        "Lengths in the request's unit (crank = request.crank); angles in degrees; fixed frame",
        "A0 = (0, 0), B0 = (d, 0), y up. Every figure comes from the exact simulation of the six-bar.",
        "",
        *_heading("Files (NN = rank, ID = candidate id made filesystem-safe)"),
    ]
    files = [
        ("index.html", "the candidates: table, animation, psi(phi) strip, dimensions, plots (self-contained)"),
        ("candidates.json", "request + per candidate its dimensions, figures and full cycle table"),
        ("candidates.csv", "one row per candidate (columns below)"),
    ]
    files += [(f"NN-ID-{name}.png/.svg", what) for name, what in PLOTS.items()]
    files += [
        ("NN-ID-drawing.svg", "the six-bar at mid-dwell, pivots and link lengths labelled"),
        ("NN-ID.toml", "the six-bar as a linkage file: dwell analyze linkage NN-ID.toml --limits gives its figures"),
        ("NN-ID-drawing.dxf", "the same geometry for CAD ($INSUNITS from --units), layers:"),
    ]
    files += [(f"  {name}", what) for name, (_, what) in LAYERS.items()]
    width = max(len(n) for n, _ in files)
    lines += [f"{name:<{width}}  {what}" for name, what in files]
    lines += ["", "Candidates: " + ", ".join(stems), "", *_heading("candidates.csv columns")]
    width = max(len(n) for n, _, _ in CSV_COLUMNS)
    for name, unit, meaning in CSV_COLUMNS:
        lines.append(f"{name:<{width}}  [{unit or '-'}]  {meaning}")
    lines += [
        "",
        *_heading("candidates.json cycle columns (one list per key, one value per crank step; null = does not exist)"),
    ]
    width = max(len(n) for n, _, _ in CYCLE_COLUMNS)
    for name, unit, meaning in CYCLE_COLUMNS:
        lines.append(f"{name:<{width}}  [{unit or '-'}]  {meaning}")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# The report
# --------------------------------------------------------------------------------------------


def write_report(
    candidates: list[Candidate],
    request: Request,
    out_dir: Path,
    *,
    step_deg: float = 1.0,
    option: str = "report folder",
    units: str = "",
    on_candidate: Callable[[int, int], None] | None = None,
    map_candidates: Callable | None = None,
) -> list[Path]:
    """Write the report of ``candidates`` (ranked, in the user's units) for ``request`` into
    ``out_dir``: written into a temporary sibling folder that replaces ``out_dir`` when
    complete (:func:`report.folder.staged_folder`; a folder holding files the tool did not
    write is refused).

    Parameters
    ----------
    candidates : list of Candidate
        In the order to show (normally rank order); ranks must be distinct.
    request : Request
        The request they answer (shown, and used for the requested minimum transmission line).
    out_dir : Path
    step_deg : float
        Crank step of the cycle tables and the animation (deg, a divisor of 360).
    option : str
        How messages name the folder (e.g. ``"--out"``).
    units : str
        Name of the candidates' length unit (``""`` unitless): drawing labels and the DXF's
        ``$INSUNITS``.
    on_candidate : callable, optional
        ``on_candidate(done, total)`` after each candidate's files (its plots take most of a
        report's time), for a progress display.
    map_candidates : callable, optional
        ``map_candidates(fn, jobs)`` yields ``fn(job)`` for every job, in any order: how the
        candidates' files are written (:func:`report.candidate_files.candidate_files`; default
        the built-in :func:`map`, in this process; the ``dwell`` commands pass a process pool
        for a report of several candidates). The files are the same either way.

    Returns
    -------
    list of Path
        Every file written: ``candidates.json``, ``candidates.csv``, ``README.txt``, per
        candidate its plots, drawing and DXF, and ``index.html`` last.

    Raises
    ------
    ValueError
        No candidates, two with the same rank, or a ``step_deg`` that does not divide 360° —
        before anything is written.
    report.folder.ReportFolderError
        ``out_dir`` holds other files, or writing failed (disk full …): ``out_dir`` is as before.
    """
    from report.candidate_files import CandidateJob, candidate_files
    from report.folder import MARKER, check_report_folder, staged_folder
    from report.html_page import PageEntry, render_page
    from report.linkage_toml import linkage_toml
    from report.sixbar_drawing import sixbar_geometry

    if not candidates:
        raise ValueError("no candidates to report")
    ranks = [int(c.rank) for c in candidates]
    if len(set(ranks)) != len(ranks):
        raise ValueError(f"candidate ranks must be distinct, got {ranks}")
    # Everything that can fail on the data is computed before the first file is written.
    cycles = [sixbar_cycle(c.sixbar, c.figures, step_deg=step_deg) for c in candidates]
    doc = report_json(request, candidates, cycles, step_deg, units)
    json_text = json_document_text(doc)
    csv_text = _csv_text(candidates)
    stems = [safe_stem(c) for c in candidates]

    final = Path(out_dir)
    check_report_folder(final, option)
    written = []
    # all files go into a temporary sibling renamed into place at the end (report/folder.py)
    with staged_folder(final, option) as out:
        for name, text in (
            ("candidates.json", json_text),
            ("candidates.csv", csv_text),
            ("README.txt", _readme(request, stems, units)),
        ):
            (out / name).write_text(text, encoding="utf-8")
            written.append(out / name)

        jobs = [
            CandidateJob(
                k,
                c,
                cyc,
                sixbar_geometry(c, cyc, units=units),
                out,
                stem,
                request.min_transmission,
                linkage_toml(c, units, band=request.band, dwells=request.dwells, leave=request.swing_tol),
            )
            for k, (c, cyc, stem) in enumerate(zip(candidates, cycles, stems))
        ]
        done = {}
        for made in (map_candidates or map)(candidate_files, jobs):
            done[made.index] = made
            if on_candidate is not None:
                on_candidate(len(done), len(jobs))
        entries = []
        for job in jobs:
            made = done[job.index]
            written += made.files
            entries.append(
                PageEntry(
                    job.candidate,
                    job.cycle,
                    job.geometry,
                    {k: pf.svg_text for k, pf in made.plots.items()},
                    [p.name for p in made.files],
                )
            )
        page = out / "index.html"
        page.write_text(render_page(request, entries, units=units), encoding="utf-8")
        written.append(page)
        (out / MARKER).write_text("\n".join(p.name for p in written) + "\n", encoding="utf-8")
    return [final / p.name for p in written]
