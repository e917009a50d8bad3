"""The independent check of a report's linkage files: ``dwell analyze linkage`` (the Assur-group
solver, not the six-bar simulation) run on every ``NN-ID.toml`` of a report folder must give
the candidate's swing, dwell interval(s) and minimum transmission angles."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np

from report.candidate_json import length_key

#: Crank step of the check (deg): the dwell ends are checked to within two steps.
STEP = 0.1


def _fold(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle between two vectors (complex), folded to [0°, 90°]."""
    ang = np.degrees(np.abs(np.angle(u * np.conj(v))))
    return np.minimum(ang, 180.0 - ang)


def _range(psi: np.ndarray, phi: np.ndarray, lo: float, hi: float) -> float:
    """max − min of ψ (deg) over crank angles in [lo, hi] (deg, counter-clockwise from lo: hi < lo
    when the interval passes 0°)."""
    inside = np.mod(phi - lo, 360.0) <= np.mod(hi - lo, 360.0) + 1e-9
    return float(np.ptp(psi[inside]))


def check_linkage_files(folder: Path, run) -> int:
    """Check every candidate of ``folder``'s report; ``run(argv) -> stdout`` runs ``dwell``.
    Returns how many candidates were checked."""
    doc = json.loads((folder / "candidates.json").read_text(encoding="utf-8"))
    band = doc["request"]["band_deg"]
    checked = 0
    for cand in doc["candidates"]:
        (path,) = folder.glob(f"{cand['rank']:02d}-*.toml")
        config = re.search(r"--configuration (\d+)", path.read_text(encoding="utf-8")).group(1)
        out = json.loads(run(["analyze", "linkage", str(path), "--configuration", config, "--from", "0", "--to", "360",
                              "--step", str(STEP), "--json"]))
        rows = out["positions"]
        phi = np.array([r["input_deg"] for r in rows])
        psi = np.degrees(np.unwrap(np.radians([r["theta_output_deg"] for r in rows])))
        unit = out["mechanism"]["length_unit"]
        pt = lambda name: np.array([complex(r[f"{name}x_{unit}"], r[f"{name}y_{unit}"]) for r in rows])  # noqa: E731
        assert abs(np.ptp(psi) - cand["swing_deg"]) < 0.01, (cand["id"], np.ptp(psi), cand["swing_deg"])
        for dwell in cand["dwells"]:
            lo, hi = dwell["interval_deg"]
            assert _range(psi, phi, lo + 1e-6, hi - 1e-6) <= band + 1e-6, (cand["id"], dwell)
            # the ends are where the band breaks: two steps further it is exceeded on each side
            assert _range(psi, phi, lo - 2 * STEP, hi) > band and _range(psi, phi, lo, hi + 2 * STEP) > band, cand["id"]
        A, B = pt("A"), pt("B")
        key = length_key(cand["length_unit"])
        mu4 = _fold(A - B, complex(cand["fourbar"][f"d_{key}"], 0.0) - B).min()
        assert cand["transmission_deg"]["fourbar_min"] - 1e-6 <= mu4 <= cand["transmission_deg"]["fourbar_min"] + 0.1
        if cand["output"]["type"] == "RRR":
            D = complex(*cand["output"][f"pivot_{key}"])
            P, Q = pt("P"), pt("Q")
            mu = _fold(P - Q, D - Q).min()
            assert cand["transmission_deg"]["output_min"] - 1e-6 <= mu <= cand["transmission_deg"]["output_min"] + 0.1
        checked += 1
    assert math.isfinite(band) and checked == len(doc["candidates"])
    return checked
