"""``dwell bench coverage --complete`` on a small built atlas: every cell answered by the
complete search, with the share the sampled query finds (apart from the grid's tests in
``test_bench_coverage.py``, so that the two long runs go to different workers)."""

from __future__ import annotations

import json

from cli.bench.coverage import DOUBLE_SWINGS
from cli.main import main


def run(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_complete_coverage_measures_the_sampled_query_against_it(capsys, coverage_atlas, tmp_path):
    """``--complete --family double``: every cell answered by the complete search (all its
    six-bars), with the share of them the sampled query finds; the table and the plot of one
    family."""
    plot = tmp_path / "double.png"
    rows = (60,)  # two of the sixteen cells: the complete search over the rest is the same code
    code, out, err = run(
        capsys,
        "bench",
        "coverage",
        "--db",
        coverage_atlas,
        "--family",
        "double",
        "--complete",
        "--json",
        "--plot",
        str(plot),
        *(f"--dwell={d}" for d in rows),
    )
    assert code == 0, err
    doc = json.loads(out)
    assert doc["complete"] is True and list(doc["summary"]) == ["double"]
    cells = doc["cells"]
    assert [(c["dwell_deg"], c["swing_deg"]) for c in cells] == [(d, s) for d in rows for s in DOUBLE_SWINGS]
    for c in cells:
        assert c["candidates"] == min(10, c["complete"])
        assert (c["recall"] is None) == (c["complete"] == 0)
        assert c["recall"] is None or 0.0 <= c["recall"] <= 1.0
    v = doc["summary"]["double"]
    # the test atlas holds no double dwell within the default limits at a swing of 20° or 45°
    # (± 0.5°; its double dwells that keep them swing less or 135°–155°, issue #41): the
    # complete search answers none of these cells, and there is no recall to report
    assert v["complete"] == sum(c["complete"] for c in cells) == 0 and v.get("recall") is None
    # the sample is a subset of the complete answer: it never finds more curves than there are
    assert all(c["sampled"] <= c["complete"] for c in cells)
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "the sampled query finds" not in err and "double 0/2 cells with ≥ 3 (0 with ≥ 1)" in err
    code, out, err = run(
        capsys, "bench", "coverage", "--db", coverage_atlas, "--family", "double", "--top", "3", "--dwell=60"
    )
    assert code == 0 and out.count("DOUBLE") == 1 and "RPR" not in out
