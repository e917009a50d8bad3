"""Mechanism description files (TOML or JSON) → a validated :class:`~kinematics.assur.model.Linkage`.

The format is documented with examples in ``docs/linkage-files.md``. In short::

    name = "Four-bar"
    units = "mm"

    [ground]                      # fixed points, global coordinates
    A0 = [0, 0]
    B0 = [100, 0]

    [links.crank]                 # a binary link: two joints and the distance between them
    joints = ["A0", "A"]
    length = 50

    [links.coupler]               # any link: named points in its own frame
    points = { A = [0, 0], B = [80, 0], P = [40, 30] }

    [[prismatic]]                 # a slider: block runs on a line of the guide link
    name = "s"
    guide = "ground"
    block = "slider"
    through = [0, -20]
    angle = 0

    [[inputs]]
    joint = "A0"                  # drives the angle of the crank relative to the ground
    link = "crank"

A point name shared by several links (the ground included) is a revolute joint; a name used
by one link only is a tracer point. Every error names the link, joint or key at fault.
"""

from __future__ import annotations

import json
import math
import sys
import tomllib
from collections.abc import Mapping
from typing import Any

from kinematics.assur.model import (
    GROUND,
    Input,
    Link,
    Linkage,
    LinkageFileError,
    Output,
    PrismaticPair,
    RevolutePair,
)
from kinematics.assur.positions import MAX_CONFIGURATIONS

__all__ = [
    "MAX_CHARS",
    "MAX_DEPTH",
    "MAX_LINKS",
    "MAX_NAME",
    "plain_text_problem",
    "linkage_from_mapping",
    "linkage_from_text",
    "nesting_depth",
]

_TOP_KEYS = {"name", "units", "configuration", "ground", "links", "prismatic", "inputs", "output"}
_LINK_KEYS = {"joints", "length", "points"}
_PRISMATIC_KEYS = {"name", "guide", "block", "through", "angle", "toward", "block_point", "block_angle"}
_INPUT_KEYS = {"joint", "link", "relative_to", "value", "range"}
_OUTPUT_KEYS = {"link", "joint", "band", "dwells", "leave"}
#: Joints closer than this (relative to the linkage size) count as one point.
_COINCIDENT = 1e-12

#: Limits of a description, each refused in one line before the work it would cause (a real
#: linkage is far inside them): characters of the text, nesting of arrays and tables (a
#: description nests 3 deep; parsers recurse per level), links and ground points, points of one
#: link, prismatic pairs, inputs.
MAX_CHARS = 1_000_000
MAX_DEPTH = 16
MAX_LINKS = 1000
MAX_POINTS_PER_LINK = 100
MAX_PRISMATIC = 1000
MAX_INPUTS = 100


def _shown(value: Any) -> str:
    """``repr(value)`` cut to 60 characters: an error line stays a line."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def nesting_depth(text: str, fmt: str) -> int:
    """Deepest nesting of ``[``/``{`` in a TOML or JSON text, outside strings and comments
    (a TOML table header counts while it is open)."""
    toml = fmt == "toml"
    depth = deepest = 0
    i, n = 0, len(text)
    while i < n:
        ch = text[i]
        if ch == '"' or (toml and ch == "'"):
            quote = ch * 3 if toml and text.startswith(ch * 3, i) else ch
            i += len(quote)
            while i < n and not text.startswith(quote, i):
                i += 2 if ch == '"' and text[i] == "\\" else 1
            i += len(quote)
            continue
        if toml and ch == "#":
            end = text.find("\n", i)
            i = n if end < 0 else end
            continue
        if ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
        i += 1
    return deepest


def linkage_from_text(text: str, fmt: str = "toml") -> Linkage:
    """Parse a TOML (``fmt="toml"``) or JSON (``fmt="json"``) description and validate it.

    Raises :class:`LinkageFileError` (an :class:`~kinematics.status.AssemblyError`) with one
    line naming the problem.
    """
    if fmt not in ("toml", "json"):
        raise ValueError(f"fmt must be 'toml' or 'json', not {fmt!r}")
    if len(text) > MAX_CHARS:
        raise LinkageFileError(f"the description has {len(text):,} characters; at most {MAX_CHARS:,}")
    depth = nesting_depth(text, fmt)
    if depth > MAX_DEPTH:
        raise LinkageFileError(f"arrays/tables nest {depth} deep; a description nests at most {MAX_DEPTH} deep")
    try:
        data = tomllib.loads(text) if fmt == "toml" else json.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise LinkageFileError(f"not valid {fmt.upper()}: {exc}") from None
    except ValueError:  # an integer of more than 4 300 digits (Python's limit of int())
        raise LinkageFileError(
            f"not valid {fmt.upper()}: an integer has more than {sys.get_int_max_str_digits()} digits"
        ) from None
    return linkage_from_mapping(data)


def linkage_from_mapping(data: Any) -> Linkage:
    """Build and validate a :class:`Linkage` from parsed TOML/JSON data (see module docs)."""
    if not isinstance(data, Mapping):
        raise LinkageFileError("the description must be a table/object at the top level")
    _no_unknown_keys(data, _TOP_KEYS, "the description")
    name = _text(data.get("name", "linkage"), "'name'")
    units = _text(data.get("units", "mm"), "'units'")

    ground_raw = data.get("ground", {})
    if not isinstance(ground_raw, Mapping):
        raise LinkageFileError("[ground] must be a table of point = [x, y]")
    if len(ground_raw) > MAX_LINKS:
        raise LinkageFileError(f"[ground] has {len(ground_raw)} points; at most {MAX_LINKS}")
    links: list[Link] = [
        Link(
            GROUND, {_text(k, "a ground point's name"): _point(v, f"ground point {k!r}") for k, v in ground_raw.items()}
        )
    ]

    links_raw = data.get("links", {})
    if not isinstance(links_raw, Mapping) or not links_raw:
        raise LinkageFileError("[links] must define at least one moving link")
    if len(links_raw) > MAX_LINKS:
        raise LinkageFileError(f"[links] defines {len(links_raw)} links; at most {MAX_LINKS}")
    for lname, spec in links_raw.items():
        if lname == GROUND:
            raise LinkageFileError(f"link name {GROUND!r} is reserved for the fixed link; use [ground]")
        links.append(_link(_text(lname, "a link's name"), spec))
    index = {link.name: i for i, link in enumerate(links)}

    prismatic_raw = _array(data, "prismatic")
    if len(prismatic_raw) > MAX_PRISMATIC:
        raise LinkageFileError(f"{len(prismatic_raw)} [[prismatic]] pairs; at most {MAX_PRISMATIC}")
    prismatic = [_prismatic(k, spec, links, index) for k, spec in enumerate(prismatic_raw)]
    point_names = {p for link in links for p in link.points}
    seen_pairs: set[str] = set()
    for pair in prismatic:
        if pair.joint in point_names:
            raise LinkageFileError(f"prismatic pair {pair.joint!r}: the name is already a point name; pick another")
        if pair.joint in seen_pairs:
            raise LinkageFileError(f"prismatic pair {pair.joint!r} is defined twice")
        seen_pairs.add(pair.joint)

    inputs_raw = _array(data, "inputs")
    if len(inputs_raw) > MAX_INPUTS:
        raise LinkageFileError(f"{len(inputs_raw)} [[inputs]]; at most {MAX_INPUTS}")
    centres = _compound_centres(inputs_raw, index)
    revolute = _revolute_pairs(links, centres)
    pairs = tuple(revolute + prismatic)
    _check_pairs(links, pairs)

    inputs = tuple(_input(k, spec, links, index, pairs) for k, spec in enumerate(inputs_raw))
    driven = [i.pair for i in inputs]
    if len(set(driven)) != len(driven):
        raise LinkageFileError("two inputs drive the same joint")
    output = _output(data.get("output"), links, index, pairs)
    configuration = _configuration(data.get("configuration"))
    linkage = Linkage(name, units, tuple(links), pairs, inputs, output, configuration)
    _check_dof(linkage)
    return linkage


# -- pieces -----------------------------------------------------------------------------------


def _no_unknown_keys(spec: Mapping, allowed: set[str], where: str) -> None:
    unknown = sorted(set(map(str, spec)) - allowed)
    if unknown:
        raise LinkageFileError(f"{where}: unknown key {unknown[0]!r} (expected one of {', '.join(sorted(allowed))})")


#: Most characters of a name (the linkage's, a unit's, a link's, a point's, a pair's): names
#: are labels, and every drawing and table repeats them.
MAX_NAME = 200


def _unsafe(ch: str) -> bool:
    """A control character (C0, DEL, C1) or a bidirectional override/isolate (U+202A–202E,
    U+2066–2069): they would act on a terminal or break XML instead of showing as text."""
    o = ord(ch)
    return o < 0x20 or 0x7F <= o <= 0x9F or 0x202A <= o <= 0x202E or 0x2066 <= o <= 0x2069


def plain_text_problem(value: str, limit: int = MAX_NAME) -> str | None:
    """Why ``value`` is not a plain name (too long, or a control character or bidirectional
    override in it), or None."""
    if len(value) > limit:
        return f"has {len(value):,} characters; a name has at most {limit}"
    bad = next((ch for ch in value if _unsafe(ch)), None)
    if bad is not None:
        return f"{_shown(value)} holds the control character U+{ord(bad):04X}; names are plain text"
    return None


def _text(value: Any, where: str) -> str:
    """A name or label of the file: a string of at most MAX_NAME characters, none of them a
    control character or a bidirectional override (one line naming the first)."""
    if not isinstance(value, str):
        raise LinkageFileError(f"{where} must be a string, got {_shown(value)}")
    problem = plain_text_problem(value)
    if problem:
        raise LinkageFileError(f"{where} {problem}")
    return value


#: Largest magnitude of a number in a file: squares and products of two stay finite.
MAX_MAGNITUDE = 1e150


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise LinkageFileError(f"{where} must be a finite number, got {_shown(value)}")
    try:
        x = float(value)
    except OverflowError:  # an integer beyond float range
        x = math.inf
    if not math.isfinite(x) or abs(x) > MAX_MAGNITUDE:
        raise LinkageFileError(
            f"{where} must be a finite number of magnitude at most {MAX_MAGNITUDE:g}, got {_shown(value)}"
        )
    return x


def _point(value: Any, where: str) -> complex:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise LinkageFileError(f"{where} must be [x, y], got {_shown(value)}")
    return complex(_number(value[0], f"{where} x"), _number(value[1], f"{where} y"))


def _array(data: Mapping, key: str) -> list[Mapping]:
    raw = data.get(key, [])
    if isinstance(raw, Mapping):
        raw = [raw]
    if not isinstance(raw, list) or not all(isinstance(x, Mapping) for x in raw):
        raise LinkageFileError(f"[[{key}]] must be an array of tables")
    return raw


def _link(name: str, spec: Any) -> Link:
    where = f"link {name!r}"
    if not isinstance(spec, Mapping):
        raise LinkageFileError(f"{where} must be a table with 'joints' and 'length', or 'points'")
    _no_unknown_keys(spec, _LINK_KEYS, where)
    points: dict[str, complex] = {}
    if "joints" in spec or "length" in spec:
        joints = spec.get("joints")
        if "length" not in spec:
            raise LinkageFileError(f"{where}: 'joints' needs 'length' (the distance between them)")
        if not isinstance(joints, list) or len(joints) != 2 or not all(isinstance(j, str) for j in joints):
            raise LinkageFileError(f"{where}: 'joints' must name two joints, got {_shown(joints)}")
        for j in joints:
            _text(j, f"{where}: a joint's name")
        if joints[0] == joints[1]:
            raise LinkageFileError(f"{where}: 'joints' names {joints[0]!r} twice")
        length = _number(spec["length"], f"{where} 'length'")
        if length <= 0:
            raise LinkageFileError(f"{where}: 'length' must be > 0, got {length:g}")
        points = {joints[0]: 0j, joints[1]: complex(length, 0.0)}
    extra = spec.get("points", {})
    if not isinstance(extra, Mapping):
        raise LinkageFileError(f"{where}: 'points' must be a table of name = [x, y]")
    if len(extra) > MAX_POINTS_PER_LINK:
        raise LinkageFileError(f"{where} has {len(extra)} points; at most {MAX_POINTS_PER_LINK}")
    for pname, value in extra.items():
        if pname in points:
            raise LinkageFileError(f"{where}: point {pname!r} is already placed by 'joints'")
        points[_text(pname, f"{where}: a point's name")] = _point(value, f"{where} point {pname!r}")
    return Link(name, points)


def _link_ref(value: Any, index: Mapping[str, int], where: str) -> int:
    if not isinstance(value, str) or value not in index:
        raise LinkageFileError(f"{where}: no link named {_shown(value)} (links: {_shown(list(index))})")
    return index[value]


def _place(value: Any, link: Link, where: str) -> complex:
    """A point of ``link``: its name, or [x, y] in its frame."""
    if isinstance(value, str):
        if value not in link.points:
            raise LinkageFileError(f"{where}: link {link.name!r} has no point {_shown(value)}")
        return link.points[value]
    return _point(value, where)


def _prismatic(k: int, spec: Mapping, links: list[Link], index: Mapping[str, int]) -> PrismaticPair:
    name = spec.get("name")
    where = f"prismatic pair {name!r}" if isinstance(name, str) else f"prismatic pair #{k + 1}"
    if not isinstance(name, str) or not name:
        raise LinkageFileError(f"{where}: 'name' (a string) is required")
    _text(name, f"prismatic pair #{k + 1} 'name'")
    _no_unknown_keys(spec, _PRISMATIC_KEYS, where)
    for key in ("guide", "block", "through"):
        if key not in spec:
            raise LinkageFileError(f"{where}: {key!r} is required")
    guide = _link_ref(spec["guide"], index, f"{where} 'guide'")
    block = _link_ref(spec["block"], index, f"{where} 'block'")
    if guide == block:
        raise LinkageFileError(f"{where}: guide and block are the same link {links[guide].name!r}")
    through = _place(spec["through"], links[guide], f"{where} 'through'")
    if ("angle" in spec) == ("toward" in spec):
        raise LinkageFileError(f"{where}: give exactly one of 'angle' (deg) or 'toward' (a point)")
    if "angle" in spec:
        direction = _unit_from_deg(_number(spec["angle"], f"{where} 'angle'"))
    else:
        toward = _place(spec["toward"], links[guide], f"{where} 'toward'")
        if abs(toward - through) == 0:
            raise LinkageFileError(f"{where}: 'toward' is the same point as 'through'")
        direction = (toward - through) / abs(toward - through)
    block_point = _place(spec.get("block_point", [0, 0]), links[block], f"{where} 'block_point'")
    block_direction = _unit_from_deg(_number(spec.get("block_angle", 0.0), f"{where} 'block_angle'"))
    return PrismaticPair(name, guide, block, through, direction, block_point, block_direction)


def _unit_from_deg(deg: float) -> complex:
    rad = math.radians(deg)
    return complex(math.cos(rad), math.sin(rad))


def _compound_centres(inputs_raw: list[Mapping], index: Mapping[str, int]) -> dict[str, int]:
    """For a joint shared by 3+ links: the link the others pair with (a driven joint's reference)."""
    out = {}
    for spec in inputs_raw:
        joint, rel = spec.get("joint"), spec.get("relative_to")
        if isinstance(joint, str) and isinstance(rel, str) and rel in index:
            out[joint] = index[rel]
    return out


def _revolute_pairs(links: list[Link], centres: Mapping[str, int]) -> list[RevolutePair]:
    """Revolute pairs from point names shared by links; a joint of k links gives k − 1 pairs.

    The k links of a compound joint pair with one centre link: the input's reference link if
    the joint is driven, else the ground if it is among them, else the first one in the file.
    """
    holders: dict[str, list[int]] = {}
    for i, link in enumerate(links):
        for pname in link.points:
            holders.setdefault(pname, []).append(i)
    pairs = []
    for joint, at in holders.items():
        if len(at) < 2:
            continue
        centre = centres.get(joint, at[0])
        if centre not in at:
            centre = at[0]
        for other in at:
            if other != centre:
                pairs.append(
                    RevolutePair(joint, (centre, other), (links[centre].points[joint], links[other].points[joint]))
                )
    return pairs


def _check_pairs(links: list[Link], pairs: tuple) -> None:
    names = {i: link.name for i, link in enumerate(links)}
    between: dict[frozenset[int], list[str]] = {}
    touched = {0}
    for pair in pairs:
        between.setdefault(frozenset(pair.links), []).append(pair.joint)
        touched.update(pair.links)
    for key, joints in between.items():
        if len(joints) > 1:
            a, b = sorted(key)
            raise LinkageFileError(
                f"links {names[a]!r} and {names[b]!r} are joined twice ({', '.join(joints)}): "
                "they would move as one rigid link; merge them or remove a joint"
            )
    for i, link in enumerate(links):
        if i and i not in touched:
            raise LinkageFileError(f"link {link.name!r} shares no joint with any other link")
    # connected to the ground
    adjacency: dict[int, set[int]] = {i: set() for i in names}
    for pair in pairs:
        a, b = pair.links
        adjacency[a].add(b)
        adjacency[b].add(a)
    reach, todo = {0}, [0]
    while todo:
        for j in adjacency[todo.pop()] - reach:
            reach.add(j)
            todo.append(j)
    loose = [names[i] for i in names if i not in reach]
    if loose:
        raise LinkageFileError(f"link(s) {', '.join(map(repr, loose))} are not connected to the ground")
    # a binary link whose two revolute joints coincide has no length: it could spin freely
    scale = max((abs(p) for link in links for p in link.points.values()), default=1.0) or 1.0
    for i, link in enumerate(links):
        mine = [pair for pair in pairs if i in pair.links]
        if i and len(mine) == 2 and all(isinstance(p, RevolutePair) for p in mine):
            ja, jb = mine[0].joint, mine[1].joint
            if abs(link.points[ja] - link.points[jb]) <= _COINCIDENT * scale:
                raise LinkageFileError(
                    f"link {link.name!r}: joints {ja!r} and {jb!r} are at the same point (zero length)"
                )


def _input(k: int, spec: Mapping, links: list[Link], index: Mapping[str, int], pairs: tuple) -> Input:
    where = f"input #{k + 1}"
    _no_unknown_keys(spec, _INPUT_KEYS, where)
    joint = spec.get("joint")
    if not isinstance(joint, str):
        raise LinkageFileError(f"{where}: 'joint' (a revolute joint or prismatic pair name) is required")
    where = f"input at joint {joint!r}"
    candidates = [i for i, p in enumerate(pairs) if p.joint == joint]
    if not candidates:
        raise LinkageFileError(f"{where}: no joint of that name shared by two links")
    sweep = None
    if "range" in spec:
        rng = spec["range"]
        if not isinstance(rng, list) or len(rng) != 2:
            raise LinkageFileError(f"{where}: 'range' must be [first, last]")
        sweep = (_number(rng[0], f"{where} 'range'"), _number(rng[1], f"{where} 'range'"))
        if sweep[1] <= sweep[0]:
            raise LinkageFileError(f"{where}: 'range' must be increasing, got {rng!r}")
    value = _number(spec.get("value", sweep[0] if sweep else 0.0), f"{where} 'value'")
    first = pairs[candidates[0]]
    if isinstance(first, PrismaticPair):
        for key in ("link", "relative_to"):
            if key in spec:
                raise LinkageFileError(
                    f"{where}: a prismatic input takes no {key!r} (it drives the block along its guide)"
                )
        return Input(candidates[0], "slide", first.block, first.guide, value, sweep)
    at = sorted({i for c in candidates for i in pairs[c].links})
    if "link" in spec:
        link = _link_ref(spec["link"], index, f"{where} 'link'")
    else:
        moving = [i for i in at if i != 0]
        if len(at) != 2 or len(moving) != 1:
            raise LinkageFileError(f"{where}: say which link it turns with 'link' (and 'relative_to')")
        link = moving[0]
    if link not in at:
        raise LinkageFileError(f"{where}: link {links[link].name!r} is not at that joint")
    if "relative_to" in spec:
        rel = _link_ref(spec["relative_to"], index, f"{where} 'relative_to'")
    else:
        others = [i for i in at if i != link]
        rel = 0 if 0 in others else others[0]
    matching = [c for c in candidates if set(pairs[c].links) == {link, rel}]
    if not matching:
        raise LinkageFileError(f"{where}: links {links[link].name!r} and {links[rel].name!r} do not meet there")
    rad = math.radians
    return Input(matching[0], "angle", link, rel, rad(value), (rad(sweep[0]), rad(sweep[1])) if sweep else None)


def _configuration(value: Any) -> int | None:
    """The top-level ``configuration``: an integer 1…MAX_CONFIGURATIONS (whether it exists is
    known only once the linkage is solved at its inputs' values)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_CONFIGURATIONS:
        raise LinkageFileError(
            f"'configuration' must be an integer from 1 to {MAX_CONFIGURATIONS}, got {_shown(value)}"
        )
    return value


def _output(spec: Any, links: list[Link], index: Mapping[str, int], pairs: tuple) -> Output | None:
    if spec is None:
        return None
    if not isinstance(spec, Mapping):
        raise LinkageFileError("[output] must be a table with 'link' or 'joint'")
    _no_unknown_keys(spec, _OUTPUT_KEYS, "[output]")
    if ("link" in spec) == ("joint" in spec):
        raise LinkageFileError(
            "[output]: give exactly one of 'link' (its angle) or 'joint' (a prismatic pair's displacement)"
        )
    if "link" in spec:
        i = _link_ref(spec["link"], index, "[output] 'link'")
        if i == 0:
            raise LinkageFileError("[output]: the ground does not move")
        band = None
        if "band" in spec:
            band = _number(spec["band"], "[output] 'band'")
            if not 0 < band < 180:
                raise LinkageFileError(f"[output] 'band' must be between 0 and 180 degrees (exclusive), got {band:g}")
            band = math.radians(band)
        dwells = spec.get("dwells", 1)
        if isinstance(dwells, bool) or dwells not in (1, 2):
            raise LinkageFileError(f"[output] 'dwells' must be 1 or 2, got {_shown(dwells)}")
        if "dwells" in spec and band is None:
            raise LinkageFileError("[output] 'dwells' needs 'band' (the output band within which it rests)")
        leave = None
        if "leave" in spec:
            if dwells != 2:
                raise LinkageFileError("[output] 'leave' applies to two dwells (dwells = 2)")
            leave = _number(spec["leave"], "[output] 'leave'")
            if not 0 <= leave < 180:
                raise LinkageFileError(f"[output] 'leave' must be at least 0 and below 180 degrees, got {leave:g}")
            leave = math.radians(leave)
        return Output("angle", i, links[i].name, band, int(dwells), leave)
    for key in ("band", "dwells", "leave"):
        if key in spec:
            raise LinkageFileError(
                f"[output] {key!r} applies to a link's angle, not to a prismatic pair's displacement"
            )
    name = spec["joint"]
    for i, pair in enumerate(pairs):
        if isinstance(pair, PrismaticPair) and pair.joint == name:
            return Output("slide", i, name)
    raise LinkageFileError(f"[output]: no prismatic pair named {name!r}")


def _check_dof(linkage: Linkage) -> None:
    n, j, f = len(linkage.links), len(linkage.pairs), linkage.dof
    k = len(linkage.inputs)
    if f == k:
        return
    grubler = f"Grübler: 3·({n} − 1) − 2·{j} = {f}"
    if f < 0:
        raise LinkageFileError(
            f"the linkage has {f} degrees of freedom ({grubler}): it is overconstrained; remove a joint or add a link"
        )
    if k > f:
        raise LinkageFileError(
            f"the linkage has {f} degree(s) of freedom ({grubler}) but {k} inputs: "
            "remove an input (a joint driven too many overconstrains it)"
        )
    raise LinkageFileError(
        f"the linkage has {f} degree(s) of freedom ({grubler}) but {k} input(s) are given; "
        "every degree of freedom needs one [[inputs]] entry"
    )
