"""Report folders are written whole or not at all (report/folder.py)."""

from __future__ import annotations

import errno
import hashlib
from pathlib import Path

import pytest
from harness.report_cases import REQUEST

import report.folder as folder
from report.export import write_report
from report.folder import MARKER, ReportFolderError


def digest(path: Path) -> dict[str, str]:
    """Every file of a folder (name → sha256): equal digests, equal folders."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(path.iterdir())}


def siblings(path: Path) -> list[str]:
    return sorted(p.name for p in path.parent.iterdir())


@pytest.fixture()
def old_report(tmp_path, candidates) -> Path:
    out = tmp_path / "rep"
    write_report(candidates[:1], REQUEST, out)
    return out


def _disk_full_on(name: str, monkeypatch) -> None:
    real = Path.write_text

    def write_text(self, *args, **kwargs):
        if self.name == name:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Path, "write_text", write_text)


@pytest.mark.parametrize("fail_at", ["candidates.json", "index.html", MARKER])
def test_disk_full_leaves_the_old_report_intact(old_report, candidates, monkeypatch, fail_at):
    before = digest(old_report)
    _disk_full_on(fail_at, monkeypatch)
    with pytest.raises(ReportFolderError, match="No space left on device"):
        write_report(candidates, REQUEST, old_report)
    assert digest(old_report) == before
    assert siblings(old_report) == ["rep"]  # no temporary folder left behind


def test_disk_full_on_a_new_folder_leaves_nothing(tmp_path, candidates, monkeypatch):
    _disk_full_on("index.html", monkeypatch)
    with pytest.raises(ReportFolderError):
        write_report(candidates, REQUEST, tmp_path / "new")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("exchange", [True, False], ids=["renameat2", "two renames"])
def test_a_report_replaces_the_previous_one_whole(old_report, candidates, monkeypatch, exchange):
    if not exchange:
        monkeypatch.setattr(folder, "_exchange", lambda a, b: False)
    first = set(digest(old_report))
    written = write_report(candidates, REQUEST, old_report)
    now = digest(old_report)
    assert set(now) == {p.name for p in written} | {MARKER}
    assert len(candidates) > 1 and set(now) > first  # the new report's files, not the old ones
    assert siblings(old_report) == ["rep"]


def test_a_folder_with_other_files_is_refused_untouched(old_report, candidates):
    (old_report / "my-notes.txt").write_text("mine")
    before = digest(old_report)
    with pytest.raises(ReportFolderError, match="my-notes.txt"):
        write_report(candidates, REQUEST, old_report)
    assert digest(old_report) == before and siblings(old_report) == ["rep"]


def test_an_older_report_without_the_file_list_is_replaced(old_report, candidates):
    (old_report / MARKER).unlink()
    write_report(candidates, REQUEST, old_report)
    assert (old_report / MARKER).exists()


def test_leftovers_of_a_killed_writer_are_removed(old_report, candidates):
    dead = 2**22 + 12345  # above the default pid_max: never a live process
    for kind in ("tmp", "old"):
        (old_report.parent / f".rep.{kind}-{dead}").mkdir()
    write_report(candidates, REQUEST, old_report)
    assert siblings(old_report) == ["rep"]


def test_non_finite_numbers_are_refused_before_writing(tmp_path, candidates):
    from report.export import json_document_text

    with pytest.raises(ValueError, match="/candidates/0/x"):
        json_document_text({"candidates": [{"x": float("inf"), "cycle": {}}]})
