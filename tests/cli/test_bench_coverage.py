"""``dwell bench coverage`` on a small built atlas: the grid of issue #13, each cell the query's
own answer, a summary that counts the cells, a heat map."""

from __future__ import annotations

import json

import pytest

from cli.bench.coverage import DOUBLE_DWELLS, DOUBLE_SWINGS, SINGLE_DWELLS, SWINGS
from cli.main import main
from synth.query import CONSTRAINTS


def run(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_coverage_grid_matches_the_query_cell_by_cell(capsys, coverage_atlas, tmp_path):
    plot = tmp_path / "coverage.png"
    # without refinement: the grid's 148 cells in seconds (refined, minutes); the cells are
    # held to `dwell query` below in the same mode
    code, out, err = run(
        capsys, "bench", "coverage", "--db", coverage_atlas, "--top", "5", "--no-refine", "--json", "--plot", str(plot)
    )
    assert code == 0, err
    summary = err
    doc = json.loads(out)
    cells = doc["cells"]
    assert len(cells) == 2 * len(SINGLE_DWELLS) * len(SWINGS) + len(DOUBLE_DWELLS) * len(DOUBLE_SWINGS)
    assert {(c["dwell_deg"], c["swing_deg"]) for c in cells if c["family"] == "rrr"} == {
        (d, s) for d in SINGLE_DWELLS for s in SWINGS
    }
    # two dwells name the output's swing (issue #41)
    assert [(c["dwell_deg"], c["swing_deg"]) for c in cells if c["family"] == "double"] == [
        (d, s) for d in DOUBLE_DWELLS for s in DOUBLE_SWINGS
    ]
    for fam, v in doc["summary"].items():
        mine = [c for c in cells if c["family"] == fam]
        assert v == {
            "cells": len(mine),
            "answered": sum(c["candidates"] >= 1 for c in mine),
            "three_or_more": sum(c["candidates"] >= 3 for c in mine),
        }
    assert all(0 <= c["candidates"] <= 5 and c["ms"] > 0 for c in cells)
    assert all((c["best_deviation_deg"] is None) == (c["candidates"] == 0) for c in cells)
    assert doc["summary"]["rpr"]["answered"] >= 10, "the demo sweep answers many RPR cells"
    # two cells against `dwell query` itself: same candidates, same best deviation (the double
    # row refined: the test atlas's double dwells are refined near misses; its 10° row's two
    # cells answer in ~1 s, where the whole row reaches for misses in 16 cells for ~100 s)
    code, out, err = run(
        capsys,
        "bench",
        "coverage",
        "--db",
        coverage_atlas,
        "--family",
        "double",
        "--dwell",
        "10",
        "--top",
        "5",
        "--json",
    )
    assert code == 0, err
    doubles = json.loads(out)["cells"]
    for cell, args in (
        (next(c for c in cells if c["family"] == "rpr" and c["candidates"] > 0), ["--no-refine"]),
        (next(c for c in doubles if c["candidates"] > 0), ["--dwells", "2", "--dwell-tol", "5"]),
    ):
        extra = ["--swing", f"{cell['swing_deg']:g}", "--output", "rpr"]
        code, out, _ = run(
            capsys,
            "query",
            "--db",
            coverage_atlas,
            "--dwell",
            f"{cell['dwell_deg']:g}",
            *extra,
            *args,
            "--top",
            "5",
            "--json",
        )
        got = json.loads(out)["candidates"]
        assert len(got) == cell["candidates"] and got[0]["id"] == cell["best"]
        best = min(max(d["output_deviation_deg"] for d in c["dwells"]) for c in got)
        assert best == pytest.approx(cell["best_deviation_deg"], abs=1e-5)
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "rpr" in summary and "cells with ≥ 3" in summary


def test_coverage_table_and_bad_input(capsys, coverage_atlas, tmp_path):
    # the table's form (the refined grid is the test above's; --no-refine keeps this one short)
    code, out, err = run(capsys, "bench", "coverage", "--db", coverage_atlas, "--top", "3", "--no-refine")
    assert code == 0, err
    assert out.startswith("coverage of demo") and "RRR" in out and "DOUBLE" in out
    code, out, err = run(capsys, "bench", "coverage", "--db", coverage_atlas, "--top", "0")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    code, out, err = run(capsys, "bench", "coverage", "--db", str(tmp_path / "none.sqlite"))
    assert code == 2 and out == ""
    # --dwell keeps the grid's rows of those dwells; one that is no row is bad input
    code, out, err = run(
        capsys,
        "bench",
        "coverage",
        "--db",
        coverage_atlas,
        "--family",
        "rrr",
        "--dwell",
        "10",
        "--dwell",
        "180",
        "--no-refine",
        "--json",
    )
    assert code == 0, err
    rows = json.loads(out)["cells"]
    assert [(c["family"], c["dwell_deg"], c["swing_deg"]) for c in rows] == [
        ("rrr", d, s) for d in (10, 180) for s in SWINGS
    ]
    assert all(c["in_the_way"] is None or c["in_the_way"][0] in CONSTRAINTS for c in rows)
    assert all(c["short_of"] is None for c in rows)  # named by the fill, which --no-refine skips
    code, out, err = run(capsys, "bench", "coverage", "--db", coverage_atlas, "--dwell", "11")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and "--dwell" in err


def test_query_complete_holds_every_sampled_answer(capsys, coverage_atlas):
    """``dwell query --complete``: every six-bar the default (sampled) query returns meets the
    request, so the complete search returns it too (or its mirror image, or a better-ranked
    six-bar of the same segment)."""
    args = [
        "query",
        "--db",
        coverage_atlas,
        "--dwell",
        "45",
        "--swing",
        "40",
        "--output",
        "rpr",
        "--top",
        "1000",
        "--no-refine",
    ]
    code, out, err = run(capsys, *args, "--json")
    assert code == 0, err
    sampled = json.loads(out)["candidates"]
    code, out, err = run(capsys, *args, "--complete", "--json")
    assert code == 0, err
    complete = json.loads(out)["candidates"]
    assert len(complete) > len(sampled) >= 1
    curve = lambda c: (
        round(c["fourbar"]["b_mm"], 6),
        round(c["fourbar"]["c_mm"], 6),
        round(c["fourbar"]["d_mm"], 6),  # noqa: E731
        round(c["coupler_point_mm"][0], 3),
        round(abs(c["coupler_point_mm"][1]), 3),
    )
    assert {curve(c) for c in sampled} <= {curve(c) for c in complete}
    code, out, err = run(capsys, *args, "--complete")
    assert code == 0 and "segment levels searched: all" in out.splitlines()[0]
