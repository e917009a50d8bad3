"""Which exceptions are the user's input (exit 2, one line) rather than a bug."""

from __future__ import annotations

import sys

import click

from kinematics.status import AssemblyError


class InputError(Exception):
    """A problem with what the user typed or pointed at (a file, a database)."""


#: Always the user's: bad options, linkages that cannot assemble, bad files.
USER_ERRORS: tuple[type[BaseException], ...] = (click.ClickException, AssemblyError, InputError)

#: Error types of layers that are imported only when a command needs them, by module.
_LAZY_USER_ERRORS = {"db.engine": "AtlasError", "atlas.sweep": "SweepSpecError", "report.folder": "ReportFolderError"}


#: SQLite result codes (primary names) that mean the atlas file or its storage, not the code:
#: found while reading or writing an atlas that opened fine (a page damaged in the middle of
#: the file, a file made read-only). What the user can do about each.
_SQLITE_FILE_PROBLEMS = {
    "SQLITE_CORRUPT": "the file is damaged: restore a copy or rebuild the atlas",
    "SQLITE_NOTADB": "the file is damaged: restore a copy or rebuild the atlas",
    "SQLITE_READONLY": "the file or its folder is read-only",
    "SQLITE_CANTOPEN": "the file or its folder cannot be opened for this",
    "SQLITE_PERM": "permission denied",
    "SQLITE_IOERR": "the storage failed",
    "SQLITE_FULL": "the disk is full",
}


#: How pysqlite says a stored text is not UTF-8 (a damaged record; SQLite itself never checks).
_UNDECODABLE = "Could not decode to UTF-8"


def _database_problem(exc: BaseException) -> str | None:
    """The hint for a database error caused by the atlas's file or server, else None."""
    sa_exc = sys.modules.get("sqlalchemy.exc")
    if sa_exc is None or not isinstance(exc, sa_exc.DBAPIError):
        return None
    if exc.connection_invalidated:
        return "the connection to the database server was lost"
    name = getattr(exc.orig, "sqlite_errorname", None) or ""
    if not name and _UNDECODABLE in str(exc.orig):  # pysqlite's own error: a text whose bytes are not UTF-8
        return _SQLITE_FILE_PROBLEMS["SQLITE_CORRUPT"]
    return next(
        (hint for code, hint in _SQLITE_FILE_PROBLEMS.items() if name == code or name.startswith(code + "_")), None
    )


def is_user_error(exc: BaseException) -> bool:
    """True for errors caused by input, including those of lazily imported layers."""
    if isinstance(exc, USER_ERRORS):
        return True
    for module, name in _LAZY_USER_ERRORS.items():
        mod = sys.modules.get(module)
        if mod is not None and isinstance(exc, getattr(mod, name)):
            return True
    return _database_problem(exc) is not None


def user_error_line(exc: BaseException) -> str:
    """One line naming the problem (click's usage errors name the command)."""
    problem = _database_problem(exc)
    if isinstance(exc, click.ClickException):
        msg = exc.format_message()
        ctx = getattr(exc, "ctx", None)
        if ctx is not None and isinstance(exc, click.UsageError):
            msg = f"{ctx.command_path}: {msg}"
    elif problem is not None:
        text = str(exc.orig).strip()  # the driver's words, without SQLAlchemy's statement dump
        if _UNDECODABLE in text:  # not the damaged bytes themselves: they may hold terminal controls
            text = text.split(" with text ", 1)[0]
        msg = f"atlas database error: {text.splitlines()[0] if text else type(exc.orig).__name__} ({problem})"
    else:
        msg = str(exc)
    return " ".join(msg.split())
