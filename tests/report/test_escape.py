"""Hostile names in every HTML/SVG/JS the tool writes: shown as text, never markup or script."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest
from hostile_markup import HOSTILE, check_html, check_svg

from report.animation import Animation, Frame, write_animation
from report.escape import script_json, text

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "linkages"


@pytest.mark.parametrize("name", HOSTILE)
def test_script_json_cannot_close_the_block_and_round_trips(name):
    out = script_json({"k": [name, 1.5]})
    for bad in ("<", ">", "&", "\u2028", "\u2029"):
        assert bad not in out
    assert json.loads(out) == {"k": [name, 1.5]}


def test_script_json_refuses_non_finite():
    with pytest.raises(ValueError):
        script_json([float("nan")])
    with pytest.raises(ValueError):
        script_json({"x": float("inf")})


def test_text_escapes_quotes_and_markup():
    assert text('<a href="x">\'&') == "&lt;a href=&quot;x&quot;&gt;&#x27;&amp;"


def _animation(name: str) -> Animation:
    frames = [Frame([[(0.0, 0.0), (1.0, k / 4)]], [(1.0, k / 4)], [], caption=f"{name} = {k}") for k in range(5)]
    return Animation(frames, [name], [(name, (0.0, 0.0))], title=name)


@pytest.mark.parametrize("name", HOSTILE)
def test_animation_html_and_svg(tmp_path, name):
    page = write_animation(_animation(name), tmp_path / "a.html").read_text(encoding="utf-8")
    check_html(page, name, scripts=1)
    check_html(page, f"{name} = 3", scripts=1)  # a later frame's caption, in the script data
    svg = write_animation(_animation(name), tmp_path / "a.svg").read_text(encoding="utf-8")
    check_svg(svg, name)


def _hostile_linkage(tmp_path: Path, name: str) -> Path:
    """examples/linkages/fourbar.toml with the input joint, a link and the title named ``name``."""
    q = json.dumps(name)  # a TOML basic string (JSON escapes are TOML escapes)
    src = (EXAMPLES / "fourbar.toml").read_text(encoding="utf-8")
    src = src.replace('name = "Four-bar P204001"', f"name = {q}")
    src = src.replace("A = [0, 0]", f"{q} = [0, 0]").replace('["A", "B"]', f'[{q}, "B"]')
    src = src.replace('joint = "A"', f"joint = {q}")
    src = src.replace("[links.rocker]", f"[links.{q}]").replace('link = "rocker"', f"link = {q}")
    path = tmp_path / "hostile.toml"
    path.write_text(src, encoding="utf-8")
    return path


@pytest.mark.parametrize("name", HOSTILE)
def test_analyze_linkage_animation_and_drawing(tmp_path, capsys, name):
    from cli.main import main
    from kinematics.assur.linkage_file import MAX_NAME

    path = _hostile_linkage(tmp_path, name)
    if len(name) > MAX_NAME:  # a name is a label: longer ones are refused in one line
        assert main(["analyze", "linkage", str(path), "--draw", str(tmp_path / "never.svg")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"a name has at most {MAX_NAME}" in err
        assert not (tmp_path / "never.svg").exists()
        return
    anim, svg, draw = tmp_path / "a.html", tmp_path / "a.svg", tmp_path / "d.svg"
    code = main(["analyze", "linkage", str(path), "--step", "30", "--animate", str(anim)])
    err = capsys.readouterr().err
    assert code == 0, err
    page = anim.read_text(encoding="utf-8")
    parsed = check_html(page, name, scripts=1)
    # every frame's caption names the input joint: all of them data, none markup
    assert "".join(parsed.scripts).count("input ") >= 12
    assert main(["analyze", "linkage", str(path), "--step", "30", "--animate", str(svg)]) == 0
    check_svg(svg.read_text(encoding="utf-8"), name)
    with warnings.catch_warnings(record=True) as caught:  # a label too long to lay out: drawn, no warning
        warnings.simplefilter("always")
        assert main(["analyze", "linkage", str(path), "--input", "50", "--draw", str(draw)]) == 0, (
            capsys.readouterr().err
        )
    assert not [w for w in caught if "layout" in str(w.message)], [str(w.message) for w in caught]
    check_svg(draw.read_text(encoding="utf-8"))
    plot = tmp_path / "p.svg"
    assert main(["analyze", "linkage", str(path), "--step", "30", "--plot", str(plot)]) == 0, capsys.readouterr().err
    check_svg(plot.read_text(encoding="utf-8"))


def test_plot_text_is_literal_in_matplotlib(tmp_path):
    import matplotlib

    from report.escape import plot_text

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure()
    fig.subplots().set_title(plot_text("$\\frac{$ and $x$"))
    fig.savefig(tmp_path / "t.svg")  # raises on mathtext it cannot parse
    assert plot_text("a$b") == "a\\$b"


def test_plot_text_draws_a_character_the_font_lacks_as_a_replacement_without_a_warning(tmp_path):
    """A name in a script the plotting font lacks (found by the fuzz test: ``--units`` of
    U+1698C, a Bamum letter) is drawn as U+FFFD, so matplotlib draws no empty box and prints
    no warning; what the font has stays, and plain ASCII is returned as it is."""
    import warnings

    import matplotlib

    from report.escape import plot_text

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    name = "x [\U0001698c mm \u00b0 \u03c8]"
    shown = plot_text(name)
    assert shown == "x [\ufffd mm \u00b0 \u03c8]" and plot_text("a b") == "a b"
    fig = Figure()
    fig.subplots().set_xlabel(shown)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fig.savefig(tmp_path / "t.png")
    fig.subplots().set_ylabel(name)
    with pytest.warns(UserWarning, match="missing from font"):  # what plot_text spares the user
        fig.savefig(tmp_path / "u.png")


@pytest.mark.parametrize("name", HOSTILE)
def test_report_page_svgs_and_files_with_a_hostile_candidate_id(tmp_path, candidates, name):
    """`dwell report`'s page: the scripts it has (two of its own and one JSON block per
    candidate), no more; the id shown as text; every SVG it writes clean."""
    import dataclasses

    from harness.report_cases import REQUEST

    from report.export import write_report

    evil = dataclasses.replace(candidates[1], id=name)
    written = write_report([evil], REQUEST, tmp_path / "r")
    page = (tmp_path / "r" / "index.html").read_text(encoding="utf-8")
    check_html(page, name, scripts=3)
    for svg in (p for p in written if p.suffix == ".svg"):
        check_svg(svg.read_text(encoding="utf-8"))
    assert json.loads((tmp_path / "r" / "candidates.json").read_text(encoding="utf-8"))["candidates"][0]["id"] == name
