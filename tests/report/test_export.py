"""Report export: the JSON rebuilds the same six-bars and reproduces their figures, the CSV has
exactly its documented columns, every file is there and readable (PNG, SVG, DXF), nothing
holds NaN/inf, bad input writes nothing."""

from __future__ import annotations

import csv
import json
import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from harness.report_cases import EVIL_ID, REQUEST

from report.candidate_json import request_json, sixbar_from_json
from report.cycle import CYCLE_COLUMNS
from report.export import (
    CSV_COLUMNS,
    candidate_row,
    csv_header,
    safe_stem,
    write_report,
)
from synth.mechanism.figures import sixbar_figures
from synth.mechanism.sixbar import simulate

DEG = math.pi / 180
PER_CANDIDATE = (
    "motion.png",
    "motion.svg",
    "coupler.png",
    "coupler.svg",
    "transmission.png",
    "transmission.svg",
    "drawing.svg",
    "drawing.dxf",
)
#: and NN-ID.toml, the linkage file (no suffix after the id)


def _strict_json(path: Path) -> dict:
    """Parse refusing NaN/Infinity (Python's json would accept them)."""

    def refuse(name):
        raise AssertionError(f"{path.name} holds {name}")

    return json.loads(path.read_text(encoding="utf-8"), parse_constant=refuse)


# ---------------------------------------------------------------------------------------------
# Files
# ---------------------------------------------------------------------------------------------


def test_every_documented_file_is_written_and_not_empty(report_dir, candidates):
    out, written = report_dir
    expected = {"candidates.json", "candidates.csv", "README.txt", "index.html"}
    for c in candidates:
        expected |= {f"{safe_stem(c)}-{suffix}" for suffix in PER_CANDIDATE} | {f"{safe_stem(c)}.toml"}
    assert {p.name for p in written} == expected
    assert {p.name for p in out.iterdir()} == expected | {".dwell-report"}  # + the list of files (report/folder.py)
    assert (out / ".dwell-report").read_text().split() == [p.name for p in written]
    assert written[-1].name == "index.html"
    for p in written:
        assert p.parent == out and p.stat().st_size > 0, p


def test_file_names_are_filesystem_safe_and_ranked(candidates):
    stems = [safe_stem(c) for c in candidates]
    assert stems[0] == "01-1234500007-rrr0_30"
    assert len(set(stems)) == len(stems)
    for s in stems:
        assert re.fullmatch(r"\d\d-[A-Za-z0-9._-]+", s), s
    evil = next(c for c in candidates if c.id == EVIL_ID)
    assert "<" not in safe_stem(evil) and "/" not in safe_stem(evil)


def test_pngs_open_and_are_not_blank(report_dir):
    import matplotlib.image as mpimg

    _, written = report_dir
    pngs = [p for p in written if p.suffix == ".png"]
    assert len(pngs) == 9
    for p in pngs:
        img = mpimg.imread(p)
        assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 300
        assert float(np.std(img[..., :3])) > 0.01  # something is drawn


def test_svgs_are_well_formed_xml(report_dir):
    _, written = report_dir
    for p in (p for p in written if p.suffix == ".svg"):
        root = ET.parse(p).getroot()
        assert root.tag.endswith("svg"), p


def test_dxf_reads_back_with_its_layers_and_entities(report_dir, candidates):
    ezdxf = pytest.importorskip("ezdxf")
    from report.dxf import LAYERS

    out, _ = report_dir
    for c in candidates:
        doc = ezdxf.readfile(out / f"{safe_stem(c)}-drawing.dxf")
        auditor = doc.audit()
        assert not auditor.has_errors
        assert set(LAYERS) <= {layer.dxf.name for layer in doc.layers}
        msp = doc.modelspace()
        by_layer = {name: len(msp.query(f'*[layer=="{name}"]')) for name in LAYERS}
        unused = {"ROD"} if c.sixbar.dyad.kind == "RPR" else set()  # an RPR has no rod
        assert all(n > 0 for name, n in by_layer.items() if name not in unused), by_layer
        texts = {t.dxf.text for t in msp.query("TEXT")}
        joints = {"A0", "B0", "D", "A", "B", "P"} | ({"Q"} if c.sixbar.dyad.kind == "RRR" else set())
        assert joints <= texts
        assert any(t.startswith("crank a = ") for t in texts)
        assert len(msp.query("CIRCLE")) >= len(joints)
        assert len(msp.query("LINE")) >= 3
        # the pivots sit where the six-bar has them (user units: crank 25)
        d = c.sixbar.d
        centres = [complex(e.dxf.center.x, e.dxf.center.y) for e in msp.query('CIRCLE[layer=="FIXED_PIVOTS"]')]
        for z in (0j, complex(d, 0), c.sixbar.dyad.pivot):
            assert min(abs(np.array(centres) - z)) < 1e-9
        if c.sixbar.dyad.kind == "RRR":
            (arc,) = msp.query("ARC")
            assert arc.dxf.radius == pytest.approx(c.sixbar.dyad.rod)


# ---------------------------------------------------------------------------------------------
# JSON
# ---------------------------------------------------------------------------------------------


def test_json_rebuilds_the_same_sixbars_and_reproduces_their_figures(report_dir, candidates):
    out, _ = report_dir
    doc = _strict_json(out / "candidates.json")
    req = doc["request"]
    assert req == request_json(REQUEST, "")  # write_report's default: an unnamed unit
    assert req["length_unit"] == "" and req["crank_unit"] == REQUEST.crank
    assert [c["id"] for c in doc["candidates"]] == [c.id for c in candidates]
    for item, cand in zip(doc["candidates"], candidates):
        sb = sixbar_from_json(item)
        assert sb == cand.sixbar  # floats round-trip exactly through JSON
        f = sixbar_figures(
            sb, band=math.radians(req["band_deg"]), dwell_length=math.radians(req["dwell_deg"]), dwells=req["dwells"]
        )
        assert len(item["dwells"]) == len(f.dwells) >= 1
        for dj, dw, dev in zip(item["dwells"], f.dwells, f.deviations):
            assert dj["dwell_deg"] == pytest.approx(math.degrees(dw.angle), abs=1e-6)
            assert all(0 <= x < 360 for x in dj["interval_deg"])
            assert dj["interval_deg"][0] == pytest.approx(math.degrees(dw.start) % 360, abs=1e-6)
            assert dj["interval_deg"][1] == pytest.approx(math.degrees(dw.end) % 360, abs=1e-6)
            assert dj["output_deviation_deg"] == pytest.approx(math.degrees(dev), abs=1e-6)
        assert item["swing_deg"] == pytest.approx(math.degrees(f.swing), abs=1e-6)
        assert item["transmission_deg"]["fourbar_min"] == pytest.approx(math.degrees(f.transmission_fourbar), abs=1e-6)
        if sb.dyad.kind == "RPR":  # a slot transmits at 90° by construction: no figure
            assert item["transmission_deg"]["output_min"] is None
        else:
            assert item["transmission_deg"]["output_min"] == pytest.approx(
                math.degrees(f.transmission_output), abs=1e-6
            )
        assert item["link_ratio"] == pytest.approx(f.link_ratio, rel=1e-9)
        assert item["footprint_unit2"] == pytest.approx(f.footprint, rel=1e-6)  # user units: crank² = 625


def test_json_cycle_is_the_exact_motion_at_one_degree_steps(report_dir, candidates):
    out, _ = report_dir
    doc = _strict_json(out / "candidates.json")
    for item, cand in zip(doc["candidates"], candidates):
        cyc = item["cycle"]
        assert cyc["step_deg"] == 1.0
        assert list(cyc)[1:] == [k for k, _, _ in CYCLE_COLUMNS]
        assert all(len(cyc[k]) == 360 for k, _, _ in CYCLE_COLUMNS)
        assert cyc["phi_deg"] == [float(k) for k in range(360)]
        m = simulate(sixbar_from_json(item), np.radians(cyc["phi_deg"]), order=2)
        np.testing.assert_allclose(cyc["psi_deg"], np.degrees(m.psi), rtol=0, atol=1e-9)
        np.testing.assert_allclose(cyc["dpsi"], m.dpsi[0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(cyc["ddpsi_per_rad"], m.dpsi[1], rtol=0, atol=1e-12)
        np.testing.assert_allclose(cyc["P_x"], m.z[0].real, rtol=0, atol=1e-9)
        np.testing.assert_allclose(cyc["B_y"], m.fourbar.B.imag, rtol=0, atol=1e-9)
        np.testing.assert_allclose(cyc["A_x"], 25.0 * np.cos(m.phi), rtol=0, atol=1e-9)
        np.testing.assert_allclose(cyc["transmission_fourbar_deg"], np.degrees(m.transmission_fourbar), atol=1e-9)
        if cand.sixbar.dyad.kind == "RRR":
            np.testing.assert_allclose(cyc["Q_x"], m.moving_pivot.real, rtol=0, atol=1e-9)
            # the rocker keeps its length: Q really is the moving pivot
            Q = np.array(cyc["Q_x"]) + 1j * np.array(cyc["Q_y"])
            np.testing.assert_allclose(np.abs(Q - cand.sixbar.dyad.pivot), cand.sixbar.dyad.rocker, rtol=1e-12)
        else:
            assert cyc["Q_x"] == [None] * 360 and cyc["Q_y"] == [None] * 360
            assert set(cyc["transmission_output_deg"]) == {90.0}
        # the dwelling flags mark the reported interval, and ψ holds still there
        (dwell,) = item["dwells"]
        start, end = dwell["interval_deg"]
        inside = (np.arange(360) - start) % 360 <= (end - start) % 360
        assert cyc["dwelling"] == inside.tolist()
        psi = np.array(cyc["psi_deg"])[inside]
        assert psi.max() - psi.min() <= REQUEST.band / DEG + 1e-9
        assert set(cyc["status"]) == {0}


def test_double_dwell_report_has_two_dwells_in_json_and_csv(double_report_dir):
    out, _, _ = double_report_dir
    doc = _strict_json(out / "candidates.json")
    (item,) = doc["candidates"]
    assert len(item["dwells"]) == 2 and item["output"]["type"] == "RPR"
    f = sixbar_figures(sixbar_from_json(item), band=0.2 * DEG, dwell_length=30 * DEG, dwells=2)
    for dj, dw in zip(item["dwells"], f.dwells):
        assert dj["dwell_deg"] == pytest.approx(math.degrees(dw.angle), abs=1e-6)
    with open(out / "candidates.csv", newline="") as fh:
        (row,) = list(csv.DictReader(fh))
    assert float(row["dwell2_deg"]) == pytest.approx(item["dwells"][1]["dwell_deg"], abs=1e-9)
    assert float(row["dwell2_deviation_deg"]) == pytest.approx(item["dwells"][1]["output_deviation_deg"], abs=1e-9)
    assert sum(item["cycle"]["dwelling"]) >= 2 * 30


def test_no_nan_or_inf_anywhere_in_the_data_files(report_dir, double_report_dir):
    for out in (report_dir[0], double_report_dir[0]):
        for name in ("candidates.json", "candidates.csv", "index.html"):
            text = (out / name).read_text(encoding="utf-8")
            assert not re.search(r"\b(NaN|nan|Infinity|inf)\b", text), name
        _strict_json(out / "candidates.json")


# ---------------------------------------------------------------------------------------------
# CSV
# ---------------------------------------------------------------------------------------------


def test_csv_has_exactly_the_documented_columns_and_one_row_per_candidate(report_dir, candidates):
    out, _ = report_dir
    with open(out / "candidates.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    assert header == csv_header() == [name for name, _, _ in CSV_COLUMNS]
    assert len(header) == len(set(header))
    assert len(body) == len(candidates)
    for row, cand in zip(body, candidates):
        assert len(row) == len(header)
        values = dict(zip(header, row))
        assert values["id"] == cand.id  # the csv module quotes it; the id survives as it is
        assert int(values["rank"]) == cand.rank
        assert values["output_type"] == cand.sixbar.dyad.kind
        expected = candidate_row(cand)
        for name in header:
            if expected[name] is None:
                assert values[name] == "", name
            elif isinstance(expected[name], float):
                assert float(values[name]) == expected[name], name  # repr round-trips exactly
        if cand.sixbar.dyad.kind == "RPR":
            assert values["rocker"] == values["rod"] == values["dwell2_deg"] == ""
        else:
            assert float(values["rod"]) == cand.sixbar.dyad.rod
        assert float(values["dwell1_deg"]) == pytest.approx(math.degrees(cand.figures.dwells[0].angle), abs=1e-12)


def test_readme_documents_exactly_the_csv_columns(report_dir):
    out, _ = report_dir
    text = (out / "README.txt").read_text(encoding="utf-8")
    section = text.split("candidates.csv columns\n")[1].split("\n\n")[0].splitlines()[1:]  # after the underline
    documented = [line.split()[0] for line in section if line.strip()]
    assert documented == csv_header()
    for name, unit, _ in CSV_COLUMNS:
        assert re.search(rf"^{re.escape(name)}\s+\[{re.escape(unit or '-')}\]", text, flags=re.M), name
    for key, _, _ in CYCLE_COLUMNS:
        assert re.search(rf"^{re.escape(key)}\s+\[", text, flags=re.M), key


# ---------------------------------------------------------------------------------------------
# Determinism and refusals
# ---------------------------------------------------------------------------------------------


def test_writing_twice_gives_identical_files(tmp_path, candidates):
    a, b = tmp_path / "a", tmp_path / "b"
    write_report(candidates[:1], REQUEST, a)
    write_report(candidates[:1], REQUEST, b)
    for p in a.iterdir():
        if p.suffix == ".dxf":
            continue  # DXF headers carry creation times
        assert p.read_bytes() == (b / p.name).read_bytes(), p.name


def test_bad_input_writes_nothing(tmp_path, candidates):
    import dataclasses

    target = tmp_path / "out"
    with pytest.raises(ValueError, match="no candidates"):
        write_report([], REQUEST, target)
    twins = [candidates[0], dataclasses.replace(candidates[1], rank=candidates[0].rank)]
    with pytest.raises(ValueError, match="distinct"):
        write_report(twins, REQUEST, target)
    with pytest.raises(ValueError, match="step_deg"):
        write_report(candidates[:1], REQUEST, target, step_deg=7.0)
    assert not target.exists()


def test_coarser_cycle_steps_are_accepted(tmp_path, candidates):
    write_report(candidates[:1], REQUEST, tmp_path, step_deg=2.0)
    doc = _strict_json(tmp_path / "candidates.json")
    assert len(doc["candidates"][0]["cycle"]["phi_deg"]) == 180
