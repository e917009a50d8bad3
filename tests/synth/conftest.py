"""Numerical warnings (overflow, 0/0) in the curvature kernels are bugs: they become errors here."""

from __future__ import annotations

from pathlib import Path

import pytest

HERE = Path(__file__).parent


def pytest_collection_modifyitems(items):
    for item in items:
        if HERE in Path(item.fspath).parents:
            item.add_marker(pytest.mark.filterwarnings("error::RuntimeWarning"))
