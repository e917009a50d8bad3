"""Shared test fixtures: the public reference cases in ``docs/cases`` (part of the repo)."""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import pytest
from hypothesis import settings

# No per-example deadline: it is a wall-clock limit (the first example of a kernel also pays its
# compilation), and wall-clock checks run apart, under the ``timing`` marker.
settings.register_profile("dwell", deadline=None)
# CI runs the same examples every time (a red CI must be reproducible); local runs keep
# exploring new random examples, which is how edge cases are found.
settings.register_profile("ci", parent=settings.get_profile("dwell"), derandomize=True, print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "dwell")

# A job started in the background without job control (``cmd &`` in a script) begins with
# SIGINT ignored, and Python then leaves it ignored: the Ctrl-C tests need Python's own handler,
# in this process and (reset to the default on exec) in the CLI processes the tests start.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Leave out the wall-clock tests (marker ``timing``) unless ``-m`` names them: a limit in
    seconds fails on a loaded machine without a bug, so they run on their own, ``pytest -m timing``."""
    if "timing" in (config.getoption("markexpr") or ""):
        return
    timed = [item for item in items if item.get_closest_marker("timing")]
    if timed:
        config.hook.pytest_deselected(items=timed)
        items[:] = [item for item in items if not item.get_closest_marker("timing")]


@pytest.fixture(autouse=True)
def _shown_ids_file(tmp_path_factory, monkeypatch):
    """The ids the query's tables show are kept in a file of the user's cache folder
    (cli/shown_ids.py): the tests keep theirs in a folder of their own, never in $HOME."""
    monkeypatch.setenv("DWELL_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "dwell-cache"))


CASES_FILE = Path(__file__).resolve().parents[1] / "docs" / "cases" / "classic_mechanisms.json"


@pytest.fixture(scope="session")
def reference_cases() -> dict[str, dict]:
    """Cases of ``docs/cases/classic_mechanisms.json`` by name (a missing file fails the tests
    that use it: the cases ship with the repo, a silent skip would hide them)."""
    data = json.loads(CASES_FILE.read_text())
    return {case["name"]: case for case in data["cases"]}


# PostgreSQL fixtures (postgres_server, postgres_url, atlas_url, demo_atlases): see tests/postgres.py
pytest_plugins = ["postgres"]
