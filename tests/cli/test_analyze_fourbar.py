"""``dwell analyze fourbar``: JSON values, files, exit codes, one-line errors."""

from __future__ import annotations

import json
import math
import warnings

import pytest

from cli.main import main
from kinematics import fourbar_motion, time_derivatives


def run(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_json_matches_the_kernel(capsys):
    code, out, err = run(
        capsys,
        "analyze",
        "fourbar",
        "--a",
        "1",
        "--b",
        "3",
        "--c",
        "2.5",
        "--d",
        "3",
        "--point",
        "1",
        "0.5",
        "--rpm",
        "120",
        "--cw",
        "--json",
    )
    assert code == 0, err
    doc = json.loads(out)
    rows = doc["positions"]
    assert [r["phi_deg"] for r in rows] == [30.0 * k for k in range(12)]
    w = -4 * math.pi  # 120 rpm clockwise
    for row in rows:
        m = fourbar_motion(1, 3, 2.5, 3, math.radians(row["phi_deg"]), 1)
        assert row["gamma_deg"] == pytest.approx(math.degrees(float(m.gamma)), abs=1e-12)
        assert row["omega_rocker_rad_s"] == pytest.approx(float(m.dgamma[0]) * w, rel=1e-12, abs=1e-12)
        assert row["alpha_coupler_rad_s2"] == pytest.approx(float(m.dtheta[1]) * w * w, rel=1e-12, abs=1e-12)
        z = m.coupler_point(1, 0.5, order=2)
        v = time_derivatives(z[1:], w)[0]
        assert row["vPy_mm_s"] == pytest.approx(float(v.imag), rel=1e-12, abs=1e-12)
    s = doc["summary"]
    assert s["grashof"] == "crank-rocker"
    assert s["swing_deg"] == pytest.approx(51.45636, abs=1e-4)
    assert s["time_ratio"] > 1


def test_table_plot_and_drawing(tmp_path, capsys):
    plot, draw = tmp_path / "m.png", tmp_path / "m.svg"
    code, out, err = run(
        capsys,
        "analyze",
        "fourbar",
        "--a",
        "1",
        "--b",
        "3",
        "--c",
        "2.5",
        "--d",
        "3",
        "--point",
        "1",
        "1",
        "--from",
        "0",
        "--to",
        "90",
        "--step",
        "45",
        "--plot",
        str(plot),
        "--draw",
        str(draw),
    )
    assert code == 0, err
    assert "omega_rocker[rad/s]" in out and "time_ratio" in out
    assert len([ln for ln in out.splitlines() if ln.strip().startswith(("0 ", "45 ", "90 "))]) == 3
    assert plot.stat().st_size > 10_000 and plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"<svg" in draw.read_bytes()[:2000]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--a", "-1", "--b", "3", "--c", "2.5", "--d", "3"], "--a"),
        (["--a", "1", "--b", "1", "--c", "1", "--d", "5"], "cannot assemble"),
        # within [|b-c|, b+c] but 1e-100 of the links: was "outside [|b-c|, b+c] = [0, 2e+100]"
        (["--a", "1", "--b", "1e100", "--c", "1e100", "--d", "1", "--phi", "30"], "is under 1e-12 of b+c"),
        (["--a", "1", "--b", "3", "--c", "2.5", "--d", "3", "--branch", "2"], "--branch"),
        (["--a", "1", "--b", "3", "--c", "2.5", "--d", "3", "--bogus"], "No such option"),
        (["--a", "1", "--b", "3", "--c", "2.5", "--d", "3", "--phi", "5", "--step", "3"], "either --phi"),
        (["--a", "1", "--b", "3", "--c", "2.5", "--d", "3", "--rpm", "1", "--omega", "2"], "either --rpm"),
        (["--a", "1", "--b", "3", "--c", "2.5", "--d", "3", "--step", "0"], "--step"),
        (["--a", "1", "--b", "3", "--c", "2.5", "--d", "3", "--plot", "/nonexistent/x.png"], "does not exist"),
        (["--a", "1", "--b", "3", "--c", "2.5", "--d", "3", "--plot", "x.pdf"], ".png or .svg"),
        (["--a", "nan", "--b", "3", "--c", "2.5", "--d", "3"], "--a"),
        (["--b", "3", "--c", "2.5", "--d", "3"], "--a"),
    ],
)
def test_bad_input_is_one_line_exit_2(capsys, tmp_path, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, "analyze", "fourbar", *args)
    assert code == 2
    assert out == ""
    assert len(err.strip().splitlines()) == 1 and message in err
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_a_far_ground_pivot_is_one_line_and_no_warning(capsys, tmp_path, monkeypatch):
    """|A−B0| = 1e100 with unit links: Heron's product overflowed, and numpy's overflow warning
    reached the terminal above the error line (the loop was flagged all the same)."""
    monkeypatch.chdir(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # pytest would otherwise collect the warning, not print it
        code, out, err = run(capsys, "analyze", "fourbar", "--a", "1", "--b", "1", "--c", "1", "--d", "1e100")
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and "cannot assemble" in err


def test_a_linkage_at_1e_minus_150_reads_as_at_unit_scale(capsys, tmp_path, monkeypatch):
    """A rhombus at 1e-150 a hair past its fold (|A−B0| = 1e-9 of the links): the loop's
    1/(2·l1·r) overflowed, and the angles came out null with numpy's warnings on the terminal.
    Every angle and rate is the unit-scale linkage's; positions scale with the links."""
    monkeypatch.chdir(tmp_path)
    docs = []
    for scale in ("1e-150", "1"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            code, out, err = run(
                capsys,
                "analyze",
                "fourbar",
                "--a",
                scale,
                "--b",
                scale,
                "--c",
                scale,
                "--d",
                scale,
                "--phi",
                "5.7e-8",
                "--json",
            )
        assert code == 0 and err == "", err
        docs.append(json.loads(out)["positions"][0])
    tiny, unit = docs
    for key in (
        "theta_deg",
        "gamma_deg",
        "omega_coupler_rad_s",
        "omega_rocker_rad_s",
        "alpha_coupler_rad_s2",
        "transmission_deg",
    ):
        assert tiny[key] is not None and tiny[key] == pytest.approx(unit[key], rel=1e-6, abs=1e-12), key
    assert tiny["Bx_mm"] == pytest.approx(unit["Bx_mm"] * 1e-150, rel=1e-9)


def test_non_grashof_range_inside_reach_works(capsys):
    # triple rocker: reachable crank angles only; inside them the analysis runs
    code, out, err = run(
        capsys,
        "analyze",
        "fourbar",
        "--a",
        "2",
        "--b",
        "3",
        "--c",
        "3.5",
        "--d",
        "5",
        "--from",
        "-30",
        "--to",
        "30",
        "--step",
        "10",
        "--json",
    )
    assert code == 0, err
    doc = json.loads(out)
    assert doc["summary"]["grashof"] == "triple-rocker"
    ((lo, hi),) = doc["summary"]["crank_range_deg"]
    assert lo < -30 and hi > 30
