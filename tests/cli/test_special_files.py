"""A FIFO (or any file that is not a regular file) given where the tool reads or writes a
file is refused in one line, exit 2 — before anything opens it (opening a FIFO blocks until
another process opens its other end; the tool used to hang forever). Run in subprocesses with
a timeout, so a regression fails instead of hanging the suite."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from linkage_chains import chain_of_dyads

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "linkages"
DWELL = [sys.executable, "-c", "import sys; from cli.main import main; sys.exit(main())"]


def _dwell(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([*DWELL, *args], capture_output=True, text=True, timeout=60, cwd=cwd, check=False)


@pytest.mark.parametrize(
    "args, message",
    [
        (["analyze", "linkage", "{fifo}"], "FILE '{fifo}' is a FIFO (named pipe), not a file"),
        (
            ["query", "--db", "{fifo}", "--dwell", "60", "--swing", "30"],
            "is not a regular file (a FIFO, device or socket)",
        ),
        (["atlas", "info", "--db", "{fifo}"], "is not a regular file"),
        (
            [
                "analyze",
                "fourbar",
                "--a",
                "1",
                "--b",
                "3",
                "--c",
                "2.5",
                "--d",
                "3",
                "--phi",
                "10",
                "--plot",
                "{fifo}.png",
            ],
            "Invalid value for '--plot': '{fifo}.png' is a FIFO (named pipe), not a file",
        ),
        (
            ["analyze", "linkage", str(EXAMPLES / "fourbar.toml"), "--animate", "{fifo}.html"],
            "Invalid value for '--animate'",
        ),
    ],
)
def test_a_fifo_is_refused_in_one_line(tmp_path, args, message):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    os.mkfifo(f"{fifo}.png")
    os.mkfifo(f"{fifo}.html")
    before = sorted(p.name for p in tmp_path.iterdir())
    proc = _dwell(*(a.replace("{fifo}", str(fifo)) for a in args), cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and message.replace("{fifo}", str(fifo)) in proc.stderr, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_chain_of_dyads_is_answered_and_its_listing_refused(tmp_path):
    """18 dyads in a chain (2^18 configurations): the analysis follows configuration 1 at once;
    listing them all is one line naming the limit."""
    path = tmp_path / "chain.toml"
    path.write_text(chain_of_dyads(18))
    proc = _dwell("analyze", "linkage", str(path), "--input", "30", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert '"configurations_capped": true' in proc.stdout
    proc = _dwell("analyze", "linkage", str(path), "--input", "30", "--all-configurations", cwd=tmp_path)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "more than 1024 assembly configurations" in proc.stderr
