"""Which exceptions are the user's input (exit 2, one line) rather than a bug."""

from __future__ import annotations

import click

from kinematics.status import AssemblyError


class InputError(Exception):
    """A problem with what the user typed or pointed at (a file, a database)."""


#: Caught by :func:`cli.main.main`; extend here when a layer adds its own error type.
USER_ERRORS: tuple[type[BaseException], ...] = (click.ClickException, AssemblyError, InputError)


def user_error_line(exc: BaseException) -> str:
    """One line naming the problem (click's usage errors name the option)."""
    if isinstance(exc, click.ClickException):
        msg = exc.format_message()
        ctx = getattr(exc, "ctx", None)
        if ctx is not None and isinstance(exc, click.UsageError):
            msg = f"{ctx.command_path}: {msg}"
    else:
        msg = str(exc)
    return " ".join(msg.split())
