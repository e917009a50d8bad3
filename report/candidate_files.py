"""One candidate's files in a report: its plots (PNG and SVG), drawing (SVG), DXF and linkage
file, written by :func:`candidate_files` from one :class:`CandidateJob`.

The job is a value and the function lives at module level, so that a caller may write several
candidates at once on worker processes (:func:`report.export.write_report`'s
``map_candidates``): matplotlib draws on one core, and a candidate's three figures, drawn
twice each (PNG, SVG), and its drawing take ~1.8 s — most of a report's time.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from report.cycle import Cycle
from report.sixbar_drawing import SixBarGeometry
from report.sixbar_plots import PlotFiles
from synth.query.candidates import Candidate

__all__ = ["CandidateFiles", "CandidateJob", "candidate_files"]


@dataclass(frozen=True, slots=True)
class CandidateJob:
    """What one candidate's files are made from.

    Attributes
    ----------
    index : int
        Its place in the report (the results of a pool come back in completion order).
    candidate, cycle, geometry :
        The candidate (user's units), its cycle and its drawing geometry.
    folder : Path
        Where its files go; ``stem`` begins each name (:func:`report.export.safe_stem`).
    stem : str
    min_transmission : float
        The request's smallest transmission angle (rad), drawn on the transmission plot.
    linkage_text : str
        Its linkage file (:func:`report.linkage_toml.linkage_toml`).
    """

    index: int
    candidate: Candidate
    cycle: Cycle
    geometry: SixBarGeometry
    folder: Path
    stem: str
    min_transmission: float
    linkage_text: str


@dataclass(frozen=True, slots=True)
class CandidateFiles:
    """The files :func:`candidate_files` wrote for the job ``index``: ``plots`` by name (with
    their SVG text, which the page inlines) and every path, plots first."""

    index: int
    plots: dict[str, PlotFiles]
    files: list[Path]


def candidate_files(job: CandidateJob) -> CandidateFiles:
    """Write ``job``'s plots, drawing, DXF and linkage file into ``job.folder``."""
    from report.dxf import write_dxf
    from report.sixbar_drawing import draw_sixbar
    from report.sixbar_plots import plot_candidate

    out, stem = job.folder, job.stem
    plots = plot_candidate(job.candidate, job.cycle, job.geometry, out / stem, min_transmission=job.min_transmission)
    drawing = draw_sixbar(job.geometry, out / f"{stem}-drawing.svg")
    dxf = write_dxf(job.geometry, out / f"{stem}-drawing.dxf")
    toml = out / f"{stem}.toml"
    toml.write_text(job.linkage_text, encoding="utf-8")
    files = [p for pf in plots.values() for p in (pf.png, pf.svg)] + [drawing, dxf, toml]
    return CandidateFiles(job.index, plots, files)
