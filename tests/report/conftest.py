"""Fixtures of the report tests: reports written once per session into temporary folders."""

from __future__ import annotations

from pathlib import Path

import pytest
from harness.report_cases import (
    REQUEST,
    REQUEST2,
    double_dwell_candidates,
    single_dwell_candidates,
)

from synth.query.candidates import Candidate


@pytest.fixture(scope="session")
def candidates() -> list[Candidate]:
    return single_dwell_candidates()


@pytest.fixture(scope="session")
def report_dir(tmp_path_factory, candidates) -> tuple[Path, list[Path]]:
    """A report of the three single-dwell candidates: (folder, files written)."""
    from report.export import write_report

    out = tmp_path_factory.mktemp("report")
    return out, write_report(candidates, REQUEST, out)


@pytest.fixture(scope="session")
def double_report_dir(tmp_path_factory) -> tuple[Path, list[Path], list[Candidate]]:
    from report.export import write_report

    out = tmp_path_factory.mktemp("report2")
    cands = double_dwell_candidates()
    return out, write_report(cands, REQUEST2, out), cands
