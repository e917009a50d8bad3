"""One shard of an atlas build: a pure function of (sweep spec, shard index) → database rows.

Any engine (local processes, a cluster) can run it; the driver alone writes. The rows and their
deterministic ids are :mod:`db.rows`'s.
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from atlas.sweep import SweepLinkages, SweepSpec, sweep_linkages
from db.digest import shard_digest
from db.packed import PACKING, PackedShard, pack
from db.rows import TableColumns, linkage_columns, segment_columns
from kinematics.fourbar import fourbar_motion
from kinematics.loop import transmission_fold
from synth.linkage import FourBar
from synth.segment_search.segments import SegmentSearch, find_segments

__all__ = ["ShardResult", "compute_shard", "handed_over"]

#: Crank samples over the turn for a linkage's transmission-angle range.
_TRANSMISSION_SAMPLES = 360


@dataclass(frozen=True, slots=True)
class ShardResult:
    """Rows of one shard per table, as columns (:class:`db.rows.TableColumns`: arrays, ids
    included; :meth:`~db.rows.TableColumns.rows` spells them out as dicts). ``skipped`` counts
    degenerate cases by reason; ``seconds`` is the compute time (not part of the content);
    ``digest`` the shard's ``db.digest.shard_digest`` (None: the writer computes it)."""

    shard_index: int
    linkages: TableColumns
    segments: TableColumns
    dwells: TableColumns
    skipped: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0
    digest: str | None = None

    @property
    def n_segments(self) -> int:
        return len(self.segments)

    @property
    def linkage_ids(self) -> tuple[int, ...]:
        return tuple(np.asarray(self.linkages.values.get("id", ()), np.int64).tolist())


def handed_over(result: ShardResult) -> ShardResult | PackedShard:
    """``result`` as a worker process hands it to the writer: packed (:mod:`db.packed`: its
    rows checked and put in a small SQLite database, which the writer copies in C), or as it
    is where this Python's sqlite3 cannot pack."""
    return pack(result, result.digest) if PACKING else result


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
    keep = ok_link
    if not keep.all():  # a crank-rocker closes over the whole turn; anything else is not stored
        skipped["linkage does not assemble over the whole turn"] += int(np.count_nonzero(~keep))
    kept = FourBar(b=b[keep], c=c[keep], d=d[keep], branch=br[keep])
    links = linkage_columns(shard_index, sweep_index[keep], kept, grashof[keep], mu[keep])
    found = find_segments(kept.b, kept.c, kept.d, kept.branch, SegmentSearch.from_spec(spec))
    skipped.update(found.skipped)
    segments, dwells = segment_columns(found, links)
    digest = shard_digest(links, segments, dwells)  # here, on a worker, from the arrays: the writer stays free
    return ShardResult(
        shard_index=int(shard_index),
        linkages=links,
        segments=segments,
        dwells=dwells,
        skipped=dict(sorted(skipped.items())),
        seconds=time.perf_counter() - t0,
        digest=digest,
    )
