"""``dwell bench kinematics`` prints machine-readable JSON with speed and error side by side."""

from __future__ import annotations

import json
import math

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
        # the yardstick computes the same coupler angle, and the ratio is its time over ours
        assert r["plain_numpy_max_abs_theta_difference_rad"] < 1e-12
        best = max(r["streamed_positions_per_s"], r["single_call_positions_per_s"])
        assert (
            abs(r["ratio_to_plain_numpy"] - best / r["plain_numpy_positions_only_per_s"])
            < 1e-9 * r["ratio_to_plain_numpy"]
        )
    errors = doc["max_error_vs_extended_precision"]
    assert set(errors) >= {"theta", "dtheta1", "dtheta2", "dtheta3", "dgamma3", "loop_residual"}
    # float64 closed form against extended precision: a few ulps, scaled by the derivatives
    assert max(errors.values()) < 1e-11


def test_bench_kinematics_bad_sizes(capsys):
    assert main(["bench", "kinematics", "--n", "ten"]) == 2
    assert "--n" in capsys.readouterr().err


def test_bench_sixbar_json(capsys):
    """Six-bar positions against the plain numpy closed form: every random RRR six-bar
    assembles at every angle, both give the same ψ, and the ratio is their rates' quotient."""
    code = main(["bench", "sixbar", "--n", "1,30", "--angles", "36", "--repeat", "1"])
    out, err = capsys.readouterr()
    assert code == 0, err
    doc = json.loads(out)
    assert [r["n"] for r in doc["results"]] == [1, 30]
    for r in doc["results"]:
        assert r["positions"] == r["assembled_positions"] == r["n"] * 36
        assert r["max_abs_psi_difference_rad"] < 1e-12
        quotient = r["ours_positions_per_s"] / r["plain_numpy_positions_per_s"]
        assert abs(r["ratio_to_plain_numpy"] - quotient) < 1e-9 * quotient
        # the numpy path, timed beside the kernel, on the same terms
        quotient = r["numpy_path_positions_per_s"] / r["plain_numpy_positions_per_s"]
        assert abs(r["numpy_path_ratio_to_plain_numpy"] - quotient) < 1e-9 * quotient
        # and the kernel on the process's threads (one core against one core above)
        quotient = r["ours_threads_positions_per_s"] / r["plain_numpy_positions_per_s"]
        assert abs(r["ratio_to_plain_numpy_threads"] - quotient) < 1e-9 * quotient
    assert doc["cores_used"] == 1 and doc["threads"] >= 1


def test_bench_atlas_build_reports_bytes_per_linkage():
    """The timed build's bytes per linkage are the SQLite file's pages over its linkages."""
    from atlas.sweep import PRESETS
    from cli.bench.atlas import STORAGE_FLOOR, timed_build

    doc = timed_build(PRESETS["demo"], 24, 1)
    assert doc["linkages"] > 0 and doc["storage_bytes"] % 4096 == 0 and doc["storage_bytes"] > 0
    assert abs(doc["bytes_per_linkage"] - doc["storage_bytes"] / doc["linkages"]) <= 0.05
    assert doc["floor_bytes_per_linkage"] == STORAGE_FLOOR
    assert doc["meets_storage_floor"] == (doc["bytes_per_linkage"] <= STORAGE_FLOOR)


def test_bench_atlas_ingest_writes_every_shard_it_computed():
    """The ingest timing writes the computed shards (all their linkages) through the product's
    build, and its rate is those linkages over the timed seconds."""
    from atlas.sweep import PRESETS, sweep_linkages
    from cli.bench.atlas import INGEST_FLOOR, timed_ingest

    spec = PRESETS["demo"].replace(shard_size=8)
    doc = timed_ingest(spec, 24, 1)
    sweep = sweep_linkages(spec.replace(samples=24))
    assert doc["shards"] == sweep.n_shards(8) >= 2
    assert 0 < doc["linkages"] <= len(sweep) * len(spec.branches) and doc["dwell_rows"] > doc["linkages"]
    t, n = doc["seconds"], doc["linkages"]  # seconds rounded to 1 ms, the rate to 0.1
    assert n / (t + 5e-4) - 0.05 <= doc["linkages_per_s"] <= n / max(t - 5e-4, 1e-9) + 0.05
    assert doc["floor_linkages_per_s"] == INGEST_FLOOR and doc["meets_floor"] == (doc["linkages_per_s"] >= INGEST_FLOOR)


def test_plain_sixbar_matches_a_hand_built_one():
    """The yardstick's ψ at one angle against a six-bar assembled by hand (independent: points
    found by intersecting circles in the frame of their centres' line)."""
    import numpy as np

    from cli.bench.plain import sixbar_rrr_positions

    a, b, c, d, u, v = 1.0, 3.0, 2.5, 3.0, 1.0, 1.0
    D, L, rho, phi = complex(6.0, 1.0), 2.0, 4.0, 0.7

    def meet(p1, r1, p2, r2, left_of):
        """The intersection of two circles left of the directed line p1 → left_of."""
        # on the line through both: x along p1→p2; solve |x|=r1, |x−|p2−p1||=r2
        e = (p2 - p1) / abs(p2 - p1)
        x = (r1**2 - r2**2 + abs(p2 - p1) ** 2) / (2 * abs(p2 - p1))
        y = np.sqrt(r1**2 - x**2)
        points = [p1 + e * complex(x, s * y) for s in (1, -1)]
        return next(q for q in points if (np.conj(left_of - p1) * (q - p1)).imag > 0)

    A = a * np.exp(1j * phi)
    B = meet(A, b, complex(d), c, complex(d))
    P = A + (B - A) / b * complex(u, v)
    Q = meet(P, rho, D, L, D)
    psi = float(sixbar_rrr_positions(a, b, c, d, u, v, D, L, rho, np.array([phi]))[0])
    assert abs(np.angle(np.exp(1j * (psi - np.angle(Q - D))))) < 1e-12


def test_bench_tolerance_json(capsys):
    """The toleranced deviation's cost per candidate: both six-bars get a figure above their
    nominal deviation, timed, with the percentile's spread over seeds."""
    code = main(["bench", "tolerance", "--draws", "32", "--repeat", "1", "--seeds", "2"])
    out, err = capsys.readouterr()
    assert code == 0, err
    doc = json.loads(out)
    assert doc["draws"] == 32 and [r["sixbar"] for r in doc["results"]] == ["rrr_60_30", "rpr_45_40"]
    assert doc["target_cpu_ms_per_candidate_at_256"] == 5.0
    for r in doc["results"]:
        assert r["toleranced_deviation_deg"] > r["nominal_deviation_deg"] > 0
        assert r["dwell_windows_only"] is True  # 0.05 on a 40 crank is far from every limit
        assert abs(r["toleranced_deviation_deg"] - r["whole_turn_toleranced_deviation_deg"]) < 2e-3
        cpu = r["cpu_ms_per_candidate"]
        assert 0 < cpu["min"] <= cpu["median"] <= cpu["max"] < 60_000
        assert 0 < r["whole_turn_cpu_ms_per_candidate"]["min"] and r["percentile_spread_over_seeds_deg"] >= 0
    assert main(["bench", "tolerance", "--draws", "8"]) == 2


def test_bench_tolerance_holds_query_answers_to_the_whole_turn(capsys, tmp_path):
    """--answers: each candidate of a query's JSON, its figure against the whole-turn path's."""
    from cli.bench.tolerance import SIXBARS
    from synth.mechanism.figures import sixbar_figures

    _, sb, dwell = SIXBARS[1]  # the RPR 45°/40° six-bar, written as the query's JSON writes it
    f = sixbar_figures(sb, band=math.radians(0.1), dwell_length=math.radians(dwell))
    candidate = {
        "length_unit": "mm",
        "fourbar": {"a_mm": sb.a, "b_mm": sb.b, "c_mm": sb.c, "d_mm": sb.d, "branch": sb.branch},
        "coupler_point_mm": [sb.u, sb.v],
        "output": {"type": "RPR", "pivot_mm": [sb.dyad.pivot.real, sb.dyad.pivot.imag]},
        "dwells": [
            {"interval_deg": [math.degrees(d.start), 0.0], "dwell_deg": math.degrees(d.angle)} for d in f.dwells
        ],
    }
    path = tmp_path / "answer.json"
    path.write_text(json.dumps({"request": {"dwell_deg": dwell}, "candidates": [candidate]}))
    code = main(["bench", "tolerance", "--draws", "32", "--repeat", "1", "--seeds", "1", "--answers", str(path)])
    out, err = capsys.readouterr()
    assert code == 0, err
    answers = json.loads(out)["answers"]
    assert answers["candidates"] == 1 and answers["dwell_windows_only"] == 1
    assert 0 < answers["largest_difference_deg"] < 2e-3  # the figure is not the whole turn's code
    assert answers["whole_turn_cpu_ms_per_candidate"]["min"] > 0
    cpu, wall = answers["cpu_ms_per_candidate"], answers["wall_ms_per_candidate"]
    assert 0 < cpu["min"] == cpu["max"] < 60_000 and 0 < wall["min"] == wall["max"] < 60_000  # one candidate
    batch = answers["batch"]  # the file's candidates in one call: the same figure
    assert batch["same_figures"] is True and 0 < batch["cpu_ms_per_candidate"] < 60_000
    (per_file,) = answers["per_file"]  # one file: its figures are the whole's
    assert per_file["file"] == str(path) and abs(per_file["dwell_deg"][0] - dwell) < 1e-9
    assert per_file["largest_difference_deg"] == answers["largest_difference_deg"]
    path.write_text(json.dumps({"request": {"dwell_deg": dwell}, "candidates": [{"fourbar": {}}]}))
    assert main(["bench", "tolerance", "--answers", str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "--answers" in err
