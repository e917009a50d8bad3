"""``dwell bench kinematics`` prints machine-readable JSON with speed and error side by side."""

from __future__ import annotations

import json

from cli.main import main


def test_bench_kinematics_json(capsys):
    code = main(["bench", "kinematics", "--n", "1,20", "--angles", "36", "--repeat", "1"])
    out, err = capsys.readouterr()
    assert code == 0, err
    doc = json.loads(out)
    assert [r["n"] for r in doc["results"]] == [1, 20]
    for r in doc["results"]:
        assert r["positions"] == r["n"] * 36
        assert r["streamed_positions_per_s"] > 0 and r["single_call_positions_per_s"] > 0
    errors = doc["max_error_vs_extended_precision"]
    assert set(errors) >= {"theta", "dtheta1", "dtheta2", "dtheta3", "dgamma3", "loop_residual"}
    # float64 closed form against extended precision: a few ulps, scaled by the derivatives
    assert max(errors.values()) < 1e-11


def test_bench_kinematics_bad_sizes(capsys):
    assert main(["bench", "kinematics", "--n", "ten"]) == 2
    assert "--n" in capsys.readouterr().err
