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
