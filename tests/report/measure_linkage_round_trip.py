"""Measurement behind docs/linkage-files.md ("The configuration a file stands for"; not a test:
run by hand on a built atlas).

    PYTHONPATH=tests .venv/bin/python tests/report/measure_linkage_round_trip.py ATLAS [TOP] [--cli]

Every cell of the coverage grid (:func:`cli.bench.coverage.cells`: RPR, RRR, double dwells),
answered as ``dwell bench coverage`` answers it (``--top TOP``, default 10, refined); every
candidate's linkage file text (:func:`report.linkage_toml.linkage_toml`) read back and analysed
as ``dwell analyze linkage FILE --limits`` does, batched (tests/linkage_checks.py); with
``--cli`` also each file through the command itself (in process, ~1 s a file). Printed as JSON:
per family and overall, the six-bars checked and the largest swing, dwell-end and transmission
differences (degrees), and any candidate beyond the file's promise.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
import tempfile
import time
from pathlib import Path

from linkage_checks import Agreement, round_trip  # tests/, on PYTHONPATH


def _cli_agreement(candidates, request, agreement: Agreement) -> None:
    from cli.main import main
    from report.candidate_json import candidate_json
    from report.linkage_toml import linkage_toml

    with tempfile.TemporaryDirectory() as tmp:
        for k, c in enumerate(candidates):
            path = Path(tmp) / f"{k:04d}.toml"
            path.write_text(linkage_toml(c, "mm", band=request.band, dwells=request.dwells), encoding="utf-8")
            out = io.StringIO()
            with contextlib.redirect_stdout(out):
                code = main(["analyze", "linkage", str(path), "--limits", "--json"])
            if code != 0:
                agreement.failures.append(f"{c.id}: dwell analyze linkage exited {code}")
                continue
            lim = json.loads(out.getvalue())["summary"]["limits"]
            agreement.add(
                c.id,
                candidate_json(c, request.rpm, "mm"),
                lim["swing_deg"],
                [tuple(d["interval_deg"]) for d in lim["dwells"]],
                {t["joint"]: t["min_deg"] for t in lim["transmission"]},
            )


def main(path: str, top: int = 10, cli: bool = False) -> dict:
    from cli.bench.coverage import cells
    from db.engine import open_atlas
    from db.queries import AtlasSource
    from synth.query import answer

    engine = open_atlas(path, readonly=True)
    source = AtlasSource(engine)
    batched: dict[str, Agreement] = {}
    command: dict[str, Agreement] = {}
    t0 = time.perf_counter()
    answering = checking = 0.0
    for cell in cells():
        request = cell.request(top)
        t = time.perf_counter()
        found = answer(request, source).candidates
        answering += time.perf_counter() - t
        t = time.perf_counter()
        round_trip(found, request, agreement=batched.setdefault(cell.family, Agreement()))
        if cli:
            _cli_agreement(found, request, command.setdefault(cell.family, Agreement()))
        checking += time.perf_counter() - t
        shown = {
            k: (v[cell.family].figures(), len(v[cell.family].failures))
            for k, v in (("batched", batched), ("command", command))
            if cell.family in v
        }
        print(
            f"{cell.family} {cell.dwell:g}/{cell.swing}: {len(found)} six-bars; so far {shown}",
            file=sys.stderr,
            flush=True,
        )
    engine.dispose()

    def summary(parts: dict[str, Agreement]) -> dict:
        total = Agreement()
        for a in parts.values():
            total.checked += a.checked
            total.swing, total.dwell_end = max(total.swing, a.swing), max(total.dwell_end, a.dwell_end)
            total.transmission = max(total.transmission, a.transmission)
            total.failures += a.failures
        return {
            "families": {f: a.figures() for f, a in parts.items()},
            "all": total.figures(),
            "failures": total.failures,
        }

    doc = {
        "atlas": path,
        "top": top,
        "answer_s": round(answering, 1),
        "check_s": round(checking, 1),
        "total_s": round(time.perf_counter() - t0, 1),
        "batched": summary(batched),
    }
    if cli:
        doc["command"] = summary(command)
    return doc


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--cli"]
    print(json.dumps(main(args[0], int(args[1]) if len(args) > 1 else 10, "--cli" in sys.argv), indent=1))
