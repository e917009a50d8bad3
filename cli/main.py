"""The ``dwell`` command: one group, one module per subcommand.

Exit status: 0 success, 2 bad input or usage (one line on stderr, nothing written), 1 an
internal error (a bug: the traceback is shown), 130 interrupted.
"""

from __future__ import annotations

import sys

import click

from cli.errors import is_user_error, user_error_line
from cli.lazy import LazyGroup

COMMANDS = {
    "demo": "cli.demo:demo",
    "analyze": "cli.analyze:analyze",
    "curvature": "cli.curvature:curvature",
    "bench": "cli.bench:bench",
    "atlas": "cli.atlas:atlas",
    "query": "cli.query:query",
    "report": "cli.report:report",
}


@click.group(cls=LazyGroup, lazy=COMMANDS, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="dwell-atlas")
def dwell() -> None:
    """Design six-bar dwell mechanisms from an atlas of four-bar coupler curves."""


def main(argv: list[str] | None = None) -> int:
    """Entry point: run ``dwell`` and map errors to exit statuses (never a traceback for input)."""
    from synth.parallel_rows import threads

    try:
        threads()  # $DWELL_THREADS read (and checked) before any work
    except ValueError as exc:
        click.echo(f"dwell: error: {exc}", err=True)
        return 2
    try:
        # without standalone mode click returns the code of ``ctx.exit(n)`` instead of raising
        rv = dwell.main(args=argv, prog_name="dwell", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.exceptions.Abort:
        click.echo("dwell: interrupted", err=True)
        return 130
    except KeyboardInterrupt:
        click.echo("dwell: interrupted", err=True)
        return 130
    except Exception as exc:
        if not is_user_error(exc):
            raise
        click.echo(f"dwell: error: {_secrets_hidden(user_error_line(exc), argv)}", err=True)
        return 2
    return rv if isinstance(rv, int) and not isinstance(rv, bool) else 0


def _secrets_hidden(line: str, argv: list[str] | None) -> str:
    """``line`` with every argument that :func:`db.engine.display_target` would mask (a URL's
    password, a connection string) shown masked: click's usage errors echo arguments as typed
    ("Got unexpected extra arguments (--db host=… password=…)"), wherever they stood."""
    from db.engine import display_target

    for arg in sorted(set(sys.argv[1:] if argv is None else argv), key=len, reverse=True):
        shown = display_target(arg) if isinstance(arg, str) else arg
        if shown != arg and arg in line:
            line = line.replace(arg, shown)
    return line


if __name__ == "__main__":
    sys.exit(main())
