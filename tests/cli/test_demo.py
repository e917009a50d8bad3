"""``dwell demo``: builds the demo atlas, answers the three sample requests, writes reports."""

from __future__ import annotations

import json

from linkage_checks import check_linkage_files

from cli.main import main


def test_demo_answers_every_request_and_writes_reports(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert stdout.count("best: ") == 3, stdout
    for name, kind, dwells in (("rrr", "RRR", 1), ("rpr", "RPR", 1), ("double", "RPR", 2)):
        doc = json.loads((out / name / "candidates.json").read_text())
        best = doc["candidates"][0]
        assert best["output"]["type"] == kind
        assert len(best["dwells"]) == dwells
        assert (out / name / "index.html").stat().st_size > 10_000
    # the double request names the output's motion (issue #41): every answer swings 12° ± 2°,
    # its two rests are ≥ 5° of crank apart each way round, and its output accelerations are a
    # double dwell's of that swing (before: 140°–160° swings at 3 000–4 000 rad/s², 60 rpm)
    doc = json.loads((out / "double" / "candidates.json").read_text())
    assert doc["request"]["swing_deg"] == 12 and doc["request"]["swing_tol_deg"] == 2
    for cand in doc["candidates"]:
        assert abs(cand["swing_deg"] - 12) <= 2 and cand["step_deg"] <= cand["swing_deg"]
        (s0, e0), (s1, e1) = (d["interval_deg"] for d in cand["dwells"])
        assert min((s1 - e0) % 360, (s0 - e1) % 360) >= 5
        assert cand["buildability"]["peak_output_accel_rad_s2"] < 100

    # every candidate's linkage file, solved by dwell analyze linkage, gives its figures (issue 14)
    def run(argv):
        assert main(argv) == 0
        return capsys.readouterr().out

    checked = sum(check_linkage_files(out / name, run) for name in ("rrr", "rpr", "double"))
    assert checked >= 3
    # a second run reuses the atlas (nothing to rebuild) and gives the same answers
    first = (out / "rpr" / "candidates.csv").read_text()
    assert main(["demo", "--out", str(out)]) == 0
    assert (out / "rpr" / "candidates.csv").read_text() == first


def test_demo_refuses_a_file_as_folder(tmp_path, capsys):
    target = tmp_path / "file"
    target.write_text("keep me")
    assert main(["demo", "--out", str(target)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert target.read_text() == "keep me"
