"""``dwell query`` on a small built atlas: every returned candidate re-simulated independently.

The independent simulation is the plain per-angle loop of :mod:`harness.plain_sixbar`
(circle intersections with cmath, no numpy, no code of ``synth``), at 0.05° steps; its dwell
is the longest run of samples within the band (so it may be up to one step shorter).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from harness.plain_sixbar import reference_psi

from atlas.build import build_atlas
from atlas.sweep import PRESETS
from cli.main import main
from report.candidate_json import sixbar_from_json
from synth.mechanism.sixbar import simulate

SPEC = PRESETS["demo"].replace(samples=384)
STEP = 0.05  # degrees


@pytest.fixture(scope="module")
def atlas_path(tmp_path_factory) -> str:
    path = str(tmp_path_factory.mktemp("atlas") / "demo.sqlite")
    build_atlas(path, SPEC, workers=1)
    return path


def run(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def _independent(doc: dict, band_deg: float) -> dict:
    sb = sixbar_from_json(doc)
    n = round(360 / STEP)
    psi, prev = [], None
    for k in range(n):
        got = reference_psi(sb, math.radians(k * STEP))
        assert got is not None, "the six-bar must assemble over the whole turn"
        p = got[0]
        if prev is not None:  # unwrap
            p += 2 * math.pi * round((prev - p) / (2 * math.pi))
        psi.append(p)
        prev = p
    swing = math.degrees(max(psi) - min(psi))
    # longest cyclic run of samples within a band of total width band_deg
    band = math.radians(band_deg)
    best, ext = 0, psi + psi
    j = 0
    for i in range(len(ext)):
        j = max(j, i)
        while j < min(len(ext), i + n) and max(ext[i : j + 1]) - min(ext[i : j + 1]) <= band:
            j += 1
        best = max(best, j - i)
        if best >= n:
            break
    return {"swing_deg": swing, "dwell_deg": (best - 1) * STEP}


def test_rpr_request_candidates_resimulated_independently(capsys, atlas_path):
    code, out, err = run(
        capsys, "query", "--db", atlas_path, "--dwell", "45", "--swing", "40", "--output", "rpr", "--top", "3", "--json"
    )
    assert code == 0, err
    doc = json.loads(out)
    assert doc["request"]["dwell_deg"] == 45
    cands = doc["candidates"]
    assert cands, "the demo sweep must answer an RPR 45°/40° request"
    for rank, cand in enumerate(cands, start=1):
        assert cand["rank"] == rank
        assert set(cand) >= {
            "rank",
            "id",
            "length_unit",
            "fourbar",
            "coupler_point_mm",
            "output",
            "dwells",
            "swing_deg",
            "transmission_deg",
            "link_ratio",
            "footprint_mm2",
            "segment_id",
        }
        assert set(cand["fourbar"]) == {"a_mm", "b_mm", "c_mm", "d_mm", "branch"}
        assert all(0 <= x < 360 for dw in cand["dwells"] for x in dw["interval_deg"])
        assert cand["output"]["type"] == "RPR"
        assert abs(cand["dwells"][0]["dwell_deg"] - 45) <= 2
        assert abs(cand["swing_deg"] - 40) <= 0.5
        assert cand["transmission_deg"]["fourbar_min"] >= 30
        ref = _independent(cand, 0.1)
        assert ref["swing_deg"] == pytest.approx(cand["swing_deg"], abs=0.01)
        # the sampled run is at most two steps shorter than the refined dwell, and the refined
        # ends are within 0.01° each of the true ones
        assert cand["dwells"][0]["dwell_deg"] - 2 * STEP <= ref["dwell_deg"] <= cand["dwells"][0]["dwell_deg"] + 0.02


def test_json_keys_carry_units(capsys, atlas_path):
    """Lengths carry the --units suffix and scale with --crank; the same six-bar comes back
    from the document; every crank angle lies in [0°, 360°)."""
    args = ("query", "--db", atlas_path, "--dwell", "45", "--swing", "40", "--output", "rpr", "--top", "3", "--json")
    code, out, err = run(capsys, *args)
    assert code == 0, err
    unit_doc = json.loads(out)
    code, out, err = run(capsys, *args, "--units", "in", "--crank", "2.5")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["request"]["length_unit"] == "in" and doc["request"]["crank_in"] == 2.5
    assert doc["request"]["band_deg"] == 0.1 and "dwell_tolerance_deg" not in doc["request"]
    for cand, one in zip(doc["candidates"], unit_doc["candidates"], strict=True):
        assert cand["length_unit"] == "in" and cand["fourbar"]["a_in"] == 2.5
        assert cand["coupler_point_in"] == pytest.approx([2.5 * x for x in one["coupler_point_mm"]], rel=1e-12)
        assert cand["output"]["pivot_in"] == pytest.approx([2.5 * x for x in one["output"]["pivot_mm"]], rel=1e-12)
        assert cand["footprint_in2"] == pytest.approx(6.25 * one["footprint_mm2"], rel=1e-9)
        assert cand["buildability"]["clearance_in"] == pytest.approx(2.5 * one["buildability"]["clearance_mm"])
        assert sixbar_from_json(cand) == sixbar_from_json(one).scaled(2.5)
        for dw in cand["dwells"]:
            lo, hi = dw["interval_deg"]
            assert 0 <= lo < 360 and 0 <= hi < 360
            assert (hi - lo) % 360 == pytest.approx(dw["dwell_deg"], abs=1e-9)


@pytest.mark.parametrize("dwell, swing, min_arm", [(50, 12, "0.2"), (30, 5, "0")])
def test_double_dwell_request(capsys, atlas_path, dwell, swing, min_arm):
    """The demo's double dwell (50°, two rests 12° ± 2° apart), and 30° (issue 13's example)
    once the slider may run over its own pivot (--min-arm 0: issue 14's unbuildable candidate).
    Every answer swings as asked and its two rests are two (issue #41): ≥ 5° of crank apart."""
    code, out, err = run(
        capsys,
        "query",
        "--db",
        atlas_path,
        "--dwell",
        str(dwell),
        "--dwell-tol",
        "5",
        "--dwells",
        "2",
        "--swing",
        str(swing),
        "--swing-tol",
        "2",
        "--min-arm",
        min_arm,
        "--json",
    )
    assert code == 0, err
    cands = json.loads(out)["candidates"]
    assert cands, f"the demo atlas answers a {dwell}° double dwell"
    for cand in cands:
        assert len(cand["dwells"]) == 2
        assert cand["buildability"]["arm_mm"] >= float(min_arm)
        for dw in cand["dwells"]:
            assert abs(dw["dwell_deg"] - dwell) <= 5
        assert abs(cand["swing_deg"] - swing) <= 2
        (s0, e0), (s1, e1) = (d["interval_deg"] for d in cand["dwells"])
        assert min((s1 - e0) % 360, (s0 - e1) % 360) >= 5
        ref = _independent(cand, 0.1)
        assert ref["swing_deg"] == pytest.approx(cand["swing_deg"], abs=0.01)


def test_double_dwell_step_between_the_rests(capsys, atlas_path):
    """--step asks for the output's turn between its two rests: every answer has it within
    --swing-tol, checked on an independent simulation (ψ at the middle of each dwell)."""
    base = (
        "query",
        "--db",
        atlas_path,
        "--dwell",
        "50",
        "--dwell-tol",
        "5",
        "--dwells",
        "2",
        "--swing",
        "12",
        "--json",
    )
    code, out, err = run(capsys, *base, "--swing-tol", "2")
    assert code == 0, err
    steps = [c["step_deg"] for c in json.loads(out)["candidates"]]
    assert steps and all(s is not None and s > 0 for s in steps)
    code, out, err = run(capsys, *base, "--step", f"{steps[0]:.3f}", "--swing-tol", "2")
    assert code == 0, err
    cands = json.loads(out)["candidates"]
    assert cands and json.loads(out)["request"]["step_deg"] == float(f"{steps[0]:.3f}")
    for cand in cands:
        assert abs(cand["step_deg"] - steps[0]) <= 2 + 1e-3
        sb = sixbar_from_json(cand)
        rests = []
        for dw in cand["dwells"]:
            lo, hi = dw["interval_deg"]
            mid = math.radians(lo + ((hi - lo) % 360) / 2)
            rests.append(float(simulate(sb, np.array([mid]), order=0).psi[0]))
        turn = abs((rests[1] - rests[0] + math.pi) % (2 * math.pi) - math.pi)
        # ψ mid-dwell is within half the band (0.1°) of the rest
        assert math.degrees(turn) == pytest.approx(cand["step_deg"], abs=0.1 + 1e-6)
    code, out, err = run(capsys, "query", "--db", atlas_path, "--dwell", "50", "--swing", "30", "--step", "20")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and "--dwells 2" in err
    # two dwells name the output's motion: the swing is required, and the step lies within it
    code, out, err = run(capsys, "query", "--db", atlas_path, "--dwell", "50", "--dwell-tol", "5", "--dwells", "2")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and "--swing is required" in err
    code, out, err = run(capsys, *base, "--step", "20")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and "--step 20 is more than --swing 12" in err


def test_table_output_and_no_match(capsys, atlas_path):
    code, out, err = run(
        capsys, "query", "--db", atlas_path, "--dwell", "45", "--swing", "40", "--output", "rpr", "--top", "2"
    )
    assert code == 0, err
    assert "rank" in out and "RPR" in out
    code, out, err = run(capsys, "query", "--db", atlas_path, "--dwell", "300", "--swing", "40", "--json")
    assert code == 1  # none found, as grep: the JSON still says why
    doc = json.loads(out)
    assert doc["candidates"] == [] and doc["no_match"]["message"].startswith("no six-bar meets the request")
    assert "no six-bar meets the request" in err
    code, out, err = run(capsys, "query", "--db", atlas_path, "--dwell", "300", "--swing", "40")
    assert code == 1 and out == "" and err.startswith("dwell: no six-bar meets the request")


@pytest.mark.parametrize(
    "args, message",
    [
        (["--dwell", "0", "--swing", "30"], "--dwell"),
        (["--dwell", "360", "--swing", "30"], "--dwell"),
        (["--dwell", "60", "--swing", "0"], "--swing"),
        (["--dwell", "60", "--swing", "180"], "--swing"),
        (["--dwell", "60", "--swing", "30", "--output", "rrp"], "--output"),
        (["--dwell", "60"], "--swing is required"),
        (["--dwell", "60", "--swing", "30", "--min-transmission", "0"], "--min-transmission"),
        (["--dwell", "60", "--swing", "30", "--min-transmission", "-0"], "--min-transmission"),
        (["--dwell", "60", "--swing", "30", "--min-transmission", "90"], "--min-transmission"),
        (["--dwell", "60", "--swing", "30", "--crank", "1e-320"], "--crank"),
        (["--dwell", "60", "--swing", "30", "--crank", "0"], "--crank"),
        # no alias of --band: "--dwell-tolerance 5" meant as ±5° on the dwell is refused, not a 5° band
        (["--dwell", "60", "--swing", "30", "--dwell-tolerance", "5"], "--dwell-tolerance"),
    ],
)
def test_bad_requests_exit_2_with_one_line(capsys, atlas_path, args, message):
    code, out, err = run(capsys, "query", "--db", atlas_path, *args)
    assert code == 2
    assert out == ""
    assert len(err.strip().splitlines()) == 1 and message in err


def test_missing_or_foreign_database(capsys, tmp_path):
    code, _, err = run(capsys, "query", "--db", str(tmp_path / "none.sqlite"), "--dwell", "60", "--swing", "30")
    assert code == 2 and "no atlas" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "none.sqlite").exists()
    foreign = tmp_path / "foreign.sqlite"
    import sqlite3

    with sqlite3.connect(foreign) as con:
        con.execute("CREATE TABLE t (x)")
    before = foreign.read_bytes()
    code, _, err = run(capsys, "query", "--db", str(foreign), "--dwell", "60", "--swing", "30")
    assert code == 2 and "another application" in err
    assert foreign.read_bytes() == before


# --------------------------------------------------------------- the same on PostgreSQL
# ``demo_atlases`` (tests/postgres.py): the demo preset built on SQLite and on PostgreSQL.
PG_REQUESTS = [
    ["--dwell", "45", "--swing", "40", "--output", "rpr", "--top", "3"],
    ["--dwell", "60", "--swing", "30", "--output", "rrr", "--max-link-ratio", "20", "--top", "3"],
    ["--dwell", "50", "--dwell-tol", "5", "--dwells", "2", "--swing", "12", "--swing-tol", "2", "--top", "3"],
]


@pytest.mark.postgres
@pytest.mark.parametrize("request_args", PG_REQUESTS, ids=["rpr", "rrr", "double"])
def test_query_on_postgresql_answers_as_on_sqlite(capsys, demo_atlases, request_args):
    docs = {}
    for backend, target in demo_atlases.items():
        code, out, err = run(capsys, "query", "--db", target, *request_args, "--json")
        assert code == 0, err
        docs[backend] = json.loads(out)
    assert docs["postgresql"]["candidates"], "the demo atlas answers every README request"
    assert docs["postgresql"] == docs["sqlite"]  # same rows, same order, same simulation: same document


@pytest.mark.postgres
def test_complete_query_on_postgresql_answers_as_on_sqlite(capsys, demo_atlases):
    """The complete search's keyset walk of the dwell index gives the same rows on both backends."""
    docs = {}
    for backend, target in demo_atlases.items():
        code, out, err = run(
            capsys,
            "query",
            "--db",
            target,
            "--dwell",
            "50",
            "--dwell-tol",
            "5",
            "--dwells",
            "2",
            "--swing",
            "12",
            "--swing-tol",
            "2",
            "--complete",
            "--no-refine",
            "--top",
            "100",
            "--json",
        )
        assert code == 0, err
        docs[backend] = json.loads(out)
    assert len(docs["postgresql"]["candidates"]) >= 5  # two separated rests at a 12° swing: 8 on the test atlas
    assert docs["postgresql"] == docs["sqlite"]


@pytest.mark.postgres
def test_report_on_postgresql(capsys, demo_atlases, tmp_path):
    url = demo_atlases["postgresql"]
    code, out, err = run(capsys, "query", "--db", url, *PG_REQUESTS[0], "--json")
    assert code == 0, err
    first = json.loads(out)["candidates"][0]
    exported = {}
    for backend, target in demo_atlases.items():
        code, out, err = run(
            capsys,
            "report",
            "--db",
            target,
            "--candidates",
            first["id"],
            "--out",
            str(tmp_path / backend),
            "--dwell",
            "45",
        )
        assert code == 0, err
        assert f"1. {first['id']}: RPR" in out
        exported[backend] = json.loads((tmp_path / backend / "candidates.json").read_text())["candidates"]
        assert (tmp_path / backend / "index.html").stat().st_size > 0
    assert exported["postgresql"] == exported["sqlite"]
    assert exported["postgresql"][0]["swing_deg"] == pytest.approx(first["swing_deg"], abs=1e-9)
    code, out, err = run(
        capsys, "report", "--db", url, "--candidates", "999999999-rpr0.0@40", "--out", str(tmp_path / "x")
    )
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and not (tmp_path / "x").exists()
    assert "no segment 999999999 in this atlas" in err


def test_report_rebuilds_the_queried_six_bar(capsys, atlas_path, tmp_path):
    code, out, err = run(
        capsys,
        "query",
        "--db",
        atlas_path,
        "--dwell",
        "45",
        "--swing",
        "40",
        "--output",
        "rpr",
        "--top",
        "2",
        "--json",
        "--report",
        str(tmp_path / "q"),
    )
    assert code == 0, err
    queried = json.loads(out)["candidates"]
    assert json.loads((tmp_path / "q" / "candidates.json").read_text())["candidates"][0]["id"] == queried[0]["id"]
    code, out, err = run(
        capsys,
        "report",
        "--db",
        atlas_path,
        "--candidates",
        queried[0]["id"],
        "--out",
        str(tmp_path / "r"),
        "--dwell",
        "45",
    )
    assert code == 0, err
    rebuilt = json.loads((tmp_path / "r" / "candidates.json").read_text())["candidates"][0]
    assert rebuilt["output"]["pivot_mm"] == pytest.approx(queried[0]["output"]["pivot_mm"], abs=1e-9)
    assert rebuilt["dwells"][0]["dwell_deg"] == pytest.approx(queried[0]["dwells"][0]["dwell_deg"], abs=1e-9)
    assert rebuilt["swing_deg"] == pytest.approx(queried[0]["swing_deg"], abs=1e-9)
    code, out, err = run(
        capsys, "report", "--db", atlas_path, "--candidates", "12-rpr0@40", "--out", str(tmp_path / "x")
    )
    assert code == 2 and "not a candidate id" in err and not (tmp_path / "x").exists()


def test_bench_query_reports_latency_and_answers(atlas_path, capsys, tmp_path):
    from cli.bench.query import REQUESTS

    plot = tmp_path / "latency.png"
    code, out, err = run(
        capsys, "bench", "query", "--db", atlas_path, "--repeat", "1", "--top", "3", "--plot", str(plot)
    )
    assert code == 0, err
    doc = json.loads(out)
    assert doc["queries"] == len(REQUESTS)  # one run each: the figures' arithmetic is the same
    assert doc["atlas"]["preset"] == SPEC.name and doc["atlas"]["linkages"] > 0
    assert doc["ms_p50"] <= doc["ms_p95"] <= doc["ms_max"]
    assert doc["meets_floor"] == (doc["ms_p95"] <= doc["floor_ms_p95"])
    plain = doc["without_refine"]
    assert plain["ms_p50"] <= plain["ms_p95"] <= plain["ms_max"] and plain["floor_ms_p95"] == 100
    assert plain["meets_floor"] == (plain["ms_p95"] <= plain["floor_ms_p95"])
    answered = 0
    for row, req in zip(doc["requests"], REQUESTS, strict=True):
        assert row["label"] == req.label and row["candidates"] <= 3
        assert row["ms_median_without_refine"] > 0 and row["candidates_without_refine"] <= 3
        assert row["sixbars_improved"] <= row["sixbars_refined"]
        # the stages are the whole query: their medians add up to about the median time
        assert sum(row["ms_by_stage"].values()) == pytest.approx(row["ms_median"], rel=0.3, abs=5.0)
        if row["best"] is not None:
            answered += 1
            for dwell in row["best"]["dwell_deg"]:
                assert abs(dwell - req.dwell) <= req.dwell_tol + 1e-9
            if req.swing is not None:
                assert abs(row["best"]["swing_deg"] - req.swing) <= 0.5 + 1e-9
    assert answered >= len(REQUESTS) // 2
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(("option", "value"), [("--dwell-tol", "0"), ("--swing-tol", "-0"), ("--dwell-tol", "5e-324")])
def test_an_exact_dwell_or_swing_is_refused_before_the_atlas_is_read(capsys, tmp_path, option, value):
    """A tolerance of 0 is a request no simulated six-bar meets: one line naming the option, exit
    2, before the atlas is opened (the path does not exist and is not made)."""
    atlas = tmp_path / "none.sqlite"
    code, out, err = run(capsys, "query", "--db", str(atlas), "--dwell", "40", "--swing", "20", option, value)
    assert code == 2 and out == "" and not atlas.exists()
    (line,) = err.strip().splitlines()
    assert option in line and "> 0" in line


def test_help_shows_the_request_defaults_and_ranges(capsys):
    """The defaults in --help are the fields of Request (one definition), in degrees."""
    from synth.query.candidates import Request

    code, out, _ = run(capsys, "query", "--help")
    assert code == 0
    flat = " ".join(out.split())
    r = Request(dwell=1.0, swing=0.5)
    assert f"[default: {math.degrees(r.dwell_tol):g}" in flat.replace(".0]", "]").replace(".0;", ";")
    assert "0.001<=x<90.0" in flat and "0.01<=x<180.0" in flat  # --min-transmission, --swing
    assert f"default: {r.top}" in flat
    # the link ratio's definition and the exit statuses, as grep's
    assert "the coupler as the plate it is (A-B, A-P and B-P" in flat
    assert "Exit status: 0 if six-bars were found, 1 if none meets the request" in flat and "2 for bad input" in flat
    assert "--dwell-tolerance" not in flat


def test_no_match_names_the_failed_constraint_and_the_nearest_six_bar(capsys, atlas_path):
    """An RRR request none of whose fitted six-bars meets it, nor any of its nearest misses
    refined (150°/90°: the nearest rests ~100°, out of the reach's ±20 % box; 150°/30° and
    150°/60° are reached): the no-match names the constraint that
    rejected most, shows the nearest six-bar and a request its figures meet."""
    args = ["query", "--db", atlas_path, "--dwell", "150", "--swing", "90", "--output", "rrr"]
    code, out, err = run(capsys, *args, "--json")
    assert code == 1, err
    doc = json.loads(out)
    assert doc["candidates"] == []
    nm = doc["no_match"]
    assert nm["sixbars_fitted"] > 0 and nm["failed"] == "dwell"
    assert nm["rejected"]["dwell"] == max(nm["rejected"].values())
    near, meet = nm["nearest"], nm["would_meet"]
    assert meet["min_transmission_deg"] <= min(near["transmission_deg"].values())
    # the loosened request is met by the nearest six-bar's figures
    assert abs(near["dwells"][0]["dwell_deg"] - meet["dwell_deg"]) <= meet["dwell_tol_deg"]
    assert abs(near["swing_deg"] - meet["swing_deg"]) <= meet["swing_tol_deg"]
    assert near["link_ratio"] <= meet["max_link_ratio"]
    code, out, err = run(capsys, *args)
    assert code == 1 and out == ""
    lines = err.strip().splitlines()
    assert "dwell angle failed most" in lines[0] and lines[1].strip().startswith("nearest:")
    assert lines[2].strip().startswith("it meets: --dwell ")
    # the dwell alone is in the way: the rest nearest 150° of the six-bars meeting every other limit
    way = nm["in_the_way"]
    assert way["constraint"] == "dwell" and way["asked"] == pytest.approx(150) and 60 <= way["best"] < 148
    assert lines[3].strip() == (
        f"in the way: the dwell angle alone; the best of the fitted six-bars meeting every "
        f"other limit is {way['best']:.4g}° (asked 150°)"
    )


def test_an_unbuildable_double_dwell_is_refused_by_the_default_arm(capsys, atlas_path, tmp_path):
    """Issue 14: the 30° double-dwell candidate brings its slider within 0.02 cranks of its
    slot pivot; the default --min-arm refuses it and the no-match says what would admit it.
    Refined (sparse: the slot pivots moved off the lines' crossings), the six-bars that meet
    the request keep their sliders ≥ 0.2 cranks from the pivot, meet it by the independent
    solver, and `dwell report` rebuilds a moved one from its id."""
    args = [
        "query",
        "--db",
        atlas_path,
        "--dwell",
        "30",
        "--dwell-tol",
        "5",
        "--dwells",
        "2",
        "--swing",
        "6",
        "--swing-tol",
        "2",
    ]
    code, out, err = run(capsys, *args, "--no-refine")
    assert code == 1 and out == ""
    assert "torque arm (--min-arm)" in err and "it meets: --min-arm 0.0" in err
    code, out, err = run(capsys, *args, "--json")
    assert code == 0, err
    doc = json.loads(out)
    cands, summary = doc["candidates"], doc["refinement"]
    assert cands and summary["from_nearest_misses"] is False and summary["pivots_moved"] > 0
    for cand in cands:
        assert cand["buildability"]["arm_mm"] >= 0.2 and "~" in cand["id"]
        assert all(abs(d["dwell_deg"] - 30) <= 5 for d in cand["dwells"]) and len(cand["dwells"]) == 2
        independent = _independent(cand, 0.1)  # the longer rest
        longest = max(d["dwell_deg"] for d in cand["dwells"])
        assert longest - 2 * STEP <= independent["dwell_deg"] <= longest + 0.02
    code, out, err = run(capsys, *args)
    assert code == 0 and f"{summary['pivots_moved']} with the output pivot moved off the fitted one" in out
    code, out, err = run(
        capsys,
        "report",
        "--db",
        atlas_path,
        "--candidates",
        cands[0]["id"],
        "--out",
        str(tmp_path / "r"),
        "--dwell",
        "30",
    )
    assert code == 0, err
    rebuilt = json.loads((tmp_path / "r" / "candidates.json").read_text())["candidates"][0]
    assert rebuilt["id"] == cands[0]["id"] and rebuilt["output"] == cands[0]["output"]
    assert [d["dwell_deg"] for d in rebuilt["dwells"]] == pytest.approx(
        [d["dwell_deg"] for d in cands[0]["dwells"]], abs=1e-9
    )


def test_refinement_answers_a_missed_rrr_request_and_the_report_rebuilds_it(capsys, atlas_path, tmp_path):
    """105° ± 1° / 60° RRR: nothing in the test atlas's samples meets it (--no-refine, the
    wider and deeper samples a sparse refined answer takes, and their pivots moved); refined,
    the nearest misses do — each checked
    by the independent solver — and `dwell report` rebuilds a refined id with the same
    dimensions and figures."""
    args = ["query", "--db", atlas_path, "--dwell", "105", "--dwell-tol", "1", "--swing", "60", "--output", "rrr"]
    code, out, err = run(capsys, *args, "--no-refine", "--json")
    assert code == 1 and json.loads(out)["candidates"] == [] and "no six-bar meets the request" in err
    assert json.loads(out)["refinement"] is None
    code, out, err = run(capsys, *args, "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["request"]["refine"] is True and "no_match" not in doc
    summary = doc["refinement"]
    # more misses may come to meet it than --top shows
    assert summary["from_nearest_misses"] is True and summary["sixbars_improved"] >= len(doc["candidates"])
    assert summary["pivots_moved"] == 0
    assert summary["sixbars_refined"] >= summary["sixbars_improved"]
    cands = doc["candidates"]
    assert cands
    for cand in cands:
        assert "~" in cand["id"] and cand["output"]["type"] == "RRR"
        ref = cand["refinement"]
        assert set(ref) == {"before", "after"}
        assert set(ref["after"]) == {"dwell_deg", "swing_deg", "output_deviation_deg"}
        assert ref["after"]["dwell_deg"] == [d["dwell_deg"] for d in cand["dwells"]]
        assert ref["after"]["output_deviation_deg"] == cand["dwells"][0]["output_deviation_deg"]
        assert abs(ref["before"]["dwell_deg"][0] - 105) > 1  # it missed before
        assert abs(cand["dwells"][0]["dwell_deg"] - 105) <= 1 and abs(cand["swing_deg"] - 60) <= 0.5
        assert min(cand["transmission_deg"].values()) >= 30
        independent = _independent(cand, 0.1)
        assert independent["swing_deg"] == pytest.approx(cand["swing_deg"], abs=0.01)
        assert (
            cand["dwells"][0]["dwell_deg"] - 2 * STEP
            <= independent["dwell_deg"]
            <= cand["dwells"][0]["dwell_deg"] + 0.02
        )
    first = cands[0]
    code, out, err = run(
        capsys,
        "report",
        "--db",
        atlas_path,
        "--candidates",
        first["id"],
        "--out",
        str(tmp_path / "r"),
        "--dwell",
        "105",
    )
    assert code == 0, err
    rebuilt = json.loads((tmp_path / "r" / "candidates.json").read_text())["candidates"][0]
    assert rebuilt["id"] == first["id"]
    for key in ("fourbar", "coupler_point_mm", "output"):
        assert rebuilt[key] == first[key]
    assert rebuilt["dwells"][0]["dwell_deg"] == pytest.approx(first["dwells"][0]["dwell_deg"], abs=1e-9)
    assert rebuilt["dwells"][0]["output_deviation_deg"] == pytest.approx(
        first["dwells"][0]["output_deviation_deg"], abs=1e-9
    )
    assert rebuilt["swing_deg"] == pytest.approx(first["swing_deg"], abs=1e-9)
    assert rebuilt["refinement"]["before"]["swing_deg"] == pytest.approx(
        first["refinement"]["before"]["swing_deg"], abs=1e-9
    )
    assert "refined from (as retrieved)" in (tmp_path / "r" / "index.html").read_text()
    # a damaged refined id is the user's error
    bad = first["id"][:-3]
    code, out, err = run(capsys, "report", "--db", atlas_path, "--candidates", bad, "--out", str(tmp_path / "x"))
    assert code == 2 and len(err.strip().splitlines()) == 1 and not (tmp_path / "x").exists()


def test_a_sparse_answer_is_topped_up_from_the_nearest_misses(capsys, atlas_path):
    """RRR 105° ± 2° / 45°: nothing of the test atlas's first sample meets it (--no-refine).
    Refined, the answer keeps what it had and adds what the wider and deeper samples find,
    six-bars with the rocker pivot moved and — those still fewer than FILL — near misses
    refined to meet the request: each meets it by the independent solver."""
    from synth.query import FILL

    args = ["query", "--db", atlas_path, "--dwell", "105", "--swing", "45", "--output", "rrr", "--json"]
    code, out, err = run(capsys, *args, "--no-refine")
    plain = json.loads(out)["candidates"]
    assert code == (0 if plain else 1), err  # 1: none found, as grep
    assert len(plain) < FILL
    code, out, err = run(capsys, *args)
    assert code == 0, err
    doc = json.loads(out)
    cands, summary = doc["candidates"], doc["refinement"]
    assert summary["from_nearest_misses"] is False and len(cands) >= FILL
    assert {c["id"] for c in plain} <= {c["id"].split("~")[0] for c in cands}
    missed = [
        c for c in cands if c["refinement"] is not None and abs(c["refinement"]["before"]["dwell_deg"][0] - 105) > 2
    ]
    assert summary["near_misses_met"] > 0 and summary["pivots_moved"] > 0
    # a six-bar whose figures before missed the dwell is a near miss met or a moved pivot; one
    # of those may also have missed only another limit (its dwell already within ± 2°)
    assert (
        len(missed)
        <= summary["near_misses_met"] + summary["pivots_moved"]
        <= sum(c["refinement"] is not None for c in cands)
    )
    for cand in cands:
        assert abs(cand["dwells"][0]["dwell_deg"] - 105) <= 2 and abs(cand["swing_deg"] - 45) <= 0.5
        independent = _independent(cand, 0.1)
        assert independent["swing_deg"] == pytest.approx(cand["swing_deg"], abs=0.01)
        assert (
            cand["dwells"][0]["dwell_deg"] - 2 * STEP
            <= independent["dwell_deg"]
            <= cand["dwells"][0]["dwell_deg"] + 0.02
        )
    code, out, err = run(capsys, *args[:-1])
    head = out.partition("\nrank ")[0].replace("\n  ", " ")  # the head is wrapped to 120 columns
    assert code == 0 and f"{summary['near_misses_met']} of the six-bars near misses refined to meet" in head
    assert f"{summary['pivots_moved']} with the output pivot moved off the fitted one" in head


def test_no_refine_gives_the_retrieved_six_bars(capsys, atlas_path):
    """--no-refine: the six-bars as the atlas yields them (no ~ in an id, no refinement
    object); with refinement the same six-bars come back, kept or refined, none worse."""
    args = ["query", "--db", atlas_path, "--dwell", "45", "--swing", "40", "--output", "rpr", "--json"]
    code, out, err = run(capsys, *args, "--no-refine")
    assert code == 0, err
    plain = json.loads(out)["candidates"]
    assert plain and all("~" not in c["id"] and c["refinement"] is None for c in plain)
    code, out, err = run(capsys, *args)
    assert code == 0, err
    refined = json.loads(out)["candidates"]
    assert sorted(c["id"].split("~")[0] for c in refined) == sorted(c["id"] for c in plain)
    dev = {c["id"]: c["dwells"][0]["output_deviation_deg"] for c in plain}
    assert any(c["refinement"] is not None for c in refined)
    for c in refined:
        before = dev[c["id"].split("~")[0]]
        if c["refinement"] is None:
            assert c["dwells"][0]["output_deviation_deg"] == before
        else:
            assert c["refinement"]["before"]["output_deviation_deg"] == pytest.approx(before, abs=1e-12)
            # no worse on any objective of the ranking, better on one (synth.query.refine_objective.better_or_equal)
            assert c["dwells"][0]["output_deviation_deg"] <= before
    doc = json.loads(out)["refinement"]
    assert doc["from_nearest_misses"] is False and doc["sixbars_refined"] == len(plain) and doc["near_misses_met"] == 0
    assert doc["sixbars_improved"] == sum(c["refinement"] is not None for c in refined)
    code, out, err = run(
        capsys, "query", "--db", atlas_path, "--dwell", "45", "--swing", "40", "--output", "rpr", "--wide"
    )  # the refined column (before → after) is the wide table's; its head is one line
    assert code == 0 and f"{doc['sixbars_improved']} of {len(plain)} refined (" in out.splitlines()[0] and "→" in out


def test_the_first_answer_freezes_the_long_lived_objects_once(atlas_path, monkeypatch):
    """After a process's first answer its objects are out of the cyclic collector's reach
    (``gc.freeze``: a full collection then skips them), and only then: later answers freeze
    nothing more (their garbage stays collectable)."""
    import gc

    import cli.process
    import cli.query as cq
    from db.engine import open_atlas
    from synth.query.candidates import Request

    monkeypatch.setattr(cli.process, "_heap_settled", False)
    gc.unfreeze()
    engine = open_atlas(atlas_path, readonly=True)
    try:
        request = Request(dwell=math.radians(60), swing=math.radians(30), output="rpr", refine=False)
        assert gc.get_freeze_count() == 0
        cq.answer(engine, request)
        frozen = gc.get_freeze_count()
        assert frozen > 1000 and cli.process._heap_settled
        cq.answer(engine, request)
        assert gc.get_freeze_count() <= frozen  # none added (a frozen object freed leaves the count)
    finally:
        engine.dispose()


def test_tolerance_adds_a_column_and_ranks_by_it(atlas_path, capsys):
    """--tolerance (the user's unit, like --crank): every candidate's toleranced deviation in
    the JSON and the table, at least its nominal one, and the ranking by it."""
    args = [
        "query",
        "--db",
        atlas_path,
        "--dwell",
        "45",
        "--swing",
        "40",
        "--output",
        "rpr",
        "--top",
        "3",
        "--crank",
        "40",
        "--no-refine",
    ]
    code, out, err = run(capsys, *args, "--tolerance", "0.05", "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["request"]["tolerance_mm"] == 0.05
    tol = [c["toleranced_deviation_deg"] for c in doc["candidates"]]
    assert tol and all(t is not None for t in tol)
    for c, t in zip(doc["candidates"], tol):
        assert t >= max(d["output_deviation_deg"] for d in c["dwells"]) * 0.999
    code, out, err = run(capsys, *args, "--tolerance", "0.05")
    assert code == 0 and "tol dev °" in out and f"{tol[0]:.3f}" in out
    code, out, err = run(capsys, *args, "--json")
    assert all(c["toleranced_deviation_deg"] is None for c in json.loads(out)["candidates"])
    assert run(capsys, *args, "--tolerance", "-0.05")[0] == 2


def test_report_gives_the_toleranced_deviation_the_query_gave(atlas_path, capsys, tmp_path):
    """dwell report --tolerance: the same figure as the query's, in the report's JSON, CSV,
    page and summary line; a bad one: exit 2 and nothing written."""
    common = ["--db", atlas_path, "--crank", "40", "--dwell", "45"]
    query = ["query", *common, "--swing", "40", "--output", "rpr", "--top", "2", "--no-refine", "--json"]
    code, out, err = run(capsys, *query, "--tolerance", "0.05")
    assert code == 0, err
    queried = json.loads(out)["candidates"]
    ids = [c["id"] for c in queried]
    code, out, err = run(
        capsys, "report", *common, "--candidates", " ".join(ids), "--out", str(tmp_path / "r"), "--tolerance", "0.05"
    )
    assert code == 0, err
    got = json.loads((tmp_path / "r" / "candidates.json").read_text())["candidates"]
    for q, r in zip(queried, got, strict=True):
        assert r["toleranced_deviation_deg"] == pytest.approx(q["toleranced_deviation_deg"], abs=1e-9)
        assert r["toleranced_deviation_deg"] > max(d["output_deviation_deg"] for d in r["dwells"])
        assert f"toleranced deviation {r['toleranced_deviation_deg']:.4f}°" in out
    csv = (tmp_path / "r" / "candidates.csv").read_text().splitlines()
    column = csv[0].split(",").index("toleranced_deviation_deg")
    assert float(csv[1].split(",")[column]) == pytest.approx(got[0]["toleranced_deviation_deg"], rel=1e-9)
    assert "toleranced deviation" in (tmp_path / "r" / "index.html").read_text()
    code, out, err = run(
        capsys, "report", *common, "--candidates", ids[0], "--out", str(tmp_path / "b"), "--tolerance", "-1"
    )
    assert code == 2 and "--tolerance" in err and not (tmp_path / "b").exists()


@pytest.mark.parametrize(
    "value, message",
    [
        ("fine", "a number of degrees or 'auto'"),
        ("auto2", "a number of degrees or 'auto'"),
        ("nan", "finite"),
        ("1e-5", "0.0001 <= x < 180"),
        ("180", "0.0001 <= x < 180"),
        ("", "'auto'"),
    ],
)
def test_bad_band_values_are_refused(capsys, tmp_path, value, message):
    """--band takes degrees or auto; anything else is one line naming the option, exit 2,
    before the atlas is opened (the path does not exist)."""
    code, out, err = run(
        capsys, "query", "--db", str(tmp_path / "none.sqlite"), "--dwell", "60", "--swing", "30", "--band", value
    )
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and "--band" in err and message in err


def test_band_auto_json_carries_the_band_reached(capsys, atlas_path):
    """--band auto: the request in the document is at the band reached, which the band search
    names with its probes; each candidate's dwell is within the request there and longer at
    the 0.1° reference band. The table says the band on its own line under the legend."""
    args = (
        "query",
        "--db",
        atlas_path,
        "--dwell",
        "60",
        "--swing",
        "30",
        "--output",
        "rpr",
        "--top",
        "3",
        "--no-refine",
        "--band",
        "auto",
    )
    code, out, err = run(capsys, *args, "--json")
    assert code == 0, err
    doc = json.loads(out)
    search = doc["band_search"]
    assert (
        search["settled"]
        and search["band_deg"] == pytest.approx(doc["request"]["band_deg"])
        and search["band_deg"] < 0.02
    )
    assert search["reference_band_deg"] == pytest.approx(0.1)
    met = [p for p in search["probes"] if p["band_deg"] == search["band_deg"]]
    assert met and met[0]["met"] >= 3
    assert [c["id"] for c in search["candidates"]] == [c["id"] for c in doc["candidates"]]
    for c in search["candidates"]:
        assert abs(c["dwell_deg"][0] - 60.0) <= 2.0 + 1e-9 and c["reference_dwell_deg"][0] > c["dwell_deg"][0]
    code, out, err = run(capsys, *args)
    assert code == 0, err
    assert f"band auto: {search['band_deg']:.3g}°, the tightest" in out


def test_band_auto_lines_name_each_dwell_at_two_bands_only_when_they_differ():
    """Under the table, each candidate's dwell at the band reached and at the 0.1° reference;
    when no band held three six-bars the answer is at 0.1° itself, and the lines would only
    repeat the table's dwell twice over: the head line alone then."""
    from types import SimpleNamespace as NS

    from cli.query import band_search_text

    def searched(band_deg, settled):
        dwell = NS(angle=math.radians(46.13))
        candidate = NS(rank=1, figures=NS(dwells=(dwell, dwell)))
        request = NS(band=math.radians(band_deg), dwells=2, top=3)
        result = NS(request=request, candidates=[candidate])
        return NS(
            result=result,
            reference_dwells=[(math.radians(50.0), math.radians(49.0))],
            settled=settled,
            band=request.band,
            pooled=1377,
            stiller=0,
        )

    text = band_search_text(searched(0.1, False))
    assert text.splitlines() == [
        "band auto: no band down to 1e-4° holds 3 six-bars (1377 six-bars fitted, 0 moved to stiller rests); "
        "answered at 0.1°"
    ]
    lines = band_search_text(searched(0.002, True)).splitlines()
    assert lines[0].startswith("band auto: 0.002°, the tightest at which 3 six-bars meet the request")
    assert lines[1:] == ["    1 dwell 46.13°/46.13° at 0.002°, 50.00°/49.00° at 0.1°"]


def test_default_band_names_a_tighter_band(capsys, atlas_path):
    """Without --band, a request that a 0.01° band also answers (3 six-bars of the unrefined
    sample) gets one line on stderr naming it; with --band given, none."""
    args = (
        "query",
        "--db",
        atlas_path,
        "--dwell",
        "45",
        "--swing",
        "40",
        "--output",
        "rpr",
        "--top",
        "3",
        "--no-refine",
    )
    code, out, err = run(capsys, *args)
    assert code == 0 and err.count("\n") == 1 and "within a 0.01° band (--band 0.01" in err
    code, _, err = run(capsys, *args, "--json")
    assert code == 0 and json.loads(_)["tighter_band_deg"] == pytest.approx(0.01)
    code, out, err = run(capsys, *args, "--band", "0.1")
    assert code == 0 and err == ""


def test_a_short_answer_says_what_is_in_the_way_of_more(capsys, atlas_path):
    """RPR 180° at a 90° swing answers one six-bar where three are sought: one line on stderr
    names the constraint in the way of more with its figure; --json gives the same facts."""
    args = ["query", "--db", atlas_path, "--dwell", "180", "--swing", "90", "--output", "rpr"]
    code, out, err = run(capsys, *args, "--json")
    doc = json.loads(out)
    assert code == 0 and len(doc["candidates"]) == 1 and "no_match" not in doc
    (way,) = doc["short_of"]
    assert (way["output"], way["constraint"], way["asked"]) == ("rpr", "dwell", pytest.approx(180))
    assert 90 < way["best"] < 178
    code, out, err = run(capsys, *args)
    assert code == 0 and out.startswith("1 six-bar(s)")
    assert err.strip() == (
        "dwell: 1 six-bar(s) where 3 were sought; in the way of more, the dwell angle alone: the best of the "
        f"other fitted six-bars meeting every other limit is {way['best']:.4g}° (asked 180°)"
    )
    # an answer that is not short adds no line and no key
    code, out, err = run(capsys, *args, "--top", "1", "--json")
    assert code == 0 and "short_of" not in json.loads(out)
