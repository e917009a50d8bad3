"""Work and memory budgets: a request whose size is a product of options is estimated before
anything is allocated, and refused in one line (exit 2) with the estimate when it exceeds the
budget — instead of exhausting the machine or running for hours.

* Memory: half of the memory available when the command starts (``MemAvailable`` of
  ``/proc/meminfo``, else physical memory), :data:`MEMORY_SHARE`.
* Time (benchmarks only: a real atlas build may rightly run all night): ten minutes,
  :data:`BENCH_SECONDS`, estimated from one timed piece of the work where that is cheap
  (``bench curvature``, ``bench query``), else from rates about 3x faster than measured on
  the 2-core reference machine (so such an estimate errs short: nothing is refused that
  would fit).
"""

from __future__ import annotations

import os

from cli.errors import InputError

__all__ = ["BENCH_SECONDS", "MEMORY_SHARE", "available_memory", "check_memory", "check_time"]

#: Share of the available memory one command may plan to use.
MEMORY_SHARE = 0.5
#: Longest a benchmark may be estimated to run (s).
BENCH_SECONDS = 600.0


def available_memory() -> int:
    """Bytes of memory available now (Linux ``MemAvailable``; else the physical memory)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (OSError, ValueError, AttributeError):
        return 8 * 2**30  # unknown: assume a small machine


def _size(n: float) -> str:
    for unit, scale in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n / 1024:.3g} KiB"


def _duration(s: float) -> str:
    if s >= 86400:
        return f"{s / 86400:.3g} days"
    if s >= 3600:
        return f"{s / 3600:.3g} h"
    return f"{s / 60:.3g} min"


def check_memory(need: float, what: str, fix: str) -> None:
    """Refuse (:class:`InputError`) when ``need`` bytes exceed the memory budget.

    ``what`` names the work ("4 096 × 100 000 crank positions"), ``fix`` the options to lower."""
    budget = MEMORY_SHARE * available_memory()
    if need > budget:
        raise InputError(
            f"{what} would need about {_size(need)} of memory, more than this machine's budget of "
            f"{_size(budget)} (half of the memory available): {fix}"
        )


def check_time(seconds: float, what: str, fix: str) -> None:
    """Refuse a benchmark estimated ``seconds`` long, over :data:`BENCH_SECONDS`."""
    if seconds > BENCH_SECONDS:
        raise InputError(
            f"{what} would take about {_duration(seconds)} on this machine (the benchmark budget "
            f"is {_duration(BENCH_SECONDS)}): {fix}"
        )
