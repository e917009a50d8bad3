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

__all__ = ["SPEC_RANGES", "SpecError", "last_spec", "spec_name", "stored_spec", "tolerances"]


class SpecError(ValueError):
    """A stored sweep spec that is not what a build writes: not a JSON object, or a field of
    the wrong type or out of range (the message names the field)."""


#: The bounds a build's spec keeps (``atlas.sweep``'s ``SAMPLES_RANGE``, ``RAYS_RANGE``,
#: ``SHARD_SIZE_RANGE``, ``CRANK_STEP_RANGE_DEG``, ``PROPORTION_RANGE``, ``TOLERANCE_RANGE``;
#: ``tests/db/test_spec.py`` holds them equal — ``db`` does not import ``atlas``).
SPEC_RANGES: dict[str, tuple[float, float]] = {
    "samples": (1, 2**31),
    "rays": (1, 3600),
    "shard_size": (1, 1_000_000),
    "seed": (0, 2**63 - 1),
    "crank_step_deg": (0.05, 30.0),
    "proportion": (1e-3, 1e3),
    "tolerance": (1e-9, 1.0),
    "min_dwell_deg": (0.0, 360.0),
}


def _integer(spec: dict[str, Any], key: str) -> None:
    value, (lo, hi) = spec[key], SPEC_RANGES[key]
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise SpecError(f"{key} is {value!r}, not a whole number from {lo} to {hi}")


def _number(value: Any, key: str, bounds: tuple[float, float]) -> float:
    lo, hi = bounds
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or not lo <= value <= hi
    ):
        raise SpecError(f"{key} is {value!r}, not a number from {lo:g} to {hi:g}")
    return float(value)


def _check_fields(spec: dict[str, Any]) -> None:
    """The types and ranges of the fields a build wrote (a field that is absent is left to
    the reader's default: specs of older builds lack some)."""
    for key in ("samples", "rays", "shard_size", "seed"):
        if key in spec:
            _integer(spec, key)
    if "crank_step_deg" in spec:
        _number(spec["crank_step_deg"], "crank_step_deg", SPEC_RANGES["crank_step_deg"])
    if "min_dwell_deg" in spec:
        _number(spec["min_dwell_deg"], "min_dwell_deg", SPEC_RANGES["min_dwell_deg"])
    for key in ("b", "c", "d"):
        if key in spec:
            pair = spec[key]
            if not isinstance(pair, list) or len(pair) != 2:
                raise SpecError(f"{key} is {pair!r}, not a range [low, high]")
            low, high = (_number(v, key, SPEC_RANGES["proportion"]) for v in pair)
            if low > high:
                raise SpecError(f"{key} is {pair!r}: low above high")
    tols = spec.get("tolerances", [])
    if not isinstance(tols, list):
        raise SpecError(f"tolerances is {tols!r}, not a list")
    values = [_number(t, "tolerances", SPEC_RANGES["tolerance"]) for t in tols]
    if any(b <= a for a, b in zip(values, values[1:])):
        raise SpecError(f"tolerances {tols!r} do not increase")
    if "branches" in spec and (
        not isinstance(spec["branches"], list)
        or not spec["branches"]
        or any(b not in (1, -1) or isinstance(b, bool) for b in spec["branches"])
    ):
        raise SpecError(f"branches is {spec['branches']!r}, not a list of 1 and -1")
    if "crank_rockers_only" in spec and not isinstance(spec["crank_rockers_only"], bool):
        raise SpecError(f"crank_rockers_only is {spec['crank_rockers_only']!r}, not true or false")
    if "name" in spec and not isinstance(spec["name"], str):
        raise SpecError(f"name is {spec['name']!r}, not a text")


def stored_spec(text: str) -> dict[str, Any]:
    """The stored spec ``text`` as a dict; :class:`SpecError` if it is not a JSON object, or
    one of its fields has the wrong type or lies out of the range a build keeps (its
    tolerances are the query's levels, its samples and shard size what a resume recomputes)."""
    try:
        spec = json.loads(text, parse_constant=float)  # NaN, Infinity: read, then refused below
    except (ValueError, TypeError, RecursionError):
        raise SpecError("not JSON") from None
    if not isinstance(spec, dict):
        raise SpecError("not a JSON object")
    _check_fields(spec)
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
