"""The reference for the fault tests: the sweep ``processes.SPEC`` built once, uninterrupted."""

from __future__ import annotations

import sqlite3
from dataclasses import dataclass
from pathlib import Path

import pytest
from harness.processes import SPEC

from atlas.build import build_atlas
from db import open_atlas
from db.digest import content_digest


@dataclass(frozen=True)
class Reference:
    path: Path  #: the complete atlas file (checkpointed: no -wal beside it); copy it, never change it
    digest: str  #: its content digest
    candidate: str  #: the id of a candidate of ``processes.QUERY``, for ``dwell report``


@pytest.fixture(scope="session")
def reference(tmp_path_factory) -> Reference:
    path = tmp_path_factory.mktemp("reference") / "atlas.sqlite"
    build_atlas(str(path), SPEC, workers=1)
    engine = open_atlas(str(path), readonly=True)
    try:
        digest = content_digest(engine)
        from cli.query import answer
        from synth.query.candidates import Request

        request = Request.from_degrees(dwell=40.0, dwell_tol=10.0, swing=20.0, swing_tol=5.0, top=3)
        candidates = answer(engine, request).candidates
    finally:
        engine.dispose()
    con = sqlite3.connect(path)  # fold the WAL into the file: copies are then whole atlases
    con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    con.close()
    for side in ("-wal", "-shm"):
        Path(f"{path}{side}").unlink(missing_ok=True)
    assert candidates, "the small sweep must answer QUERY"
    return Reference(path, digest, candidates[0].id)
