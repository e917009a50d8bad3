"""Progress on stderr (cli/progress.py): a line on a terminal once a job runs past a second,
status lines every few seconds in a log for the long jobs, and stdout untouched."""

from __future__ import annotations

import io
import json
import re
import sys
import time

import pytest

from cli.main import main
from cli.progress import DELAY, STATUS_INTERVAL, Progress, status_interval

#: A sweep of 32 Sobol points in shards of 4 (the fault tests' small build).
SMALL = ["--b", "1.5", "4.5", "--c", "1.5", "4.5", "--d", "1.5", "4.5", "--samples", "32", "--shard-size", "4"]
REQUEST = ["--dwell", "40", "--swing", "20", "--dwell-tol", "10", "--swing-tol", "5", "--json"]


def test_a_build_and_a_complete_query_in_a_log_print_status_lines(tmp_path, capsys, monkeypatch):
    """stderr not a terminal (captured): the build of a small sweep prints status lines
    (linkages so far) at the interval, the complete query too (rows searched), the sampled
    query none; stdout holds only the results (the build's summary line, the JSON)."""
    monkeypatch.setenv("DWELL_STATUS_INTERVAL", "0.1")
    db = str(tmp_path / "small.sqlite")
    assert main(["atlas", "build", "--db", db, *SMALL, "--workers", "1"]) == 0
    out, err = capsys.readouterr()
    status = [line for line in err.splitlines() if line.startswith("dwell: atlas: ")]
    assert len(status) >= 2, err
    assert all(re.search(r"; [0-9]+ s$", line) for line in status), status
    assert any(re.search(r"building the atlas, [0-9,]+/[0-9,]+ linkages", line) for line in status), status
    assert out.count("\n") == 1 and "dwell: " not in out  # the summary line alone

    monkeypatch.setenv("DWELL_STATUS_INTERVAL", "0.02")
    assert main(["query", "--db", db, *REQUEST, "--complete", "--workers", "1", "--no-refine"]) in (0, 1)
    out, err = capsys.readouterr()
    assert "candidates" in json.loads(out)  # the JSON, whole
    assert [line for line in err.splitlines() if line.startswith("dwell: query: ")], err
    # the sampled query is not a long job: no status lines in a log
    assert main(["query", "--db", db, *REQUEST, "--no-refine"]) in (0, 1)
    out, err = capsys.readouterr()
    assert "candidates" in json.loads(out) and "dwell: query: " not in err


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_terminal_gets_a_line_only_past_a_second(monkeypatch):
    """A part that ends within DELAY draws nothing; one that runs past it draws its name and
    count (tqdm), and the line is wiped when the part ends (the results print on a clean line)."""
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    with Progress("report") as shown:
        assert shown.terminal and not shown.log
        shown.stage("quick", 3, "candidates")
        shown.advance(3)
    assert term.getvalue() == ""
    with Progress("report") as shown:
        feed = shown.counter("writing the report", "candidates")
        feed(1, 3)
        time.sleep(DELAY + 0.6)
        feed(2, 3)
    drawn = term.getvalue()
    assert "writing the report" in drawn and "2/3" in drawn
    assert drawn.endswith("\r") and drawn.rstrip("\r").rsplit("\r", 1)[-1].strip() == ""  # wiped at the end


def test_status_lines_of_a_log(monkeypatch):
    """Not a terminal, ``log``: a line per interval naming the job, its part, its count."""
    log = io.StringIO()
    monkeypatch.setattr(sys, "stderr", log)
    monkeypatch.setenv("DWELL_STATUS_INTERVAL", "0.05")
    with Progress("demo", log=True) as shown:
        shown.stage("building the atlas", 1274, "linkages")
        shown.advance(637, "812 segments")
        time.sleep(0.3)
    lines = log.getvalue().splitlines()
    assert len(lines) >= 2
    assert lines[0].startswith("dwell: demo: building the atlas, 637/1,274 linkages (50 %), 812 segments; ")
    with Progress("query", log=False) as quiet:
        assert not quiet.active
        time.sleep(0.2)
    assert log.getvalue().splitlines() == lines  # nothing more


@pytest.mark.parametrize(
    "text, seconds",
    [
        ("0.5", 0.5),
        ("", STATUS_INTERVAL),
        ("soon", STATUS_INTERVAL),
        ("-1", STATUS_INTERVAL),
        ("nan", STATUS_INTERVAL),
        ("inf", STATUS_INTERVAL),
    ],
)
def test_the_status_interval(monkeypatch, text, seconds):
    monkeypatch.setenv("DWELL_STATUS_INTERVAL", text)
    assert status_interval() == seconds
