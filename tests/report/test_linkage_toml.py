"""Linkage files of a report (issue 14): each candidate as ``NN-ID.toml`` that ``dwell analyze
linkage`` reads and solves to the candidate's swing, dwell interval(s) and transmission angles
(checked on the demo's real candidates in tests/cli/test_demo.py too)."""

from __future__ import annotations

import math
import tomllib

import pytest
from harness.report_cases import EVIL_ID
from linkage_checks import check_linkage_files

from cli.main import main


def _run(capsys):
    def run(argv):
        code = main(argv)
        out, err = capsys.readouterr()
        assert code == 0, err
        return out

    return run


def test_report_linkage_files_reproduce_the_candidates(report_dir, capsys):
    out, written = report_dir
    assert sum(p.suffix == ".toml" for p in written) == 3
    assert check_linkage_files(out, _run(capsys)) == 3


def test_double_dwell_linkage_files_reproduce_both_dwells(double_report_dir, capsys):
    out, _, cands = double_report_dir
    assert check_linkage_files(out, _run(capsys)) == len(cands)


def test_the_same_description_in_json_is_the_candidate_too(report_dir, tmp_path, capsys):
    out, _ = report_dir
    assert check_linkage_files(out, _run(capsys), as_json=tmp_path) == 3


def test_the_file_names_the_configuration_band_and_dwells(report_dir, double_report_dir, candidates):
    """The keys that make the file the candidate (that the configuration key matters —
    numbers other than 1 — is held by tests/report/test_linkage_round_trip.py)."""
    from harness.report_cases import REQUEST, REQUEST2

    seen = set()
    for folder, request in ((report_dir[0], REQUEST), (double_report_dir[0], REQUEST2)):
        for path in folder.glob("*.toml"):
            data = tomllib.loads(path.read_text(encoding="utf-8"))
            seen.add(data["configuration"])
            assert data["output"]["band"] == pytest.approx(math.degrees(request.band), abs=1e-12)
            assert data["output"]["dwells"] == request.dwells and data["inputs"][0]["value"] == 0.0
            assert "--configuration" not in path.read_text(encoding="utf-8")
    assert seen == {1}  # these four-bars and dyads are all on their branch +1


def test_a_hostile_id_stays_in_a_comment_and_a_string(report_dir, candidates):
    """The id is user text: it must not add TOML keys (a newline in it would)."""
    import dataclasses

    from report.linkage_toml import linkage_toml

    out, _ = report_dir
    names = {tomllib.loads(p.read_text(encoding="utf-8"))["name"] for p in out.glob("*.toml")}
    assert f"six-bar {EVIL_ID}" in names
    hostile = dataclasses.replace(candidates[0], id='x"\n[evil]\nkey = 1\n# \u2028')
    data = tomllib.loads(linkage_toml(hostile, "mm"))
    from report.escape import terminal

    assert "evil" not in data and data["name"] == f"six-bar {terminal(hostile.id)}"  # its controls escaped
