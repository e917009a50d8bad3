"""The sweep spec as the database stores it (``build.spec_json``): the one reader of it.

``atlas.sweep.SweepSpec`` writes the spec (its ``to_json``) and validates it for a build; the
database's readers (the query's tolerance levels, ``atlas info``, the writer's messages, the
damaged-atlas check, the benchmarks) need only a few facts of a stored one and must survive a
damaged row, so they read it here: :func:`stored_spec` parses and checks it, the other
functions answer from it.
"""

from __future__ import annotations

import json
import math
from typing import Any

from sqlalchemy import Connection, Engine, select

from db.schema import Build

__all__ = ["SpecError", "last_spec", "spec_name", "stored_spec", "tolerances"]


class SpecError(ValueError):
    """A stored sweep spec that is not a JSON object with finite tolerances."""


def stored_spec(text: str) -> dict[str, Any]:
    """The stored spec ``text`` as a dict; :class:`SpecError` if it is not a JSON object or
    its ``tolerances`` are not finite numbers (the query reads them as its levels)."""
    try:
        spec = json.loads(text)
        ok = isinstance(spec, dict) and all(math.isfinite(float(t)) for t in spec.get("tolerances", []))
    except (ValueError, TypeError):
        ok = False
    if not ok:
        raise SpecError("not a readable sweep spec")
    return spec


def spec_name(text: str) -> str:
    """The preset name of a stored spec (``?`` if it has none or cannot be read)."""
    try:
        return str(stored_spec(text).get("name", "?"))
    except SpecError:
        return "?"


def tolerances(spec: dict[str, Any]) -> list[float]:
    """The path tolerances of the spec's levels (crank lengths), level 0 first."""
    return [float(t) for t in spec.get("tolerances", [])]


def last_spec(bind: Engine | Connection) -> dict[str, Any] | None:
    """The spec of the atlas's newest build (None for an atlas without a build)."""
    stmt = select(Build.spec_json).order_by(Build.id.desc()).limit(1)
    if isinstance(bind, Connection):
        text = bind.execute(stmt).scalar()
    else:
        with bind.connect() as conn:
            text = conn.execute(stmt).scalar()
    return None if text is None else stored_spec(text)
