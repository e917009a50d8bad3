"""Numerical warnings (overflow, 0/0) in the curvature kernels are bugs: they become errors here.
``source``: a small demo atlas (384 samples) read as the query's segment source, built once."""

from __future__ import annotations

from pathlib import Path

import pytest

HERE = Path(__file__).parent


def pytest_collection_modifyitems(items):
    for item in items:
        if HERE in Path(item.fspath).parents:
            item.add_marker(pytest.mark.filterwarnings("error::RuntimeWarning"))


#: The small atlas of ``source``: the demo sweep on 384 samples.
SMALL_SPEC_SAMPLES = 384


@pytest.fixture(scope="session")
def source(tmp_path_factory):
    from atlas.build import build_atlas
    from atlas.sweep import PRESETS
    from db.engine import open_atlas
    from db.queries import AtlasSource

    path = str(tmp_path_factory.mktemp("atlas") / "demo.sqlite")
    build_atlas(path, PRESETS["demo"].replace(samples=SMALL_SPEC_SAMPLES), workers=1)
    engine = open_atlas(path, readonly=True)
    yield AtlasSource(engine)
    engine.dispose()
