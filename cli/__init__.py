"""The ``dwell`` command-line interface (click). Owns progress bars, files and exit codes."""

from cli.main import dwell, main

__all__ = ["dwell", "main"]
