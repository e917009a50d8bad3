"""Report folders written all at once: a temporary sibling folder renamed into place.

A report is written into ``.NAME.tmp-<pid>`` beside the target folder ``NAME`` and renamed to
``NAME`` only when every file is complete, so a kill, a full disk or any other failure leaves
either the previous complete report or the new complete one — never a mix, never a partial
folder that looks complete. An existing report folder is swapped with the new one in one
step (Linux ``renameat2(RENAME_EXCHANGE)``; elsewhere two renames, with the old folder kept
aside until the new one is in place) and then removed.

A folder is only replaced if the tool wrote everything in it: each report lists its files in
:data:`MARKER`; a folder without that list is accepted only if every entry is a report file
by name (``index.html``, ``candidates.json``, ``NN-<id>-<plot>.svg`` …, as reports written
before the list existed). Any other file (the user's own notes, another program's output)
makes the write refuse, naming the file, before anything is written: reports go into a
folder of their own.

Left-overs of a killed writer (``.NAME.tmp-<pid>``, ``.NAME.old-<pid>`` of a process that no
longer runs) are removed by the next write into ``NAME``.

A single output file (``dwell analyze ... --plot/--draw/--animate``) is written the same way
(:func:`staged_file`): into ``.NAME.tmp-<pid>`` beside it, renamed over ``NAME`` when complete,
so a killed run leaves the previous file or the new one, never a truncated one.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import re
import shutil
from collections.abc import Iterator
from pathlib import Path

__all__ = ["MARKER", "ReportFolderError", "check_report_folder", "staged_file", "staged_folder"]

#: The file in every report folder that lists the files the report wrote, one per line.
MARKER = ".dwell-report"

# The names a report writes (export.write_report): fixed files and NN-<safe id>-<what>.<ext>.
_REPORT_FILE = re.compile(
    r"(index\.html|candidates\.json|candidates\.csv|README\.txt"
    r"|\d{2,}-[A-Za-z0-9._-]+\.(png|svg|dxf|toml))"
)


class ReportFolderError(Exception):
    """A report folder that cannot be written or replaced (message names folder and cause)."""


def _entries_not_ours(out: Path) -> list[str]:
    names = sorted(p.name for p in out.iterdir())
    listed = set()
    with contextlib.suppress(OSError):
        listed = set((out / MARKER).read_text(encoding="utf-8").split("\n")) | {MARKER}
    if listed:
        return [n for n in names if n not in listed]
    return [n for n in names if not (_REPORT_FILE.fullmatch(n) and (out / n).is_file())]


def check_report_folder(out: Path, option: str = "report folder") -> None:
    """Refuse ``out`` unless it is missing, empty, or a report folder the tool wrote.

    Raises :class:`ReportFolderError` (before anything is written)."""
    if not out.exists():
        return
    if not out.is_dir():
        raise ReportFolderError(f"{option} {str(out)!r} is a file, not a folder")
    try:
        foreign = _entries_not_ours(out)
    except OSError as exc:
        raise ReportFolderError(f"{option}: cannot read {str(out)!r}: {exc.strerror}") from None
    if foreign:
        more = f" and {len(foreign) - 1} more" if len(foreign) > 1 else ""
        raise ReportFolderError(
            f"{option} {str(out)!r} holds files dwell did not write ({foreign[0]!r}{more}): "
            "a report replaces its whole folder; choose a new or empty folder"
        )


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, not ours
        return True
    return True


def _staging(out: Path, kind: str = "tmp") -> Path:
    """The sibling ``.NAME.<kind>-<pid>`` a new ``out`` is written into (or an old one set aside)."""
    return out.with_name(f".{out.name}.{kind}-{os.getpid()}")


def _remove_leftovers(out: Path) -> None:
    pattern = re.compile(rf"\.{re.escape(out.name)}\.(tmp|old)-(\d+)")
    for p in out.parent.iterdir():
        m = pattern.fullmatch(p.name)
        if m and int(m.group(2)) != os.getpid() and not _alive(int(m.group(2))):
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    p.unlink()


@contextlib.contextmanager
def staged_file(path: Path) -> Iterator[Path]:
    """Yield a temporary sibling of the file ``path`` to write; when the block ends without an
    error it replaces ``path`` in one rename, otherwise it is removed and ``path`` is as it was.
    The temporary name has no suffix: writers that pick a format by suffix are told it."""
    path = Path(path).absolute()
    with contextlib.suppress(OSError):
        _remove_leftovers(path)
    tmp = _staging(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _exchange(a: Path, b: Path) -> bool:
    """Swap folders ``a`` and ``b`` in one step (Linux renameat2); False if not available."""
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    at_fdcwd, rename_exchange = -100, 2
    return renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0


@contextlib.contextmanager
def staged_folder(out: Path, option: str = "report folder") -> Iterator[Path]:
    """Yield an empty temporary sibling of ``out`` to write the report into; when the block
    ends without an error it becomes ``out`` (replacing a previous report), otherwise it is
    removed and ``out`` is left as it was.

    An :class:`OSError` (disk full, permissions) becomes one :class:`ReportFolderError`."""
    out = Path(out).absolute()
    check_report_folder(out, option)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        _remove_leftovers(out)
        tmp = _staging(out)
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir()
    except OSError as exc:
        raise ReportFolderError(f"{option}: cannot write into {str(out.parent)!r}: {exc.strerror}") from None
    try:
        yield tmp
        if not out.exists():
            os.rename(tmp, out)
        elif _exchange(tmp, out):
            shutil.rmtree(tmp, ignore_errors=True)  # now the previous report
        else:
            old = _staging(out, "old")
            os.rename(out, old)
            try:
                os.rename(tmp, out)
            except OSError:
                os.rename(old, out)
                raise
            shutil.rmtree(old, ignore_errors=True)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        raise ReportFolderError(
            f"{option}: cannot write the report into {str(out)!r}: {exc.strerror or exc}; nothing was changed"
        ) from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
