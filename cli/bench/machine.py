"""The machine a benchmark ran on, as every ``dwell bench`` report names it."""

from __future__ import annotations

import os
import platform

import numpy as np

__all__ = ["machine_facts"]


def machine_facts() -> dict:
    """Python and numpy versions, the processor architecture and the CPUs the OS reports (the
    figures of a report are this machine's: a run elsewhere is compared by these)."""
    return {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "machine": platform.machine(),
        "cpus": os.cpu_count(),
    }
