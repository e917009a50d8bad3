"""``dwell analyze linkage``: JSON values against the kernels, files, exit codes, one-line errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from cli.main import main
from kinematics.assur import assemble, configurations, linkage_from_text, linkage_motion
from kinematics.fourbar import fourbar_motion, rocker_limits

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "linkages"


def run(capsys, *args):
    code = main(["analyze", "linkage", *map(str, args)])
    out, err = capsys.readouterr()
    return code, out, err


def test_fourbar_json_matches_the_closed_form(capsys):
    code, out, err = run(capsys, EXAMPLES / "fourbar.toml", "--rpm", "120", "--cw", "--json")
    assert code == 0, err
    doc = json.loads(out)
    rows = doc["positions"]
    assert [r["input_deg"] for r in rows] == [30.0 * k for k in range(12)]
    w = -4 * math.pi
    for row in rows:
        m = fourbar_motion(50, 80, 80, 100, math.radians(row["input_deg"]), 1)
        assert row["theta_rocker_deg"] == pytest.approx(math.degrees(float(m.gamma)), abs=1e-10)
        assert row["omega_rocker_rad_s"] == pytest.approx(float(m.dgamma[0]) * w, abs=1e-11)
        assert row["alpha_coupler_rad_s2"] == pytest.approx(float(m.dtheta[1]) * w * w, abs=1e-10)
        z = m.coupler_point(40, 30, order=2)
        assert row["Px_mm"] == pytest.approx(float(z[0].real), abs=1e-11)
        assert row["vPy_mm_s"] == pytest.approx(float(z[1].imag) * w, abs=1e-10)
    mech = doc["mechanism"]
    assert (
        mech["dof"] == 1
        and mech["groups"] == ["RRR dyad (coupler-rocker)"]
        and mech["configurations_at_first_position"] == 2
    )
    assert doc["summary"]["loop_closure_max"] < 1e-12


def test_limits_in_json_and_text(capsys):
    code, out, err = run(capsys, EXAMPLES / "fourbar.toml", "--limits", "--json")
    assert code == 0, err
    lim = json.loads(out)["summary"]["limits"]
    ref = rocker_limits(50, 80, 80, 100)
    assert lim["swing_deg"] == pytest.approx(math.degrees(ref.swing), abs=1e-8)
    assert lim["time_ratio"] == pytest.approx(ref.time_ratio, abs=1e-9)
    kinds = {p["kind"]: p for p in lim["positions"]}
    assert kinds["min"]["input_deg"] == pytest.approx(math.degrees(ref.phi_extended), abs=1e-8)
    code, out, err = run(capsys, EXAMPLES / "shaper.toml", "--limits")
    assert code == 0, err
    assert "limit positions of s5 (slide)" in out and "stroke: 180" in out and "time ratio: 1.48" in out


def test_all_configurations_of_the_class3_sixbar(capsys):
    code, out, err = run(capsys, EXAMPLES / "class3_sixbar.toml", "--input", "0", "--all-configurations", "--json")
    assert code == 0, err
    doc = json.loads(out)
    rows = doc["configurations"]
    assert [r["configuration"] for r in rows] == [1, 2, 3, 4, 5, 6]
    assert all(r["loop_closure_mm"] < 1e-12 for r in rows)
    assert len({round(r["theta_ternary_deg"], 6) for r in rows}) == 6
    code, out, err = run(
        capsys, EXAMPLES / "eightbar.toml", "--from", "0", "--to", "60", "--step", "30", "--all-configurations"
    )
    assert code == 0, err
    assert "configurations: 36" in out


def test_configuration_is_followed_over_the_sweep(capsys):
    path = EXAMPLES / "class3_sixbar.toml"
    code, out, err = run(capsys, path, "--configuration", "4", "--step", "45", "--json")
    assert code == 0, err
    rows = json.loads(out)["positions"]
    lk = linkage_from_text(path.read_text())
    start = configurations(lk, [0.0])[3]
    phi = np.radians([r["input_deg"] for r in rows])
    asm = assemble(lk, phi[:, None], start)
    m = linkage_motion(lk, asm, rates=[2 * math.pi])
    assert [r["theta_ternary_deg"] for r in rows] == pytest.approx(np.degrees(asm.theta[:, 2]).tolist(), abs=1e-10)
    assert [r["omega_leg2_rad_s"] for r in rows] == pytest.approx(m.omega[:, 4].tolist(), abs=1e-10)


def test_slide_input_and_speed(capsys):
    code, out, err = run(capsys, EXAMPLES / "hydraulic_boom.toml", "--speed", "50", "--json")
    assert code == 0, err
    rows = json.loads(out)["positions"]
    assert rows[0]["input_mm"] == 160 and rows[-1]["input_mm"] == 300 and len(rows) == 13
    assert all(r["v_s_mm_s"] == pytest.approx(50.0, abs=1e-9) for r in rows)


def test_text_tables_plot_drawing_animation(tmp_path, capsys):
    plot, draw, anim, svg = tmp_path / "m.png", tmp_path / "d.svg", tmp_path / "a.html", tmp_path / "a.svg"
    code, out, err = run(
        capsys,
        EXAMPLES / "shaper.toml",
        "--from",
        "0",
        "--to",
        "90",
        "--step",
        "45",
        "--plot",
        plot,
        "--draw",
        draw,
        "--animate",
        anim,
    )
    assert code == 0, err
    assert "positions:" in out and "velocities:" in out and "accelerations:" in out
    assert (
        "v_s5[mm/s]" in out and len([ln for ln in out.splitlines() if ln.strip().startswith(("0 ", "45 ", "90 "))]) == 9
    )
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"<svg" in draw.read_bytes()[:2000]
    html = anim.read_text()
    assert "<svg" in html and "<script>" in html and "src=" not in html and "https://" not in html
    code, out, err = run(capsys, EXAMPLES / "class3_sliders.toml", "--input", "10", "--animate", svg)
    assert code == 0, err
    text = svg.read_text()
    assert text.startswith("<svg") and "<animate" in text


@pytest.mark.parametrize(
    "args, message",
    [
        (["missing.toml"], "does not exist"),
        (["{bad}"], "not valid TOML"),
        (["{dof}"], "degree(s) of freedom"),
        (["{fourbar}", "--configuration", "3"], "configuration 3 does not exist"),
        (["{fourbar}", "--input", "10", "--input", "20"], "--input"),
        (["{fourbar}", "--output", "nope", "--limits"], "no link or prismatic pair named 'nope'"),
        (["{fourbar}", "--step", "0"], "Invalid value for '--step': must be 1e-09 <= x"),
        (["{fourbar}", "--from", "90", "--to", "10"], "must not be below"),
        (["{fourbar}", "--plot", "x.txt"], "--plot"),
        (["{fourbar}", "--animate", "x.png"], "--animate"),
        (["{fourbar}", "--bogus"], "No such option"),
        (["{triple}"], "cannot assemble"),
        (["{triple}", "--limits", "--input", "0"], "give --from/--to"),
        (["{fourbar}", "--all-configurations", "--limits"], "leave out --all-configurations"),
        (["{fourbar}", "--configuration", "0"], "--configuration"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, args, message):
    bad = tmp_path / "bad.toml"
    bad.write_text("[links.a\n")
    dof = tmp_path / "dof.toml"
    dof.write_text(
        (EXAMPLES / "fourbar.toml").read_text().replace('[[inputs]]\njoint = "A"\nlink = "crank"\nvalue = 50\n', "")
    )
    triple = tmp_path / "triple.toml"
    triple.write_text(
        '[ground]\nA = [0, 0]\nD = [3, 0]\n[links.crank]\njoints = ["A", "B"]\nlength = 2\n'
        '[links.coupler]\njoints = ["B", "C"]\nlength = 2\n[links.rocker]\njoints = ["D", "C"]\nlength = 2\n'
        '[[inputs]]\njoint = "A"\nlink = "crank"\n'
    )
    names = {"{bad}": bad, "{dof}": dof, "{fourbar}": EXAMPLES / "fourbar.toml", "{triple}": triple}
    args = [str(names.get(a, a)) for a in args]
    plot = tmp_path / "never.png"
    code, out, err = run(capsys, *args, "--plot", plot) if "--plot" not in args else run(capsys, *args)
    assert code == 2, (out, err)
    assert message in err and err.count("\n") == 1 and err.startswith("dwell: error:")
    assert not plot.exists()  # nothing written on bad input


def test_json_document_from_a_json_file(tmp_path, capsys):
    import tomllib

    path = tmp_path / "scotch.json"
    path.write_text(json.dumps(tomllib.loads((EXAMPLES / "scotch_yoke.toml").read_text())))
    code, out, err = run(capsys, path, "--input", "60", "--json")
    assert code == 0, err
    row = json.loads(out)["positions"][0]
    assert row["s_x_mm"] == pytest.approx(40 * math.cos(math.radians(60)), abs=1e-12)
    assert row["v_x_mm_s"] == pytest.approx(-40 * math.sin(math.radians(60)) * 2 * math.pi, abs=1e-10)


# -- the configuration a file stands for; transmission angles and dwells of --limits ------------


def _fourbar_text(extra_top: str = "", output: str = "") -> str:
    """examples/linkages/fourbar.toml with top-level keys added and [output] replaced."""
    text = (EXAMPLES / "fourbar.toml").read_text()
    body = text.replace('units = "mm"\n', f'units = "mm"\n{extra_top}')
    return body.replace('[output]\nlink = "rocker"\n', "[output]\n" + (output or 'link = "rocker"\n'))


def test_the_file_configuration_is_followed_and_the_option_overrides_it(tmp_path, capsys):
    path = tmp_path / "mirror.toml"
    path.write_text(_fourbar_text("configuration = 2\n"))
    code, out, err = run(capsys, path, "--json")
    assert code == 0, err
    own = json.loads(out)
    assert own["mechanism"]["configuration"] == 2 and own["mechanism"]["configuration_from"] == "file"
    code, out, _ = run(capsys, EXAMPLES / "fourbar.toml", "--configuration", "2", "--json")
    assert json.loads(out)["positions"] == own["positions"]
    code, out, _ = run(capsys, path, "--configuration", "1", "--json")
    doc = json.loads(out)
    assert doc["mechanism"]["configuration_from"] == "option"
    # the option's configuration 1 puts C on the other side: a different mechanism
    assert doc["positions"][1]["Cy_mm"] == pytest.approx(-own["positions"][1]["Cy_mm"], abs=1e-9) or doc["positions"][
        1
    ]["Cy_mm"] != pytest.approx(own["positions"][1]["Cy_mm"], abs=1e-6)
    code, out, _ = run(capsys, EXAMPLES / "fourbar.toml", "--json")
    assert json.loads(out)["mechanism"]["configuration_from"] == "default"


def test_the_file_configuration_is_numbered_at_the_inputs_values(tmp_path, capsys):
    """A triad's configurations are listed by the ternary link's angle, an order that changes
    with the crank: the file's number is the one at the input's value, followed to the sweep."""
    path = tmp_path / "class3.toml"
    path.write_text(
        (EXAMPLES / "class3_sixbar.toml").read_text().replace('units = "mm"\n', 'units = "mm"\nconfiguration = 4\n')
    )
    code, out, err = run(capsys, path, "--from", "120", "--to", "180", "--step", "30", "--json")
    assert code == 0, err
    rows = json.loads(out)["positions"]
    code, out, err = run(
        capsys,
        EXAMPLES / "class3_sixbar.toml",
        "--configuration",
        "4",
        "--from",
        "0",
        "--to",
        "180",
        "--step",
        "30",
        "--json",
    )
    assert code == 0, err
    followed = json.loads(out)["positions"][4:]
    assert [r["theta_ternary_deg"] for r in rows] == pytest.approx([r["theta_ternary_deg"] for r in followed], abs=1e-9)
    # numbered at 120° instead, configuration 4 is another branch of the triad
    code, out, _ = run(
        capsys,
        EXAMPLES / "class3_sixbar.toml",
        "--configuration",
        "4",
        "--from",
        "120",
        "--to",
        "180",
        "--step",
        "30",
        "--json",
    )
    other = json.loads(out)["positions"]
    assert other[0]["theta_ternary_deg"] != pytest.approx(rows[0]["theta_ternary_deg"], abs=1e-3)


def test_a_file_configuration_that_does_not_exist_is_one_line(tmp_path, capsys):
    path = tmp_path / "three.toml"
    path.write_text(_fourbar_text("configuration = 3\n"))
    code, out, err = run(capsys, path, "--limits")
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "'configuration' is 3 but Four-bar P204001 has 2 assembly configuration(s)" in err
    code, out, err = run(capsys, path, "--configuration", "2")  # the option overrides the file
    assert code == 0, err


def test_limits_give_transmission_angles_and_dwells(tmp_path, capsys):
    """The four-bar's smallest transmission angle against the closed form on a fine grid; the
    rocker's dwells within a band against a brute-force 0.001° grid."""
    from kinematics.fourbar import fourbar_motion, transmission_angle

    band = 2.0
    path = tmp_path / "rest.toml"
    path.write_text(_fourbar_text(output=f'link = "rocker"\nband = {band}\ndwells = 2\n'))
    code, out, err = run(capsys, path, "--limits", "--json")
    assert code == 0, err
    lim = json.loads(out)["summary"]["limits"]
    phi = np.radians(np.arange(0, 360, 0.001))
    m = fourbar_motion(50, 80, 80, 100, phi, 1)
    (mu,) = lim["transmission"]
    assert mu["joint"] == "C"
    assert mu["min_deg"] == pytest.approx(
        math.degrees(float(np.minimum(transmission_angle(m), np.pi - transmission_angle(m)).min())), abs=1e-6
    )
    assert lim["band_deg"] == band and len(lim["dwells"]) == 2
    psi = np.degrees(np.unwrap(m.gamma))
    deg = np.degrees(phi)
    for d in lim["dwells"]:
        lo, hi = d["interval_deg"]
        inside = np.mod(deg - lo, 360) <= np.mod(hi - lo, 360)
        assert np.ptp(psi[inside]) <= band + 1e-9
        assert d["dwell_deg"] == pytest.approx(np.mod(hi - lo, 360), abs=1e-9)
        for widen in ((lo - 0.005, hi), (lo, hi + 0.005)):  # the ends are where the band breaks
            wide = np.mod(deg - widen[0], 360) <= np.mod(widen[1] - widen[0], 360)
            assert np.ptp(psi[wide]) > band
    code, out, err = run(capsys, path, "--limits")
    assert code == 0, err
    assert f"smallest transmission angle at C: {lim['transmission'][0]['min_deg']:.10g} deg" in out
    assert f"dwell 2 within a {band:g} deg band: input" in out
    # --band measures another output; a slide has no band
    code, out, err = run(capsys, EXAMPLES / "fourbar.toml", "--limits", "--band", str(band), "--dwells", "2", "--json")
    assert json.loads(out)["summary"]["limits"]["dwells"] == lim["dwells"]
    code, out, err = run(capsys, EXAMPLES / "shaper.toml", "--limits", "--band", "1", "--json")
    assert code == 0, err
    assert json.loads(out)["summary"]["limits"]["dwells_not_measured"] == "the output is a slide (a band is an angle)"


def test_two_rests_are_told_apart_by_the_file_leave(tmp_path, capsys):
    """``[output] leave`` (the query's ``--swing-tol``) is how far the output must leave the band
    between two rests: the rocker swings 77.4° between its two rests, so a leave below that
    keeps both and one above it leaves only the longer; ``--leave`` overrides the file."""
    path = tmp_path / "rest.toml"
    path.write_text(_fourbar_text(output='link = "rocker"\nband = 2.0\ndwells = 2\nleave = 10\n'))
    code, out, err = run(capsys, path, "--limits", "--json")
    assert code == 0, err
    two = json.loads(out)["summary"]["limits"]
    assert two["leave_deg"] == pytest.approx(10.0, abs=1e-12) and len(two["dwells"]) == 2
    swing = two["swing_deg"]
    code, out, err = run(capsys, path, "--limits", "--json", "--leave", str(swing + 1))
    assert code == 0, err
    one = json.loads(out)["summary"]["limits"]
    assert one["leave_deg"] == pytest.approx(swing + 1) and one["dwells"] == two["dwells"][:1]
    path.write_text(_fourbar_text(output='link = "rocker"\nband = 2.0\ndwells = 2\n'))
    code, out, err = run(capsys, path, "--limits", "--json")
    assert json.loads(out)["summary"]["limits"]["leave_deg"] == pytest.approx(0.5, abs=1e-12)  # REST_LEAVE
