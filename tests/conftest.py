"""Shared test fixtures: the public reference cases in ``../shared/cases``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

CASES_FILE = Path(__file__).resolve().parents[1].parent / "shared" / "cases" / "classic_mechanisms.json"


@pytest.fixture(scope="session")
def reference_cases() -> dict[str, dict]:
    """Cases of ``shared/cases/classic_mechanisms.json`` by name (skips if absent)."""
    if not CASES_FILE.exists():
        pytest.skip(f"reference cases not found at {CASES_FILE}")
    data = json.loads(CASES_FILE.read_text())
    return {case["name"]: case for case in data["cases"]}
