"""The round trip of a candidate's linkage file: ``dwell analyze linkage FILE --limits`` with no
other option — the Assur-group solver, not the six-bar simulation — must give the candidate's
swing (to 1e-4°), the ends of every dwell interval (to 0.01°) and its smallest transmission
angles (to 1e-3°).

Two ways in: :func:`check_linkage_files` runs the command on every ``NN-ID.toml`` of a report
folder; :func:`round_trip` does for many candidates at once what the command does for one — the
same file text, parser, configuration choice, transmission minima and dwell search, with the
dwell search batched over the candidates — and the swing from the extremes refined on the same
exact solution (the command's limit-position search costs ~1 s a file; it is checked on the
report folders).
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

#: The agreement the file promises (docs/linkage-files.md), degrees.
SWING_TOL = 1e-4
DWELL_END_TOL = 0.01
TRANSMISSION_TOL = 1e-3


def _circular(a: float, b: float) -> float:
    """|a − b| of two crank angles (deg) around the circle."""
    d = (a - b) % 360.0
    return min(d, 360.0 - d)


@dataclass
class Agreement:
    """Largest differences (deg) between candidates and their files' analyses, and the
    candidates that broke a tolerance (id: what)."""

    checked: int = 0
    swing: float = 0.0
    dwell_end: float = 0.0
    transmission: float = 0.0
    failures: list[str] = field(default_factory=list)
    #: how many files named each configuration number (round_trip only)
    configurations: Counter = field(default_factory=Counter)

    def add(
        self,
        ident: str,
        cand: dict,
        swing: float,
        dwells: Sequence[tuple[float, float]],
        transmission: dict[str, float],
    ) -> None:
        """Compare one candidate (its ``candidates.json`` object) with its file's ``swing`` (deg),
        ``dwells`` ((start, end) deg) and smallest transmission angle by joint (deg)."""
        self.checked += 1
        e = abs(swing - cand["swing_deg"])
        self.swing = max(self.swing, e)
        if e > SWING_TOL:
            self.failures.append(f"{ident}: swing {swing!r} vs {cand['swing_deg']!r}")
        want = [tuple(d["interval_deg"]) for d in cand["dwells"]]
        if len(want) != len(dwells):
            self.failures.append(f"{ident}: {len(dwells)} dwell(s) vs {len(want)}")
        for (s0, e0), (s1, e1) in zip(want, dwells):
            e = max(_circular(s0, s1), _circular(e0, e1))
            self.dwell_end = max(self.dwell_end, e)
            if e > DWELL_END_TOL:
                self.failures.append(f"{ident}: dwell {s1!r}..{e1!r} vs {s0!r}..{e0!r}")
        mu = cand["transmission_deg"]
        pairs = [("B", mu["fourbar_min"])] + ([("Q", mu["output_min"])] if cand["output"]["type"] == "RRR" else [])
        if set(transmission) != {j for j, _ in pairs}:
            self.failures.append(f"{ident}: transmission angles at {sorted(transmission)}")
        for joint, value in pairs:
            e = abs(transmission.get(joint, math.inf) - value)
            self.transmission = max(self.transmission, e)
            if e > TRANSMISSION_TOL:
                self.failures.append(f"{ident}: transmission at {joint} {transmission.get(joint)!r} vs {value!r}")

    def figures(self) -> dict:
        return {
            "six_bars": self.checked,
            "max_swing_error_deg": self.swing,
            "max_dwell_end_error_deg": self.dwell_end,
            "max_transmission_error_deg": self.transmission,
        }


def check_linkage_files(folder: Path, run, as_json: Path | None = None) -> int:
    """Run ``dwell analyze linkage FILE --limits --json`` (``run(argv) -> stdout``) on every
    candidate's linkage file of ``folder``'s report and assert the agreement; with ``as_json``
    (a folder), on the same description written as JSON there. Returns how many candidates
    were checked."""
    import tomllib

    doc = json.loads((folder / "candidates.json").read_text(encoding="utf-8"))
    agreement = Agreement()
    for cand in doc["candidates"]:
        (path,) = folder.glob(f"{cand['rank']:02d}-*.toml")
        if as_json is not None:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
            path = as_json / f"{path.stem}.json"
            path.write_text(json.dumps(data), encoding="utf-8")
        out = json.loads(run(["analyze", "linkage", str(path), "--limits", "--json"]))
        assert out["mechanism"]["configuration_from"] == "file"
        lim = out["summary"]["limits"]
        assert abs(lim["band_deg"] - doc["request"]["band_deg"]) < 1e-9
        agreement.add(
            cand["id"],
            cand,
            lim["swing_deg"],
            [tuple(d["interval_deg"]) for d in lim["dwells"]],
            {t["joint"]: t["min_deg"] for t in lim["transmission"]},
        )
    assert not agreement.failures, agreement.failures[:5]
    assert agreement.checked == len(doc["candidates"])
    return agreement.checked


def round_trip(candidates: Sequence, request, units: str = "mm", agreement: Agreement | None = None) -> Agreement:
    """Write each candidate's linkage file text, read it back and analyse it as
    ``dwell analyze linkage FILE --limits`` does (batched); add the comparison to
    ``agreement`` (a new one if None) and return it."""
    from cli.analyze.linkage import configuration_start
    from cli.analyze.linkage_limits import rests
    from kinematics.assur import configurations, decompose, linkage_from_text, output_at, transmission_minima
    from report.candidate_json import candidate_json
    from report.linkage_toml import linkage_toml
    from synth.mechanism.output_range import output_swing
    from synth.mechanism.sixbar import crank_grid

    agreement = Agreement() if agreement is None else agreement
    if not candidates:
        return agreement
    items = []
    for c in candidates:
        mech = linkage_from_text(
            linkage_toml(c, units, band=request.band, dwells=request.dwells, leave=request.swing_tol)
        )
        dec = decompose(mech)
        first = np.zeros((1, 1))
        number, source, start = configuration_start(
            mech, dec, first, configurations(mech, first[0], decomposition=dec), None, "file"
        )
        assert source == "file" and mech.output.band == request.band
        # two rests are told apart as the query told them: the file carries the swing tolerance
        assert mech.output.leave == (pytest.approx(request.swing_tol, abs=1e-15) if request.dwells == 2 else None)
        agreement.configurations[number] += 1
        items.append((mech, dec, start, mech.output))
    found = rests(items, request.band, request.dwells, items[0][3].leave)
    phi = crank_grid(720)
    for c, (mech, dec, start, output), dwells in zip(candidates, items, found):
        exact = output_at(mech, start, output, decomposition=dec)
        # extremes located by the parabola through the samples, evaluated on the exact positions
        swing, turns = output_swing(phi, np.unwrap(exact(phi)), psi_at=exact)
        assert int(turns) == 0, c.id
        mu = {
            t.joint: math.degrees(t.angle)
            for t in transmission_minima(mech, start, 0.0, 2 * math.pi, decomposition=dec)
        }
        agreement.add(
            c.id,
            candidate_json(c, request.rpm, units),
            math.degrees(float(swing)),
            [(d.start, d.end) for d in dwells],
            mu,
        )
    return agreement
