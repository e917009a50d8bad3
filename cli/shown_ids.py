"""The ids the query has shown, so that ``dwell report`` takes a short id
(:mod:`report.short_id`) as well as the full one.

A short id holds a hash of the full id, not the full id: it is looked up in a small file of
``short<TAB>full`` lines that every table appends to — ``$DWELL_CACHE_DIR/shown-ids.tsv``,
else ``$XDG_CACHE_HOME/dwell-atlas/…``, else ``~/.cache/dwell-atlas/…``. The file keeps the
last :data:`KEEP` ids (older ones are dropped when it grows past twice that); an id no longer
in it is given in full (``dwell query --wide`` or ``--json`` show it).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from cli.errors import InputError
from report.escape import terminal
from report.short_id import SHORT_ID, short_id

__all__ = ["KEEP", "ids_file", "remember", "remember_shown", "resolve"]

#: Ids kept in the file (a line is ~60–90 bytes: under 2 MB at twice this).
KEEP = 10_000


def ids_file() -> Path:
    """Where the shown ids are kept (see the module's text)."""
    base = os.environ.get("DWELL_CACHE_DIR")
    if base:
        return Path(base) / "shown-ids.tsv"
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "dwell-atlas" / "shown-ids.tsv"


def remember(full_ids: Iterable[str]) -> str | None:
    """Append ``full_ids`` (with their short ids) to :func:`ids_file`; None when done, else
    the reason it could not be (the table is shown all the same; only the short ids cannot be
    looked up then)."""
    lines = "".join(f"{short_id(i)}\t{i}\n" for i in full_ids)
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


def resolve(text: str, option: str = "--candidates") -> str | None:
    """The full id a short id ``text`` stands for; None if ``text`` is not shaped as a short
    id (it may be a full one). A short id the query has not shown, or that two shown ids share,
    is the user's error (one line naming ``option``)."""
    if not SHORT_ID.fullmatch(text):
        return None
    path = ids_file()
    try:
        with open(path, encoding="utf-8", errors="replace") as lines:
            # a line counts only if its short id is its full id's: a damaged line is ignored
            found = {
                full
                for short, _, full in (line.rstrip("\n").partition("\t") for line in lines)
                if short == text and _stands_for(full, text)
            }
    except FileNotFoundError:
        found = set()
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
    return found.pop()


def remember_shown(candidates: Iterable) -> None:
    """:func:`remember` the ids of the candidates a table has shown; if they cannot be kept,
    one line on stderr says so (the table stands; only its short ids cannot be looked up)."""
    import click

    problem = remember(c.id for c in candidates)
    if problem is not None:
        click.echo(
            f"dwell: the short ids cannot be kept for dwell report ({terminal(problem)}); "
            "it takes the full ids (--wide or --json)",
            err=True,
        )
