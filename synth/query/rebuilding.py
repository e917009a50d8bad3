"""Candidates rebuilt from their ids (:func:`rebuild`): re-fitted and re-simulated, or for a
refined id, the six-bar its dimensions give.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from synth.kinds import OutputTag
from synth.mechanism.sixbar import SixBar
from synth.query.candidate_ids import candidate_dimensions, parse_candidate_id
from synth.query.candidates import Candidate, Request
from synth.query.contract import SegmentSource
from synth.query.evaluate import candidate_of, figures_of, rest_position, scaled_figures
from synth.query.fitting import fit
from synth.query.result import RebuildError


def rebuild(ids: Sequence[str], source: SegmentSource, request: Request) -> list[Candidate]:
    """The candidates named by ``ids`` (from an earlier query), re-fitted and re-simulated.

    ``request`` gives the output band, the deviation window (its dwell), the crank length and
    the minimum transmission the RRR fit used; its other limits are ignored — the figures of a
    rebuilt six-bar are shown whatever they are. A refined id's six-bar is the one its
    dimensions give (its figures are the query's for the same band and dwell); its
    ``refined_from`` holds the figures of the six-bar it was refined from. Raises
    :class:`RebuildError` naming the id."""
    out = []
    for text in ids:
        try:
            seg_id, output, slot, level, swing = parse_candidate_id(text)
            dims = candidate_dimensions(text)
        except ValueError as exc:
            raise RebuildError(str(exc)) from None
        if dims is not None:
            out.append(dataclasses.replace(_rebuild_refined(text, dims, source, request), rank=len(out) + 1))
            continue
        # a double dwell's id from before --swing was required holds no swing ("@free"): its
        # fit does not use one
        req = dataclasses.replace(
            request,
            swing=request.swing if swing is None else swing,
            dwells=2 if output == OutputTag.DOUBLE_RPR else 1,
            output=(OutputTag.RRR if output == OutputTag.RRR else OutputTag.RPR).value,
        )
        row = source.segment(seg_id, level)
        if row is None:
            raise RebuildError(f"no segment {seg_id} in this atlas (candidate {text!r})")
        found = None
        if row.parts:
            fitted = [f for f in fit(req, [row], row.kind) if f.output == output and f.slot == slot]
            # whatever its figures — a fit a six-bar was moved or refined from may revolve, or
            # have one rest where two were asked —, but a six-bar that assembles and rests
            cands = (
                [
                    candidate_of(req, f, fig)
                    for f, fig in zip(fitted, figures_of(req, [f.sixbar() for f in fitted]))
                    if fig.assembled and fig.dwells
                ]
                if fitted
                else []
            )
            found = dataclasses.replace(cands[0], id=text.strip()) if cands else None
        if found is None:
            raise RebuildError(f"candidate {text!r} cannot be rebuilt from this atlas (no fit for that slot and level)")
        out.append(dataclasses.replace(found, rank=len(out) + 1))
    return out


def _rebuild_refined(text: str, dims: SixBar, source: SegmentSource, request: Request) -> Candidate:
    """The refined six-bar ``dims`` (crank-normalised) an id carries, simulated as the query
    simulated it; the six-bar it was refined from is rebuilt for ``refined_from`` (None if it
    cannot be)."""
    seg_id, output, _, level, _ = parse_candidate_id(text)
    if source.segment(seg_id, level) is None:
        raise RebuildError(f"no segment {seg_id} in this atlas (candidate {text!r})")
    req = dataclasses.replace(request, dwells=2 if output == OutputTag.DOUBLE_RPR else 1)
    fig = figures_of(req, [dims])[0]
    try:
        base = rebuild([text.strip().split("~")[0]], source, request)[0].figures
    except RebuildError:
        base = None
    rest = rest_position(dims, fig)
    s = request.crank
    return Candidate(
        id=text.strip(),
        segment_id=seg_id,
        sixbar=dims.scaled(s),
        figures=scaled_figures(fig, s),
        dwell_position=None if rest is None else rest * s,
        refined_from=base,
    )
