"""Names are data (issue 42): control characters and bidirectional overrides in a linkage file
are refused in one line, names have a length limit, and wherever a user string is shown anyway
(an atlas's candidate id, a typed unit) it is escaped — terminal, SVG, HTML, DXF, CSV; CSV cells
a spreadsheet would evaluate are neutralised; typed candidate ids are the query's or refused;
every output file of ``dwell analyze`` is written whole or not at all."""

from __future__ import annotations

import csv
import io
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from cli.main import main
from kinematics.assur import LinkageFileError, linkage_from_text
from kinematics.assur.linkage_file import MAX_NAME
from report.escape import CONTROLS, plot_text, terminal, text

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "linkages"
#: Characters a hostile name is drawn from: controls, bidi overrides, markup, ordinary text.
HOSTILE_CHARS = st.sampled_from(sorted(CONTROLS) + list("<>&\"'$\\ aé中\u2028\u00a0"))
NAMES = st.text(HOSTILE_CHARS, min_size=1, max_size=12) | st.text(min_size=1, max_size=300)


def _unsafe(name: str) -> bool:
    return any(ch in CONTROLS for ch in name)


def _fourbar(name: str, where: str) -> str:
    """examples/linkages/fourbar.toml as JSON (any string can be written) with ``name`` as the
    linkage's name, its unit, a link's or a joint's."""
    import tomllib

    doc = tomllib.loads((EXAMPLES / "fourbar.toml").read_text(encoding="utf-8"))
    if where in ("name", "units"):
        doc[where] = name
    elif where == "link":
        doc["links"][name] = doc["links"].pop("rocker")
        doc["output"]["link"] = name
    else:  # the joint between crank and coupler
        doc["links"]["crank"]["joints"][1] = doc["links"]["coupler"]["joints"][0] = name
    return json.dumps(doc)


@settings(max_examples=300, deadline=None)
@given(name=NAMES, where=st.sampled_from(["name", "units", "link", "joint"]))
@example(name="\x1b[2J", where="name")
@example(name="evil\u202eexe.toml", where="link")
@example(name="\x00", where="joint")
@example(name="\ud800", where="name")
@example(name="x" * (MAX_NAME + 1), where="units")
@example(name="x" * MAX_NAME, where="joint")
def test_a_name_is_plain_text_or_refused_in_one_line(name, where):
    try:
        linkage = linkage_from_text(_fourbar(name, where), "json")
    except LinkageFileError as exc:
        message = str(exc)
        assert "\n" not in message and not _unsafe(message)  # the line shows the name escaped
        if not (_unsafe(name) or len(name) > MAX_NAME):
            # a plain name can still clash with the file's others ('ground', 'A', 'C' ...)
            assert where in ("link", "joint") and "control character" not in message, message
        return
    assert not _unsafe(name) and len(name) <= MAX_NAME
    shown = (
        {linkage.name, linkage.units}
        | {link.name for link in linkage.links}
        | {p for link in linkage.links for p in link.points}
    )
    assert name in shown


@settings(max_examples=300, deadline=None)
@given(name=st.text(min_size=0, max_size=40) | st.text(HOSTILE_CHARS, max_size=40))
@example(name="\x00\x08\x0b\x1b\x7f\x85\u202e\u2066")
def test_every_escape_shows_no_control_character_and_makes_xml(name):
    for shown in (terminal(name), text(name), plot_text(name)):
        assert not _unsafe(shown)
    # as element content and attribute value, the escaped name is well-formed XML
    root = ET.fromstring(f'<svg xmlns="http://www.w3.org/2000/svg"><text a="{text(name)}">{text(name)}</text></svg>')
    assert root[0].text in (None, terminal(name)) and root[0].get("a") == terminal(name)


def test_cli_refuses_a_control_character_in_one_line(tmp_path, capsys):
    path = tmp_path / "esc.json"
    path.write_text(_fourbar("\x1b]0;owned\x07", "name"), encoding="utf-8")
    draw = tmp_path / "d.svg"
    assert main(["analyze", "linkage", str(path), "--draw", str(draw)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "U+001B" in err and "\x1b" not in err
    assert not draw.exists()


def test_units_with_a_del_blame_units(capsys):
    for argv in (
        ["query", "--db", "nowhere.sqlite", "--dwell", "60", "--swing", "30", "--units", "mm\x7f"],
        ["analyze", "linkage", str(EXAMPLES / "fourbar.toml"), "--units", "m\x7f"],
        ["analyze", "fourbar", "--a", "1", "--b", "3", "--c", "3", "--d", "2.5", "--units", "\u202emm"],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "--units" in err and "--crank" not in err and "\x7f" not in err, err


# -- files a name reaches: SVG drawings and plots, HTML, DXF, CSV --------------------------------


@pytest.mark.parametrize(
    "cid",
    [
        "\x1b[31m-rpr0.1@30",
        '=HYPERLINK("http://x")',
        "+1-rpr0.1@30",
        "@SUM(A1)",
        "-2+3",
        "\tx",
        "\rx",
        "ok\u202eevil\x00",
    ],
)
def test_a_hostile_candidate_id_in_every_report_file(tmp_path, candidates, cid):
    """An id comes from the atlas (it could be anything): every SVG parses as XML, the DXF
    reads, the page holds no control character, and the CSV cell cannot be a formula."""
    import dataclasses

    import ezdxf
    from harness.report_cases import REQUEST

    from report.export import write_report

    evil = dataclasses.replace(candidates[0], id=cid)
    written = write_report([evil], REQUEST, tmp_path / "r")
    for path in written:
        if path.suffix == ".svg":
            ET.fromstring(path.read_bytes())  # well-formed XML
        if path.suffix in (".svg", ".html", ".csv", ".txt", ".toml"):
            assert not _unsafe(
                path.read_text(encoding="utf-8").replace("\n", "").replace("\t", "").replace("\r", "")
            ), path.name
        if path.suffix == ".dxf":
            ezdxf.readfile(path)
    rows = list(csv.DictReader(io.StringIO((tmp_path / "r" / "candidates.csv").read_text(encoding="utf-8"))))
    assert rows[0]["id"][0] not in "=+-@\t\r" and rows[0]["id"].lstrip("'") == terminal(cid)
    assert float(rows[0]["u"]) == evil.sixbar.u  # numbers, negative ones included, stay numbers


def test_csv_cells():
    from report.export import csv_cell

    assert [csv_cell(v) for v in ("=1+1", "+1", "-1", "@x", "\tx", "\rx", "a=b", None, -1.5, 3)] == [
        "'=1+1",
        "'+1",
        "'-1",
        "'@x",
        "'\\x09x",
        "'\\x0dx",
        "a=b",
        "",
        "-1.5",
        "3",
    ]


# -- candidate ids typed by the user -------------------------------------------------------------


@pytest.mark.parametrize(
    "typed",
    [
        "+1234500007-rrr0.1@30",
        "１２３-rrr0.1@30",
        "4_0-rrr0.1@30",
        "12-rpr0.1@+30",
        "12-rpr0.1@30\x1b[2J",
        "12-rpr0.1@30\u202e",
        "x" * 300,
    ],
)
def test_report_refuses_an_id_not_spelled_as_the_query_prints_it(tmp_path, capsys, typed):
    out = tmp_path / "r"
    assert main(["report", "--db", str(tmp_path / "none.sqlite"), "--candidates", typed, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--candidates" in err and not _unsafe(err.replace("\n", ""))
    assert not out.exists()


def test_report_echoes_the_canonical_spelling():
    from cli.report import canonical_id

    assert canonical_id("1234500007-rrr0.1@30.0") == "1234500007-rrr0.1@30"
    assert canonical_id("12-dbl3.0@free") == "12-dbl3.0@free"


# -- output files written whole or not at all ------------------------------------------------------


@pytest.mark.parametrize("option, name", [("--plot", "m.svg"), ("--draw", "d.svg"), ("--animate", "a.html")])
def test_an_interrupted_output_leaves_the_previous_file(tmp_path, capsys, monkeypatch, option, name):
    """A write that fails halfway (a kill, a full disk) leaves the file as it was and no
    temporary beside it; a complete one replaces it."""
    target = tmp_path / name
    target.write_text("previous", encoding="utf-8")
    argv = ["analyze", "linkage", str(EXAMPLES / "fourbar.toml"), "--step", "90", option, str(target)]

    import report.folder

    real = report.folder.os.replace

    def dies(src, dst):
        Path(src).write_bytes(Path(src).read_bytes()[:10])  # what a killed writer leaves …
        raise KeyboardInterrupt  # … and the process stops before the rename

    monkeypatch.setattr(report.folder.os, "replace", dies)
    assert main(argv) == 130  # "dwell: interrupted"
    assert target.read_text(encoding="utf-8") == "previous"
    assert [p.name for p in tmp_path.iterdir()] == [name]
    monkeypatch.setattr(report.folder.os, "replace", real)
    assert main(argv) == 0, capsys.readouterr().err
    data = target.read_bytes()
    assert data != b"previous" and (b"<svg" in data[:3000] or b"<html" in data[:3000].lower())
    if name.endswith(".svg"):
        ET.fromstring(data)
    assert [p.name for p in tmp_path.iterdir()] == [name]
