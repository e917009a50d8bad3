"""Fixtures of the CLI tests that several files share."""

from __future__ import annotations

import pytest

from atlas.build import build_atlas
from atlas.sweep import PRESETS


@pytest.fixture(scope="module")
def coverage_atlas(tmp_path_factory) -> str:
    """A small atlas of the demo sweep (384 samples) for the coverage bench's tests: built once
    per module, so that the grid's file and the complete search's file run on two workers."""
    path = str(tmp_path_factory.mktemp("atlas") / "demo.sqlite")
    build_atlas(path, PRESETS["demo"].replace(samples=384), workers=1)
    return path
