"""Description files: parsing, every validation error names what is wrong, degrees of freedom."""

from __future__ import annotations

import json
import tomllib

import pytest
from assur_builders import EXAMPLES
from hypothesis import given, settings
from hypothesis import strategies as st
from linkage_chains import chain_of_dyads

from kinematics.assur import LinkageFileError, decompose, linkage_from_mapping, linkage_from_text
from kinematics.status import AssemblyError

FOURBAR = {
    "ground": {"A": [0, 0], "D": [100, 0]},
    "links": {
        "crank": {"joints": ["A", "B"], "length": 50},
        "coupler": {"joints": ["B", "C"], "length": 80},
        "rocker": {"joints": ["D", "C"], "length": 80},
    },
    "inputs": [{"joint": "A", "link": "crank"}],
}


def _with(**changes):
    doc = json.loads(json.dumps(FOURBAR))
    for path, value in changes.items():
        node = doc
        keys = path.split("__")
        for k in keys[:-1]:
            node = node[int(k)] if isinstance(node, list) else node[k]
        if value is None:
            del node[keys[-1]]
        else:
            node[keys[-1]] = value
    return doc


@pytest.mark.parametrize("name", sorted(p.name for p in EXAMPLES.glob("*.toml")))
def test_every_example_parses_and_decomposes(name):
    lk = linkage_from_text((EXAMPLES / name).read_text())
    assert lk.dof == len(lk.inputs)
    groups = decompose(lk).groups
    assert groups and all(g.kind in ("RRR", "RRP", "RPR", "PRP", "RPP", "triad") for g in groups)


def test_json_and_toml_describe_the_same_linkage():
    text = (EXAMPLES / "shaper.toml").read_text()
    a = linkage_from_text(text)
    b = linkage_from_text(json.dumps(tomllib.loads(text)), "json")
    assert a == b


def test_structure_and_units():
    lk = linkage_from_mapping(FOURBAR)
    assert lk.dof == 1 and len(lk.pairs) == 4 and lk.units == "mm"
    assert [l.name for l in lk.links] == ["ground", "crank", "coupler", "rocker"]
    assert lk.links[1].points == {"A": 0j, "B": 50 + 0j}


@pytest.mark.parametrize(
    "doc, message",
    [
        (_with(links__crank__length=-5), "link 'crank': 'length' must be > 0"),
        (_with(links__crank__length="x"), "link 'crank' 'length' must be a finite number"),
        (_with(links__crank__lenght=5), "link 'crank': unknown key 'lenght'"),
        (_with(links__crank__joints=["A"]), "link 'crank': 'joints' must name two joints"),
        (_with(links__crank__joints=["A", "A"]), "names 'A' twice"),
        (_with(links__crank={"joints": ["A", "B"]}), "'joints' needs 'length'"),
        (_with(links__coupler__points={"B": [0, 0]}), "point 'B' is already placed by 'joints'"),
        (_with(ground__D=[1, "y"]), "ground point 'D' y must be a finite number"),
        (_with(ground__D=[1]), "ground point 'D' must be [x, y]"),
        (_with(links__ground={"joints": ["A", "B"], "length": 1}), "reserved"),
        (_with(inputs=[{"joint": "Q", "link": "crank"}]), "input at joint 'Q': no joint of that name"),
        (_with(inputs=[{"joint": "A", "link": "rocker"}]), "link 'rocker' is not at that joint"),
        (_with(inputs=[{"joint": "A", "link": "nope"}]), "no link named 'nope'"),
        (_with(inputs=[]), "1 degree(s) of freedom"),
        (
            _with(inputs=[{"joint": "A", "link": "crank"}, {"joint": "D", "link": "rocker"}]),
            "1 degree(s) of freedom .* but 2 inputs: remove an input",
        ),
        (_with(links__rocker__joints=["D", "E"]), "3 degree(s) of freedom .* every degree of freedom needs"),
        (_with(links__extra={"joints": ["X", "Y"], "length": 3}), "link 'extra' shares no joint"),
        (
            _with(
                links__x1={"joints": ["P", "Q"], "length": 3},
                links__x2={"joints": ["Q", "R"], "length": 3},
                links__x3={"joints": ["R", "P"], "length": 3},
            ),
            "'x1', 'x2', 'x3' are not connected to the ground",
        ),
        (_with(links__crank__points={"C": [1, 1]}), "links 'crank' and 'coupler' are joined twice"),
        (_with(links__coupler__length=1e-15), "link .coupler.: joints .B. and .C. are at the same point"),
        (_with(output={"link": "ground"}), "the ground does not move"),
        (_with(output={"joint": "s"}), "no prismatic pair named 's'"),
        (_with(output={"link": "rocker", "joint": "s"}), "give exactly one of"),
        (
            _with(prismatic=[{"name": "C", "guide": "ground", "block": "rocker", "through": [0, 0], "angle": 0}]),
            "already a point name",
        ),
        (
            _with(prismatic=[{"name": "s", "guide": "ground", "block": "ground", "through": [0, 0], "angle": 0}]),
            "guide and block are the same link",
        ),
        (
            _with(prismatic=[{"name": "s", "guide": "ground", "block": "rocker", "through": [0, 0]}]),
            "give exactly one of 'angle'",
        ),
        (
            _with(prismatic=[{"name": "s", "guide": "ground", "block": "rocker", "through": "Z", "angle": 0}]),
            "link 'ground' has no point 'Z'",
        ),
        (
            _with(prismatic=[{"guide": "ground", "block": "rocker", "through": [0, 0], "angle": 0}]),
            "'name' (a string) is required",
        ),
        (_with(links__coupler__length=0.5, links__coupler__joints=["B", "C"], ground__D=[100, 0]), None),
        (_with(configuration=0), "'configuration' must be an integer from 1 to 1024, got 0"),
        (_with(configuration=1025), "'configuration' must be an integer from 1 to 1024"),
        (_with(configuration=2.0), "'configuration' must be an integer"),
        (_with(configuration=True), "'configuration' must be an integer"),
        (_with(configuration="2"), "'configuration' must be an integer"),
        (_with(output={"link": "rocker", "band": 0}), "[output] 'band' must be between 0 and 180"),
        (_with(output={"link": "rocker", "band": 180}), "[output] 'band' must be between 0 and 180"),
        (_with(output={"link": "rocker", "band": "x"}), "[output] 'band' must be a finite number"),
        (_with(output={"link": "rocker", "band": 0.1, "dwells": 3}), "[output] 'dwells' must be 1 or 2, got 3"),
        (_with(output={"link": "rocker", "band": 0.1, "dwells": True}), "[output] 'dwells' must be 1 or 2"),
        (_with(output={"link": "rocker", "dwells": 2}), r"'dwells' needs 'band'"),
        (_with(output={"link": "rocker", "band": 0.1, "leave": 2}), r"'leave' applies to two dwells"),
        (_with(output={"link": "rocker", "band": 0.1, "dwells": 2, "leave": -1}), r"'leave' must be at least 0"),
        (_with(output={"link": "rocker", "band": 0.1, "dwells": 2, "leave": 180}), r"'leave' must be at least 0"),
        (_with(output={"link": "rocker", "band": 0.1, "dwells": 2, "leave": "x"}), r"'leave' must be a finite number"),
        (_with(output={"link": "rocker", "band": 0.1, "dwells": 2, "leave": 0}), None),
        (_with(output={"joint": "s", "leave": 1}), r"'leave' applies to a link's angle"),
        (_with(output={"joint": "s", "band": 0.1}), r"'band' applies to a link's angle"),
        ({"links": {}}, "at least one moving link"),
        ([1, 2], "table/object at the top level"),
    ],
)
def test_validation_messages(doc, message):
    if message is None:  # lengths that cannot assemble still make a valid description
        linkage_from_mapping(doc)
        return
    pattern = (
        message.replace("(", r"\(")
        .replace(")", r"\)")
        .replace("[", r"\[")
        .replace("]", r"\]")
        .replace(r"\(s\)", r"\(s\)")
    )
    with pytest.raises(LinkageFileError, match=pattern):
        linkage_from_mapping(doc)


def test_errors_are_assembly_errors_and_one_line():
    with pytest.raises(AssemblyError) as info:
        linkage_from_text("name = 'x'\n[links.a\n")
    assert "not valid TOML" in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(LinkageFileError, match="not valid JSON"):
        linkage_from_text("{", "json")


def test_decomposition_errors():
    ppp = {
        "ground": {},
        "links": {"s1": {}, "s2": {}},
        "prismatic": [
            {"name": "p1", "guide": "ground", "block": "s1", "through": [0, 0], "angle": 0},
            {"name": "p2", "guide": "s1", "block": "s2", "through": [0, 0], "angle": 90},
            {"name": "p3", "guide": "ground", "block": "s2", "through": [0, 0], "angle": 45},
        ],
    }
    with pytest.raises(LinkageFileError, match="PPP"):
        decompose(linkage_from_mapping(ppp))
    # a class IV group: a closed loop a-b-c-d hung from the crank (at a) and the ground (at c)
    class4 = {
        "ground": {"O": [0, 0], "G": [10, 0]},
        "links": {
            "crank": {"joints": ["O", "A"], "length": 1},
            "a": {"points": {"A": [0, 0], "P": [3, 0], "S": [0, 3]}},
            "b": {"joints": ["P", "Q"], "length": 3},
            "c": {"points": {"Q": [0, 0], "R": [3, 0], "G": [1, 1]}},
            "d": {"joints": ["R", "S"], "length": 3},
        },
        "inputs": [{"joint": "O", "link": "crank"}],
    }
    lk = linkage_from_mapping(class4)
    assert lk.dof == 1
    with pytest.raises(LinkageFileError, match="class IV"):
        decompose(lk)


def test_actuator_input_fuses_two_moving_links():
    lk = linkage_from_text((EXAMPLES / "hydraulic_boom.toml").read_text())
    dec = decompose(lk)
    assert [g.kind for g in dec.groups] == ["RRR"]
    assert dec.body_name(lk, dec.groups[0].bodies[1]) == "cylinder+rod"


# -- limits: every hostile file is one LinkageFileError line, before the work it would cause ----


@pytest.mark.parametrize(
    "text, fmt, message",
    [
        ('{"name": ' + "[" * 100_000 + "]" * 100_000 + "}", "json", "nest 100001 deep; a description nests at most 16"),
        ("name = " + "[" * 5000 + "]" * 5000, "toml", "nest 5000 deep"),
        ("# " + "x" * 1_000_001, "toml", "characters; at most 1,000,000"),
        ("[links.c]\njoints = ['A', 'B']\nlength = " + "9" * 5000, "toml", "an integer has more than 4300 digits"),
        ('{"links": {"c": {"joints": ["A", "B"], "length": ' + "9" * 5000 + "}}}", "json", "more than 4300 digits"),
        (
            "[links.c]\njoints = ['A', 'B']\nlength = " + "9" * 400,
            "toml",
            "'length' must be a finite number of magnitude",
        ),
        (chain_of_dyads(600), "toml", "[links] defines 1201 links; at most 1000"),
        (
            "[links.c]\npoints = {" + ", ".join(f"P{i} = [0, {i}]" for i in range(101)) + "}",
            "toml",
            "link 'c' has 101 points; at most 100",
        ),
    ],
)
def test_hostile_descriptions_are_one_line(text, fmt, message):
    with pytest.raises(LinkageFileError) as err:
        linkage_from_text(text, fmt)
    assert message in str(err.value) and "\n" not in str(err.value) and len(str(err.value)) < 300


def test_nesting_depth_skips_strings_and_comments():
    from kinematics.assur.linkage_file import nesting_depth

    assert nesting_depth('a = [[1, 2], [3]]\n[[inputs]]\nx = "[[[[" # [[[[\n', "toml") == 2
    assert nesting_depth('{"a": ["[[[", {"b": 1}]}', "json") == 3
    assert nesting_depth("s = '''[[[['''\nt = \"\\\"[[\"", "toml") == 0


def test_a_chain_of_dyads_lists_at_most_max_configurations():
    """18 dyads: 2^18 = 262 144 configurations took 75 s to list; now the first 1024, in order."""
    import numpy as np

    from kinematics.assur import MAX_CONFIGURATIONS, configurations

    lk = linkage_from_text(chain_of_dyads(18))
    found = configurations(lk, [np.radians(30)])
    assert len(found) == MAX_CONFIGURATIONS
    # depth first, branch +1 before -1: the last group varies fastest
    assert [f.choice[-10:] for f in found[:2]] == [(1,) * 10, (1,) * 9 + (-1,)]
    small = linkage_from_text(chain_of_dyads(3))
    assert len(configurations(small, [np.radians(30)])) == 8  # all of them when fewer


def test_too_many_partial_configurations_is_one_line(monkeypatch):
    import numpy as np

    from kinematics.assur import ConfigurationLimit, configurations, positions

    monkeypatch.setattr(positions, "MAX_PARTIAL_CONFIGURATIONS", 50)
    with pytest.raises(ConfigurationLimit) as err:
        configurations(linkage_from_text(chain_of_dyads(12)), [np.radians(30)])
    assert "12 dyad(s) and 0 triad(s) have up to 2^12·6^0 assembly configurations; 50 partial" in str(err.value)


hostile_text = st.one_of(
    st.integers(0, 3000).map(lambda n: "name = " + "[" * n + "]" * n),
    st.integers(1, 6000).map(lambda n: "[links.c]\njoints = ['A', 'B']\nlength = " + "9" * n),
    st.integers(0, 1500).map(lambda n: "[ground]\n" + "\n".join(f"G{i} = [{i}, 0]" for i in range(n))),
    st.integers(0, 2000).map(
        lambda n: "\n".join(f"[links.l{i}]\njoints = ['A{i}', 'B{i}']\nlength = 1" for i in range(n))
    ),
    st.text(max_size=200),
    st.binary(max_size=200).map(lambda b: b.decode("latin-1")),
)


@settings(max_examples=60, deadline=None)
@given(hostile_text, st.sampled_from(["toml", "json"]))
def test_any_description_is_a_linkage_or_one_line(text, fmt):
    try:
        linkage_from_text(text, fmt)
    except LinkageFileError as exc:
        assert "\n" not in str(exc) and len(str(exc)) < 400
