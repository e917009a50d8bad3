"""``dwell analyze fourbar --stats``: JSON against the kernel, plot, exit codes."""

from __future__ import annotations

import json

import pytest

from cli.main import main
from kinematics.fourbar_stats import output_speed_stats

BASE = ["analyze", "fourbar", "--a", "20", "--b", "80", "--c", "60", "--d", "90", "--stats"]


def run(capsys, *args):
    code = main([*BASE, *map(str, args)])
    out, err = capsys.readouterr()
    return code, out, err


def test_json_matches_the_kernel(capsys):
    code, out, err = run(capsys, "--crank-lengths", "10,20,30,70", "--rpms", "60,150", "--phases", "3", "--json")
    assert code == 0, err
    doc = json.loads(out)
    rows = doc["stats"]
    assert [(r["crank_mm"], r["n_in_rpm"]) for r in rows] == [(a, n) for a in (10, 20, 30, 70) for n in (60, 150)]
    st = output_speed_stats([10, 20, 30], 80, 60, 90, [60, 150], phases=3)
    for k, row in enumerate(rows[:6]):
        i, j = divmod(k, 2)
        assert row["mean_out_rad_s"] == pytest.approx(st.mean[i, j], rel=1e-12)
        assert row["cv"] == pytest.approx(st.cv[i, j], rel=1e-12)
        assert row["ratio_max"] == pytest.approx(st.ratio_max[i, j], rel=1e-12)
    assert rows[6]["mean_out_rad_s"] is None  # a 70 mm crank cannot turn: shown as null, flagged
    summary = doc["summary"]
    assert summary["crank_lengths_without_full_turn"] == [70.0]
    best = summary["cv_minimum"]
    assert 10 <= best["a"] <= 70 and best["cv"] <= min(r["cv"] for r in rows if r["cv"] is not None) + 1e-12


def test_table_and_plot(tmp_path, capsys):
    plot = tmp_path / "stats.png"
    code, out, err = run(
        capsys, "--crank-lengths", "10,30", "--cv-bounds", "a=10:40", "--cv-bounds", "c=50:70", "--plot", plot
    )
    assert code == 0, err
    assert "cv_minimum" in out and "mean_out[rpm]" in out
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    "args, message",
    [
        (["--crank-lengths", "10,x"], "--crank-lengths"),
        (["--rpms", "-5"], "--rpms"),
        (["--cv-bounds", "e=1:2"], "--cv-bounds"),
        (["--cv-bounds", "a=3:1"], "--cv-bounds"),
        (["--phases", "0"], "--phases"),
        (["--clutch", "ratchet"], "--clutch"),
    ],
)
def test_bad_input_exits_2(capsys, args, message):
    code, out, err = run(capsys, *args)
    assert code == 2 and message in err and err.count("\n") == 1
