"""``dwell query --complete --engine dask``: the complete search's batches on a cluster give the
local search's answer, exactly; Ctrl-C cancels what is pending; every way the cluster cannot
be used is one line, exit 2, with nothing read.

One two-process ``LocalCluster`` serves the whole module (a few seconds to start), on a small
demo atlas (384 Sobol samples) built once.
"""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys

import pytest

pytest.importorskip("distributed")

import dask
from distributed import Client
from harness.dask_cluster import drained, free_port, local_cluster

from atlas import dask_cluster
from atlas.build import build_atlas
from atlas.dask_cluster import DaskCluster
from atlas.dask_search import search_map
from atlas.sweep import PRESETS
from cli.main import main
from db.engine import open_atlas
from db.queries import AtlasSource
from synth import query as Q
from synth.query.candidates import Request

#: The requests compared: (what, options). The double's swing is one the small atlas's double
#: dwells reach (tests/synth/test_query_complete.py).
REQUESTS = {
    "rpr": ["--dwell", "60", "--swing", "30", "--output", "rpr"],
    "rrr": ["--dwell", "60", "--swing", "30", "--output", "rrr"],
    "double": [
        "--dwell",
        "40",
        "--dwell-tol",
        "10",
        "--swing",
        "145",
        "--swing-tol",
        "10",
        "--dwells",
        "2",
        "--output",
        "rpr",
    ],
}


@pytest.fixture(scope="module")
def atlas_path(tmp_path_factory) -> str:
    path = str(tmp_path_factory.mktemp("atlas") / "demo.sqlite")
    build_atlas(path, PRESETS["demo"].replace(samples=384), workers=1)
    return path


@pytest.fixture(scope="module")
def cluster():
    with local_cluster(2) as cluster:
        yield cluster


@pytest.fixture(scope="module")
def client(cluster):
    with Client(cluster, set_as_default=False) as client:
        yield client


def query(capsys, *args: str) -> tuple[int, str, str]:
    rc = main(["query", *args])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.mark.parametrize("name", sorted(REQUESTS))
def test_the_cluster_answers_as_the_local_search(name, atlas_path, cluster, client, capsys):
    args = ["--db", atlas_path, *REQUESTS[name], "--complete", "--top", "20", "--json"]
    rc, local, err = query(capsys, *args, "--workers", "1")
    assert rc == 0, err
    rc, remote, err = query(capsys, *args, "--engine", "dask", "--scheduler", cluster.scheduler_address)
    assert rc == 0, err
    note, *status = err.splitlines()
    assert note == f"dwell: dask: 2 worker(s), 2 thread(s) at {cluster.scheduler_address}"
    assert all(line.startswith("dwell: query: ") for line in status), err  # every 10 s, as the local search's
    assert remote == local  # the same six-bars, figures and order, to the last digit
    doc = json.loads(remote)
    assert len(doc["candidates"]) >= 10, "too few six-bars to compare"
    assert [c["rank"] for c in doc["candidates"]] == list(range(1, len(doc["candidates"]) + 1))
    assert drained(client)


def test_the_complete_answer_does_not_depend_on_the_order_batches_finish_in(atlas_path):
    """What lets a cluster return batches as they finish: the same answer when they come back
    in reverse (ranked by Pareto layer, score and a unique id)."""
    source = AtlasSource(open_atlas(atlas_path, readonly=True))
    request = Request(dwell=math.radians(60), swing=math.radians(30), output="rrr", top=20, complete=True, refine=False)
    try:
        forward = Q.answer(request, source)
        backward = Q.answer(request, source, map_batches=lambda fn, items: reversed([fn(i) for i in items]))
    finally:
        source.engine.dispose()
    assert len(forward.candidates) == 20
    assert [c.id for c in backward.candidates] == [c.id for c in forward.candidates]
    assert [c.figures for c in backward.candidates] == [c.figures for c in forward.candidates]


def test_ctrl_c_during_the_search_cancels_the_pending_batches(atlas_path, client):
    source = AtlasSource(open_atlas(atlas_path, readonly=True))
    request = Request(dwell=math.radians(60), swing=math.radians(30), output="rrr", complete=True)
    seen: list[int] = []

    def ctrl_c_after_the_first_batch(done: int, total: int) -> None:
        seen.append(done)
        if len(seen) == 1:
            signal.raise_signal(signal.SIGINT)  # noted by the map, raised where it next waits

    try:
        with pytest.raises(KeyboardInterrupt):
            Q.search(
                request,
                source,
                on_progress=ctrl_c_after_the_first_batch,
                map_batches=search_map(DaskCluster(client, in_flight=2)),
            )
    finally:
        source.engine.dispose()
    assert len(seen) == 1 and 0 < seen[0]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # put back
    assert drained(client), "the search's batches are still on the cluster"


def test_a_worker_with_another_version_is_refused(atlas_path, cluster, client, capsys, monkeypatch):
    monkeypatch.setattr(dask_cluster, "installed_version", lambda: "0.0-other")  # the driver's view only
    rc, out, err = query(
        capsys,
        "--db",
        atlas_path,
        *REQUESTS["rpr"],
        "--complete",
        "--engine",
        "dask",
        "--scheduler",
        cluster.scheduler_address,
    )
    assert rc == 2 and out == ""
    note, *status, last = err.splitlines()
    assert note.startswith("dwell: dask: 2 worker(s)"), err
    assert all(line.startswith("dwell: query: ") for line in status), err
    assert last.startswith("dwell: error: dask worker tcp://") and last.endswith(
        ", this query 0.0-other: install the same version on every node"
    ), last
    assert drained(client)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--engine", "dask", "--scheduler", "tcp://127.0.0.1:1"], "dwell query: --engine dask runs the complete "),
        (["--complete", "--engine", "dask"], "dwell query: --engine dask needs --scheduler ADDR"),
        (["--complete", "--scheduler", "tcp://127.0.0.1:1"], "dwell query: --scheduler needs --engine dask"),
        (["--complete", "--engine", "spark"], "Invalid value for '--engine': 'spark' is not one of 'local', 'dask'"),
        (
            ["--complete", "--engine", "dask", "--scheduler", "scheduler"],
            "not a dask scheduler address: 'scheduler' (missing port number in address 'scheduler')",
        ),
    ],
)
def test_bad_engine_options_are_one_line(atlas_path, capsys, args, message):
    rc, out, err = query(capsys, "--db", atlas_path, *REQUESTS["rpr"], *args)
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("dwell: error: ") and message in err, err


def test_an_unreachable_scheduler_is_one_line_before_the_atlas_is_read(tmp_path, capsys):
    port = free_port()
    missing = tmp_path / "none.sqlite"  # never opened: the scheduler is reached first
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        rc, out, err = query(
            capsys,
            "--db",
            str(missing),
            *REQUESTS["rpr"],
            "--complete",
            "--engine",
            "dask",
            "--scheduler",
            f"tcp://127.0.0.1:{port}",
        )
    assert rc == 2 and out == ""
    assert err.count("\n") == 1, err
    assert err.startswith(
        f"dwell: error: cannot connect to the dask scheduler at tcp://127.0.0.1:{port}: "
        f"Timed out trying to connect to tcp://127.0.0.1:{port} after 1 s"
    )
    assert list(tmp_path.iterdir()) == []


def test_without_the_dask_extra_the_engine_says_how_to_install_it(atlas_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # what an install without the extra sees
    rc, out, err = query(
        capsys, "--db", atlas_path, *REQUESTS["rpr"], "--complete", "--engine", "dask", "--scheduler", "h:1"
    )
    assert rc == 2 and out == ""
    assert err.startswith("dwell: error: the dask engine cannot import dask.distributed (")
    assert err.endswith("); install the dask extra: pip install 'dwell-atlas[dask]'\n")


def test_a_local_complete_search_never_imports_distributed(atlas_path):
    code = (
        "import sys; from cli.main import main; "
        f"rc = main(['query', '--db', {atlas_path!r}, '--dwell', '60', '--swing', '30', '--output', 'rpr', "
        "'--complete', '--no-refine', '--workers', '1', '--json']); "
        "print(rc, 'distributed' in sys.modules, file=sys.stderr)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.stderr.splitlines()[-1] == "0 False", done.stderr
