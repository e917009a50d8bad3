"""``dwell curvature`` and ``dwell bench curvature|stability``: JSON shape and values, files,
exit codes, one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cli.main import main
from kinematics.fourbar import fourbar_motion
from synth import ball_point, double_ball_points, inflection_circle, line_scan, pole

LINKAGE = ["--a", "1", "--b", "3", "--c", "2.5", "--d", "3"]


def run(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_json_has_the_documented_shape_and_the_kernel_values(capsys):
    code, out, err = run(capsys, "curvature", *LINKAGE, "--phi", "60", "--rays", "4", "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert {"linkage", "phi_deg", "pole", "inflection_circle", "ball_point", "conjugate_pairs", "skipped"} <= set(doc)
    assert doc["linkage"] == {"a": 1.0, "b": 3.0, "c": 2.5, "d": 3.0, "branch": 1}
    assert doc["phi_deg"] == 60.0
    pl = pole(fourbar_motion(1, 3, 2.5, 3, np.radians(60.0)))
    circle, ball = inflection_circle(pl), ball_point(pl)
    xy = lambda z: [float(np.real(z)), float(np.imag(z))]  # noqa: E731
    assert doc["pole"] == pytest.approx(xy(pl.point), abs=1e-12)
    assert doc["inflection_circle"]["center"] == pytest.approx(xy(circle.center), abs=1e-12)
    assert doc["inflection_circle"]["diameter"] == pytest.approx(float(circle.diameter), rel=1e-14)
    assert doc["ball_point"]["xy"] == pytest.approx(xy(ball.point), abs=1e-12)
    assert doc["ball_point"]["uv"] == pytest.approx(xy(ball.uv), abs=1e-12)
    pairs = doc["conjugate_pairs"]
    assert [p["ray_deg"] for p in pairs] == [0.0, 45.0, 90.0, 135.0]
    scan = line_scan(pl, np.radians([0.0, 45.0, 90.0, 135.0]))
    for p, k in zip(pairs, range(4)):
        assert set(p) >= {"ray_deg", "circle_point", "center_point"}
        assert set(p["circle_point"]) == {"xy", "uv"}
        assert p["circle_point"]["xy"] == pytest.approx(xy(scan.circle_point[k]), abs=1e-12)
        assert p["circle_point"]["uv"] == pytest.approx(xy(scan.circle_point_uv[k]), abs=1e-12)
        assert p["center_point"] == pytest.approx(xy(scan.center_point[k]), abs=1e-12)
    assert doc["skipped"] == []
    assert "double_ball_points" not in doc


@pytest.mark.parametrize("scale", [1e-150, 1e100, 1e149])
def test_the_unit_of_length_only_scales_the_answer(capsys, scale):
    """Every length times ``scale`` (the command takes 1e-150 … 1e150): every point and length
    of the answer times ``scale``, no NaN. Before the fix, Heron's product overflowed (NaN
    pole at 1e100) or underflowed (every position a toggle at 1e-150)."""

    def doc(k):
        code, out, err = run(
            capsys,
            "curvature",
            *(f"{float(x) * k!r}" if x[0].isdigit() else x for x in LINKAGE),
            "--phi",
            "60",
            "--rays",
            "4",
            "--json",
        )
        assert code == 0, err
        assert "NaN" not in out and "Infinity" not in out
        return json.loads(out)

    unit, scaled = doc(1.0), doc(scale)
    assert scaled["pole"] == pytest.approx([x * scale for x in unit["pole"]], rel=1e-12)
    assert scaled["inflection_circle"]["diameter"] == pytest.approx(
        unit["inflection_circle"]["diameter"] * scale, rel=1e-12
    )
    assert scaled["ball_point"]["xy"] == pytest.approx([x * scale for x in unit["ball_point"]["xy"]], rel=1e-12)
    for p, q in zip(scaled["conjugate_pairs"], unit["conjugate_pairs"]):
        assert p["center_point"] == pytest.approx([x * scale for x in q["center_point"]], rel=1e-9, abs=1e-9 * scale)


def test_double_ball_points_and_the_dead_centre_skip(capsys):
    code, out, err = run(capsys, "curvature", *LINKAGE, "--phi", "10", "--rays", "0", "--double-ball", "--json")
    assert code == 0, err
    doc = json.loads(out)
    found = double_ball_points(1.0, 3.0, 2.5, 3.0)
    assert len(doc["double_ball_points"]) == len(found) >= 1
    first = doc["double_ball_points"][0]
    assert first["uv"] == pytest.approx([found.uv[0].real, found.uv[0].imag], abs=1e-12)
    assert first["phi_deg"] == pytest.approx(np.degrees([found.phi1[0], found.phi2[0]]).tolist(), abs=1e-10)
    assert len(first["tangent_lines"]) == 2
    assert any("dead-centre" in s["reason"] for s in doc["skipped"])
    assert doc["conjugate_pairs"] == []


def test_pole_at_infinity_gives_nulls_with_their_reason(capsys):
    # a near-translation instant: the pole is at infinity, every point depending on it is null
    grid = np.linspace(0, 2 * np.pi, 3601)
    t1 = fourbar_motion(1, 3, 2.5, 3, grid, order=1).dtheta[0]
    k = int(np.flatnonzero(np.sign(t1[:-1]) != np.sign(t1[1:]))[0])
    lo, hi = grid[k], grid[k + 1]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        same = np.sign(fourbar_motion(1, 3, 2.5, 3, mid, order=1).dtheta[0]) == np.sign(t1[k])
        lo, hi = (mid, hi) if same else (lo, mid)
    code, out, err = run(capsys, "curvature", *LINKAGE, "--phi", repr(float(np.degrees(lo))), "--rays", "2", "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["pole"] is None and doc["ball_point"]["xy"] is None and doc["inflection_circle"]["center"] is None
    assert all(p["circle_point"] is None and p["center_point"] is None for p in doc["conjugate_pairs"])
    assert any(s["what"] == "pole" and "infinity" in s["reason"] for s in doc["skipped"])
    assert "NaN" not in out and "Infinity" not in out


def test_text_output_and_plot(tmp_path, capsys):
    png, svg = tmp_path / "c.png", tmp_path / "c.svg"
    code, out, err = run(
        capsys, "curvature", *LINKAGE, "--phi", "60", "--rays", "3", "--double-ball", "--plot", str(png)
    )
    assert code == 0, err
    assert "inflection circle" in out and "Ball's point" in out and "double Ball points" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    code, out, err = run(capsys, "curvature", *LINKAGE, "--branch", "-1", "--phi", "200", "--plot", str(svg))
    assert code == 0, err
    assert b"<svg" in svg.read_bytes()[:2000]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--phi", "60", "--a", "0"], "--a"),
        (["--phi", "nan"], "--phi"),
        (["--rays", "-1", "--phi", "0"], "--rays"),
        (["--branch", "2", "--phi", "0"], "--branch"),
        (["--phi", "0", "--plot", "out.pdf"], "--plot"),
        (["--phi", "0", "--bogus"], "No such option"),
        ([], "--phi"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, "curvature", *LINKAGE, *args)
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1
    assert out == "" and list(tmp_path.iterdir()) == []


def test_position_that_cannot_assemble_is_refused(tmp_path, capsys):
    plot = tmp_path / "x.png"
    code, out, err = run(
        capsys, "curvature", "--a", "1", "--b", "1.2", "--c", "1.5", "--d", "2.5", "--phi", "180", "--plot", str(plot)
    )
    assert code == 2 and "cannot assemble" in err and len(err.strip().splitlines()) == 1
    assert not plot.exists()


def test_bench_curvature_json(capsys):
    code, out, err = run(
        capsys,
        "bench",
        "curvature",
        "--linkages",
        "3",
        "--angles",
        "20",
        "--repeat",
        "1",
        "--double-ball-linkages",
        "2",
    )
    assert code == 0, err
    doc = json.loads(out)
    assert doc["rays"] == 36 and doc["instants"] == 60 and doc["instants_per_s"] > 0
    assert set(doc["time_share"]) == {"fourbar_motion", "pole", "inflection_circle", "ball_point", "line_scan"}
    assert doc["double_ball"]["linkages"] == 2 and doc["double_ball"]["seconds_per_linkage"] > 0
    assert max(doc["max_residual_vs_extended_precision"].values()) < 1e-9


def test_bench_stability_json(capsys):
    code, out, err = run(capsys, "bench", "stability", "--n", "300", "--seed", "2")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["cases"] == 300 and doc["nonfinite_values"] == 0 and doc["exceptions"] == {}
    assert set(doc["flagged"]) == {"pole", "inflection_circle", "ball_point", "line_scan", "euler_savary"}
    code, out, err = run(capsys, "bench", "stability", "--n", "0")
    assert code == 2 and "--n" in err


def test_text_at_a_toggle_says_why_before_anything_else(capsys):
    # the rhombus at phi = 180 deg: coupler and rocker aligned, no pole, nothing to tabulate
    code, out, err = run(capsys, "curvature", "--a", "1", "--b", "1", "--c", "1", "--d", "1", "--phi", "180")
    assert code == 0, err
    lines = out.splitlines()
    assert lines[1].startswith("no pole at this instant") and "toggle position" in lines[2]
    assert "ray[deg]" not in out and " - " not in out and "skipped:" not in out
