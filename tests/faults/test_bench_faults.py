"""``dwell bench faults``: its JSON on a real (tiny) run, and exit status 1 when a trial fails."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import cli.bench.faults as faults
from processes import run


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc (Linux)")
def test_a_tiny_run_reports_every_trial(capsys):
    rc, out, err = run(capsys, "bench", "faults", "--trials", "2", "--kills", "2", "--seed", "3", "--samples", "16",
                       "--shard-size", "2", "--workers", "1")
    assert rc == 0, err
    doc = json.loads(out)
    assert (doc["benchmark"], doc["trials"], doc["survived"], doc["seed"]) == ("faults", 2, 2, 3)
    assert doc["concurrent_builder_refused"] is True
    (sqlite,) = doc["runs"]
    assert sqlite["db_kind"] == "sqlite" and sqlite["reference"]["n_shards"] >= 3
    reference = sqlite["reference"]["content_digest"]
    for trial in sqlite["per_trial"]:
        assert trial["survived"] and trial["problems"] == [] and trial["content_digest"] == reference
        assert 1 <= len(trial["kills"]) <= 2 and trial["kills_landed"] == sum(k["landed"] for k in trial["kills"])
        for kill in trial["kills"]:
            assert 0 <= kill["at_s"] <= sqlite["reference"]["seconds"]
            assert kill["shards_done"] is None or 0 <= kill["shards_done"] <= sqlite["reference"]["n_shards"]
    second = sqlite["concurrent_builder"]
    assert second["second_exit"] == 2 and "is being built by another process" in second["second_message"]
    assert second["first_exit"] == 0 and second["first_content_digest"] == reference
    summary = err.strip().splitlines()[-1]
    assert summary.startswith("faults: sqlite 2/2 trials survived (") and "second builder refused" in summary


def test_a_failed_trial_makes_exit_status_1(capsys, monkeypatch):
    def one_failure(kind, sweep, trials, max_kills, seed, postgres_url):
        return {"db_kind": kind, "trials": 2, "survived": 1, "kills_landed": 3,
                "concurrent_builder": {"passed": True}, "per_trial": []}

    monkeypatch.setattr(faults, "_run_kind", one_failure)
    rc, out, err = run(capsys, "bench", "faults", "--trials", "2")
    assert rc == 1
    assert json.loads(out)["survived"] == 1
    assert "faults: sqlite 1/2 trials survived (3 kills landed)" in err


@pytest.mark.parametrize("args, message", [
    (["--db-kind", "postgresql"], "--db-kind postgresql needs --postgres URL"),
    (["--db-kind", "both", "--postgres", "mysql://x/y"], "--postgres must be a postgresql:// URL"),
    (["--db-kind", "postgresql", "--postgres", "postgresql+psycopg://u@127.0.0.1:1/x"], "cannot connect to the server"),
])
def test_bad_postgres_options_are_refused(capsys, monkeypatch, args, message):
    monkeypatch.delenv("DWELL_TEST_POSTGRES", raising=False)
    rc, out, err = run(capsys, "bench", "faults", *args)
    assert rc == 2 and out == "" and err.count("\n") == 1 and message in err, err
