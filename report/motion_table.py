"""A table of motion over crank angles: named columns with units, as text or JSON.

Every ``dwell analyze`` subcommand builds one :class:`MotionTable`; this module is the single
place that decides how such tables look and how units enter JSON key names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Column", "MotionTable", "unit_key"]


def unit_key(unit: str) -> str:
    """Unit as it appears in a JSON key: ``"mm/s^2" → "mm_s2"``, ``"rad/s" → "rad_s"``."""
    return unit.replace("/", "_").replace("^", "").replace(" ", "")


@dataclass(frozen=True, slots=True)
class Column:
    """One quantity over the crank angles: ``name`` (e.g. ``"omega3"``), ``unit`` and values."""

    name: str
    unit: str
    values: np.ndarray
    label: str = ""  #: longer description for plots and the table legend

    @property
    def key(self) -> str:
        return f"{self.name}_{unit_key(self.unit)}" if self.unit else self.name


@dataclass(frozen=True, slots=True)
class MotionTable:
    """Columns over the same crank angles (first column is the crank angle in degrees).

    ``summary`` carries scalar results (limit positions, stroke, time ratio); ``mechanism`` the
    inputs. Both go into the JSON document as they are, so they must hold plain JSON values.
    """

    mechanism: dict[str, Any]
    columns: list[Column]
    summary: dict[str, Any] = field(default_factory=dict)

    def column(self, name: str) -> Column:
        for col in self.columns:
            if col.name == name:
                return col
        raise KeyError(name)

    def to_json(self) -> dict[str, Any]:
        """One JSON document: the mechanism, one object per crank angle, and the summary."""
        n = len(self.columns[0].values)
        rows = [{col.key: _json_float(col.values[i]) for col in self.columns} for i in range(n)]
        return {"mechanism": self.mechanism, "positions": rows, "summary": self.summary}

    def to_text(self, digits: int = 7) -> str:
        """A fixed-width table; the header shows each column's name and unit."""
        heads = [f"{c.name}[{c.unit}]" if c.unit else c.name for c in self.columns]
        cells = [[_fmt(v, digits, _scale(col.values)) for v in col.values] for col in self.columns]
        widths = [max(len(h), *(len(x) for x in cs)) for h, cs in zip(heads, cells)]
        lines = ["  ".join(h.rjust(w) for h, w in zip(heads, widths))]
        for i in range(len(cells[0])):
            lines.append("  ".join(cs[i].rjust(w) for cs, w in zip(cells, widths)))
        return "\n".join(lines)


def _scale(values: np.ndarray) -> float:
    finite = np.abs(values[np.isfinite(values)])
    return float(finite.max()) if finite.size else 0.0


def _fmt(value: float, digits: int, scale: float = 0.0) -> str:
    if not math.isfinite(value):
        return "-"
    # rounding noise of an exact zero (a velocity at a dead centre) reads as 0 in the table;
    # JSON keeps the computed value
    if abs(value) <= 1e-12 * scale or value == 0:
        return "0"
    return f"{value:.{digits}g}"


def _json_float(value: float) -> float | None:
    v = float(value)
    return v if math.isfinite(v) else None
