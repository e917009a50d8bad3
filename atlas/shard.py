"""One shard of an atlas build: a pure function of (sweep spec, shard index) → database rows.

Any engine (local processes, a cluster) can run it; the driver alone writes. Row ids are
deterministic, so the content of an atlas does not depend on the worker count, the order in
which shards finish, or how often the build was interrupted and resumed:

* linkage id = 2·sweep_index + (0 for branch +1, 1 for branch −1) + 1
* segment id = linkage id · ``SEGMENTS_PER_LINKAGE`` + ordinal of the segment in its linkage
* dwell id   = segment id · ``DWELLS_PER_SEGMENT`` + 2·level + part
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from atlas.sweep import SweepLinkages, SweepSpec, sweep_linkages
from kinematics.fourbar import fourbar_motion
from kinematics.loop import transmission_fold
from synth.segments import SegmentSearch, find_segments

__all__ = ["DWELLS_PER_SEGMENT", "SEGMENTS_PER_LINKAGE", "ShardResult", "compute_shard", "linkage_id"]

#: Room for segment ordinals inside one linkage's id range (ids stay below 2^63 for 10^8 linkages).
SEGMENTS_PER_LINKAGE = 100_000
#: Room for (level, part) inside one segment's id range: up to 32 tolerance levels.
DWELLS_PER_SEGMENT = 64
#: Crank samples over the turn for a linkage's transmission-angle range.
_TRANSMISSION_SAMPLES = 360


def linkage_id(sweep_index: int, branch: int) -> int:
    """The deterministic primary key of a (proportion, branch) pair."""
    return 2 * int(sweep_index) + (0 if branch == 1 else 1) + 1


@dataclass(frozen=True, slots=True)
class ShardResult:
    """Rows of one shard, ready for bulk insertion: dicts keyed by column name, plain Python
    values (no numpy scalars, no NaN/inf), ids included. ``skipped`` counts degenerate cases
    by reason; ``seconds`` is the compute time (not part of the content)."""

    shard_index: int
    linkages: list[dict[str, Any]]
    segments: list[dict[str, Any]]
    dwells: list[dict[str, Any]]
    skipped: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0


def compute_shard(spec: SweepSpec, shard_index: int, linkages: SweepLinkages | None = None) -> ShardResult:
    """Compute every row of shard ``shard_index`` of ``spec``'s sweep.

    ``linkages`` may pass the already drawn sweep (the driver draws it once); it must be
    ``sweep_linkages(spec)``.
    """
    t0 = time.perf_counter()
    sweep = linkages if linkages is not None else sweep_linkages(spec)
    part = sweep.shard(shard_index, spec.shard_size)
    n = len(part)
    branches = np.asarray(spec.branches, dtype=np.int64)
    # every proportion on every branch, proportion-major (canonical order)
    b = np.repeat(part.b, branches.size)
    c = np.repeat(part.c, branches.size)
    d = np.repeat(part.d, branches.size)
    br = np.tile(branches, n)
    sweep_index = np.repeat(part.sweep_index, branches.size)
    grashof = np.repeat(part.grashof, branches.size)

    phi = np.linspace(0.0, 2 * np.pi, _TRANSMISSION_SAMPLES, endpoint=False)
    motion = fourbar_motion(1.0, b[:, None], c[:, None], d[:, None], phi, br[:, None], order=0)
    mu = transmission_fold(motion.e_theta * np.conj(motion.e_gamma))
    ok_link = motion.ok.all(axis=1)
    mu = np.where(motion.ok, mu, np.nan)

    skipped: Counter[str] = Counter()
    linkage_rows: list[dict[str, Any]] = []
    ids = np.array([linkage_id(s, k) for s, k in zip(sweep_index, br)], dtype=np.int64)
    for i in range(b.size):
        if not ok_link[i]:
            # a crank-rocker closes over the whole turn; anything else is not stored
            skipped["linkage does not assemble over the whole turn"] += 1
            continue
        linkage_rows.append(
            {
                "id": int(ids[i]),
                "shard_index": int(shard_index),
                "sweep_index": int(sweep_index[i]),
                "b": float(b[i]),
                "c": float(c[i]),
                "d": float(d[i]),
                "branch": int(br[i]),
                "grashof": int(grashof[i]),
                "transmission_min": float(np.nanmin(mu[i])),
                "transmission_max": float(np.nanmax(mu[i])),
            }
        )

    keep = ok_link
    search = SegmentSearch.from_spec(spec)
    found = find_segments(b[keep], c[keep], d[keep], br[keep], search)
    skipped.update(found.skipped)
    segment_rows, dwell_rows = found.rows(ids[keep], SEGMENTS_PER_LINKAGE, DWELLS_PER_SEGMENT)
    # the query's covering index holds the linkage's constraint figures with every dwell
    figures = {row["id"]: (row["transmission_min"], max(row["b"], row["c"], row["d"])) for row in linkage_rows}
    linkage_of = {row["id"]: row["linkage_id"] for row in segment_rows}
    for row in dwell_rows:
        row["linkage_transmission_min"], row["longest_link"] = figures[linkage_of[row["segment_id"]]]
    return ShardResult(
        shard_index=int(shard_index),
        linkages=linkage_rows,
        segments=segment_rows,
        dwells=dwell_rows,
        skipped=dict(sorted(skipped.items())),
        seconds=time.perf_counter() - t0,
    )
