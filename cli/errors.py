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
_LAZY_USER_ERRORS = {"db.engine": "AtlasError", "atlas.sweep": "SweepSpecError"}


def is_user_error(exc: BaseException) -> bool:
    """True for errors caused by input, including those of lazily imported layers."""
    if isinstance(exc, USER_ERRORS):
        return True
    for module, name in _LAZY_USER_ERRORS.items():
        mod = sys.modules.get(module)
        if mod is not None and isinstance(exc, getattr(mod, name)):
            return True
    return False


def user_error_line(exc: BaseException) -> str:
    """One line naming the problem (click's usage errors name the command)."""
    if isinstance(exc, click.ClickException):
        msg = exc.format_message()
        ctx = getattr(exc, "ctx", None)
        if ctx is not None and isinstance(exc, click.UsageError):
            msg = f"{ctx.command_path}: {msg}"
    else:
        msg = str(exc)
    return " ".join(msg.split())
