"""``dwell analyze slider-crank`` and ``dwell analyze shaper``: JSON values, files, exit codes."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cli.main import main

SLIDER = ["analyze", "slider-crank", "--crank", "50", "--rod", "150", "--offset", "20"]
SHAPER = ["analyze", "shaper", "--crank", "60", "--rod", "300", "--link", "150", "--height", "200", "--offset", "30"]


def run(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def run_json(capsys, *args):
    code, out, err = run(capsys, *args, "--json")
    assert code == 0, err
    return json.loads(out)


def assert_rows_match(rows, reference_rows, rel=1e-9):
    """Every reference key, every row, relative to the column's magnitude (zeros included)."""
    assert len(rows) == len(reference_rows)
    for key in reference_rows[0]:
        want = np.array([r[key] for r in reference_rows], float)
        got = np.array([r[key] for r in rows], float)
        np.testing.assert_allclose(got, want, rtol=rel, atol=rel * max(1.0, float(np.abs(want).max())), err_msg=key)


def test_slider_crank_json_is_the_reference_table(capsys, reference_cases):
    doc = run_json(capsys, *SLIDER)
    assert_rows_match(doc["positions"], reference_cases["offset_slider_crank_reference"]["rows"])
    s = doc["summary"]
    assert s["full_turn"] is True and s["crank_range_deg"] == [[-180.0, 180.0]]
    assert s["stroke_mm"] == pytest.approx(math.sqrt(200**2 - 20**2) - math.sqrt(100**2 - 20**2), rel=1e-14)
    assert s["limit_positions"]["s3_max_mm"] == pytest.approx(math.sqrt(200**2 - 20**2), rel=1e-14)
    assert s["time_ratio"] == pytest.approx(1.066563891554241, rel=1e-12)
    assert doc["mechanism"]["crank_speed_rad_s"] == pytest.approx(2 * math.pi)


def test_shaper_json_is_the_reference_table(capsys, reference_cases):
    doc = run_json(capsys, *SHAPER)
    assert_rows_match(doc["positions"], reference_cases["shaper_crank_guiderod_slider_reference"]["rows"])
    s = doc["summary"]
    turn = math.asin(0.3)
    assert s["stroke_mm"] == pytest.approx(180.0, rel=1e-14)
    assert s["time_ratio"] == pytest.approx((math.pi + 2 * turn) / (math.pi - 2 * turn), rel=1e-13)
    assert s["rod_swing_deg"] == pytest.approx(math.degrees(2 * turn), rel=1e-14)
    assert s["limit_positions"]["phi1_max_deg"] == pytest.approx(360 - math.degrees(turn), rel=1e-13)
    assert s["reversals_per_turn"] == 2


@pytest.mark.parametrize(
    "base, velocities",
    [(SLIDER, ["omega2_rad_s", "v3_mm_s"]), (SHAPER, ["v2_mm_s", "omega3_rad_s", "omega4_rad_s", "v5_mm_s"])],
)
def test_clockwise_flips_every_velocity(capsys, base, velocities):
    ccw = run_json(capsys, *base, "--phi", "40")["positions"][0]
    cw = run_json(capsys, *base, "--phi", "40", "--cw")["positions"][0]
    for key, value in ccw.items():
        assert cw[key] == (-value if key in velocities else value), key


def test_p204101_inclined_guide(capsys, reference_cases):
    case = reference_cases["P204101_offset_slider_crank"]
    for branch, row in zip(("1", "-1"), case["rows"]):
        doc = run_json(
            capsys,
            "analyze",
            "slider-crank",
            "--crank",
            "50",
            "--rod",
            "100",
            "--offset",
            "40",
            "--guide-angle",
            "30",
            "--phi",
            "60",
            "--branch",
            branch,
        )
        got = doc["positions"][0]
        assert [got["phi2_deg"], got["s3_mm"]] == pytest.approx(row["solver"], rel=1e-9)


def test_slider_crank_inside_a_partial_reach(capsys):
    # l1 + |e| > l2: no full turn, no limit positions, but reachable angles analyse fine.
    doc = run_json(
        capsys,
        "analyze",
        "slider-crank",
        "--crank",
        "50",
        "--rod",
        "30",
        "--offset",
        "10",
        "--from",
        "-50",
        "--to",
        "20",
        "--step",
        "10",
        "--units",
        "in",
    )
    assert doc["summary"]["full_turn"] is False and "limit_positions" not in doc["summary"]
    assert len(doc["summary"]["crank_range_deg"]) == 2
    assert len(doc["positions"]) == 8 and "v3_in_s" in doc["positions"][0]


@pytest.mark.parametrize("base, plotted", [(SLIDER, "v3[mm/s]"), (SHAPER, "v5[mm/s]")])
def test_table_plot_and_drawing(tmp_path, capsys, base, plotted):
    plot, draw = tmp_path / "m.png", tmp_path / "m.svg"
    code, out, err = run(
        capsys, *base, "--from", "0", "--to", "90", "--step", "45", "--plot", str(plot), "--draw", str(draw)
    )
    assert code == 0, err
    assert plotted in out and "time_ratio" in out and "stroke_mm" in out
    assert len([ln for ln in out.splitlines() if ln.strip().startswith(("0 ", "45 ", "90 "))]) == 3
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"<svg" in draw.read_bytes()[:2000]


@pytest.mark.parametrize(
    "args, message",
    [
        (["slider-crank", "--crank", "-50", "--rod", "150"], "--crank"),
        (["slider-crank", "--crank", "50", "--rod", "0"], "--rod"),
        (["slider-crank", "--crank", "50", "--rod", "150", "--offset", "nan"], "--offset"),
        (["slider-crank", "--crank", "50", "--rod", "150", "--guide-angle", "inf"], "--guide-angle"),
        (["slider-crank", "--crank", "50", "--rod", "150", "--branch", "0"], "--branch"),
        (["slider-crank", "--rod", "150"], "--crank"),
        (
            ["slider-crank", "--crank", "50", "--rod", "30", "--offset", "10"],
            "reachable crank angles [deg]: [-53.1301, 23.5782]",
        ),
        (
            ["slider-crank", "--crank", "50", "--rod", "70", "--offset", "20", "--phi", "90"],
            "perpendicular to the guide",
        ),
        (["shaper", "--crank", "60", "--rod", "300", "--link", "150", "--height", "50"], "l1 < h"),
        (["shaper", "--crank", "60", "--rod", "250", "--link", "150", "--height", "200"], "l1 + h < l3"),
        (["shaper", "--crank", "60", "--rod", "300", "--link", "100", "--height", "200"], "l3 + e - h < l4"),
        (
            ["shaper", "--crank", "190", "--rod", "400", "--link", "150", "--height", "200", "--offset", "-100"],
            "h - e - l3*sqrt(1 - (l1/h)^2) < l4",
        ),
        (["shaper", "--crank", "60", "--rod", "300", "--link", "-150", "--height", "200"], "--link"),
        (["shaper", "--crank", "60", "--rod", "300", "--link", "150", "--height", "200", "--bogus"], "No such option"),
    ],
)
def test_bad_input_is_one_line_exit_2(capsys, tmp_path, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, "analyze", *args, "--plot", "m.png")
    assert code == 2
    assert out == ""
    assert len(err.strip().splitlines()) == 1 and message in err
    assert list(tmp_path.iterdir()) == []  # nothing written
