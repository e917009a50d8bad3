"""``dwell demo`` (analysis version): tables, JSON, plots and drawings of both mechanisms."""

from __future__ import annotations

import json

import pytest

from cli.main import main


def test_demo_writes_everything(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert "time_ratio" in stdout and "stroke_mm: 180" in stdout
    names = {p.name for p in out.iterdir()}
    for mech in ("fourbar", "shaper"):
        assert {f"{mech}.txt", f"{mech}.json", f"{mech}_motion.png", f"{mech}.svg"} <= names
    shaper = json.loads((out / "shaper.json").read_text())
    assert shaper["summary"]["stroke_mm"] == pytest.approx(2 * 300 * 60 / 200, rel=1e-12)  # 2·l3·l1/h
    row90 = next(r for r in shaper["positions"] if r["phi1_deg"] == 90)
    assert row90["s5_mm"] == pytest.approx(74.8331477355, rel=1e-10)


def test_demo_refuses_a_file_as_folder(tmp_path, capsys):
    target = tmp_path / "file"
    target.write_text("keep me")
    assert main(["demo", "--out", str(target)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert target.read_text() == "keep me"
