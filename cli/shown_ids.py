"""The ids the query has shown, with its settings, so that ``dwell report`` takes a short id
(:mod:`report.short_id`) as well as the full one, and reports it as its table showed it.

A short id holds a hash of the full id, not the full id: it is looked up in a small file of
``short<TAB>full<TAB>settings`` lines that every table appends to — ``$DWELL_CACHE_DIR/shown-ids.tsv``,
else ``$XDG_CACHE_HOME/dwell-atlas/…``, else ``~/.cache/dwell-atlas/…``. ``settings`` is the
JSON object of the showing query's options that ``dwell report`` also takes
(:data:`REPORT_SETTINGS`), so that a short id reports the six-bar as its table showed it (a
line without it, as older tables wrote, is read as none). The file keeps the last :data:`KEEP`
ids (older ones are dropped when it grows past twice that); an id no longer in it is given in
full (``dwell query --wide`` or ``--json`` show it).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from cli.errors import InputError
from report.escape import terminal
from report.short_id import SHORT_ID, short_id

__all__ = ["KEEP", "REPORT_SETTINGS", "Shown", "ids_file", "remember", "remember_shown", "report_settings", "resolve"]

#: Ids kept in the file (a line is ~160–200 bytes with its settings: under 4 MB at twice this).
KEEP = 10_000

#: The options of the showing query kept beside its ids: ``dwell report``'s own (its option
#: names, the query's values in the command's units: degrees, the user's length unit, rev/min).
#: ``units`` is a text, ``tolerance`` None when not given, the others numbers.
REPORT_SETTINGS = ("dwell", "band", "crank", "min_transmission", "rpm", "tolerance", "units")


@dataclass(frozen=True, slots=True)
class Shown:
    """A short id looked up: the full id, and the settings of the last table that showed it
    (by :data:`REPORT_SETTINGS`; None if its line has none or they are damaged)."""

    full: str
    settings: dict | None


def report_settings(request, units: str) -> dict:
    """The :data:`REPORT_SETTINGS` of a query's ``request`` (``synth.query.Request``, at the band
    it answered at) shown in ``units``."""
    return {
        "dwell": math.degrees(request.dwell),
        "band": math.degrees(request.band),
        "crank": request.crank,
        "min_transmission": math.degrees(request.min_transmission),
        "rpm": request.rpm,
        "tolerance": request.tolerance if request.tolerance > 0 else None,
        "units": units,
    }


def _settings(text: str) -> dict | None:
    """The settings of a line's third field; None when missing or not as :func:`report_settings`
    writes them (a damaged or hand-edited line counts as one without)."""
    try:
        found = json.loads(text) if text else None
    except ValueError:
        return None
    if not isinstance(found, dict) or set(found) != set(REPORT_SETTINGS) or not isinstance(found["units"], str):
        return None
    numbers = [found[k] for k in REPORT_SETTINGS if k not in ("units", "tolerance")]
    if found["tolerance"] is not None:
        numbers.append(found["tolerance"])
    ok = all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in numbers)
    return found if ok else None


def ids_file() -> Path:
    """Where the shown ids are kept (see the module's text)."""
    base = os.environ.get("DWELL_CACHE_DIR")
    if base:
        return Path(base) / "shown-ids.tsv"
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "dwell-atlas" / "shown-ids.tsv"


def remember(full_ids: Iterable[str], settings: dict | None = None) -> str | None:
    """Append ``full_ids`` (with their short ids, and the showing query's ``settings``:
    :func:`report_settings`) to :func:`ids_file`; None when done, else the reason it could not
    be (the table is shown all the same; only the short ids cannot be looked up then)."""
    tail = "" if settings is None else "\t" + json.dumps(settings, separators=(",", ":"), allow_nan=False)
    lines = "".join(f"{short_id(i)}\t{i}{tail}\n" for i in full_ids)
    if not lines:
        return None
    path = ids_file()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        # one append of whole lines: two queries writing at once do not mix their lines
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
        try:
            os.write(fd, lines.encode("utf-8"))
            size = os.fstat(fd).st_size
        finally:
            os.close(fd)
        if size > 2 * KEEP * 100:
            _trim(path)
    except OSError as exc:
        return f"{path}: {exc.strerror or exc}"
    return None


def _trim(path: Path) -> None:
    """Keep the last :data:`KEEP` lines (written aside, then renamed over the file)."""
    kept = path.read_text(encoding="utf-8", errors="replace").splitlines(keepends=True)[-KEEP:]
    aside = path.with_name(f".{path.name}.{os.getpid()}")
    aside.write_text("".join(kept), encoding="utf-8")
    os.replace(aside, path)


def _stands_for(full: str, short: str) -> bool:
    try:
        return short_id(full) == short
    except ValueError:  # a damaged line
        return False


def resolve(text: str, option: str = "--candidates") -> Shown | None:
    """The full id a short id ``text`` stands for, with the settings of the last table that
    showed it; None if ``text`` is not shaped as a short id (it may be a full one). A short id
    the query has not shown, or that two shown ids share, is the user's error (one line naming
    ``option``)."""
    if not SHORT_ID.fullmatch(text):
        return None
    path = ids_file()
    found: dict[str, dict | None] = {}  # full id → the settings of its last line
    try:
        with open(path, encoding="utf-8", errors="replace") as lines:
            # a line counts only if its short id is its full id's: a damaged line is ignored
            for short, full, rest in ((line.rstrip("\n").split("\t", 2) + ["", ""])[:3] for line in lines):
                if short == text and _stands_for(full, text):
                    found[full] = _settings(rest)
    except FileNotFoundError:
        pass
    except OSError as exc:
        raise InputError(
            f"{option}: short id {text} cannot be looked up ({path}: {exc}); give the full id "
            "(dwell query --wide or --json shows it)"
        ) from None
    if not found:
        raise InputError(
            f"{option}: short id {text} is not one dwell query has shown here (or no longer kept in "
            f"{terminal(str(path))}); give the full id (dwell query --wide or --json shows it)"
        )
    if len(found) > 1:
        raise InputError(
            f"{option}: short id {text} is ambiguous: it stands for {len(found)} six-bars "
            f"({', '.join(sorted(found))}); give the full id"
        )
    ((full, settings),) = found.items()
    return Shown(full, settings)


def remember_shown(candidates: Iterable, settings: dict | None = None) -> None:
    """:func:`remember` the ids of the candidates a table has shown, with the query's
    ``settings`` (:func:`report_settings`); if they cannot be kept, one line on stderr says so
    (the table stands; only its short ids cannot be looked up)."""
    import click

    problem = remember((c.id for c in candidates), settings)
    if problem is not None:
        click.echo(
            f"dwell: the short ids cannot be kept for dwell report ({terminal(problem)}); "
            "it takes the full ids (--wide or --json)",
            err=True,
        )
