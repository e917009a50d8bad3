"""Sweep specification: which crank-normalised four-bars an atlas holds, and how it is sharded.

A sweep is a pure function of its :class:`SweepSpec`: scrambled Sobol points (scipy.stats.qmc,
seeded) over log-uniform ranges of coupler b, rocker c and ground d (crank a = 1), kept in
draw order, optionally filtered to crank-rockers, each on every requested branch. Shards are
fixed slices of that order, so any engine (local processes, a cluster) computes the same
shard contents, and the database content does not depend on scheduling.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinematics.fourbar import GrashofType, grashof_type

__all__ = ["PRESETS", "SweepLinkages", "SweepSpec", "SweepSpecError", "sweep_linkages"]


#: Tolerance levels a sweep may have (each is a dwell row per segment: more is storage, not precision).
MAX_TOLERANCE_LEVELS = 32
#: Accepted ranges of a sweep's fields (the command line shows and checks the same ones).
#: Proportions (crank = 1): beyond 1:1000 a four-bar is a drawing error, not a mechanism.
PROPORTION_RANGE = (1e-3, 1e3)
SAMPLES_RANGE = (1, 2**31)
#: Crank step of the search (°): finer than 0.05° (7 200 steps a turn) adds no dwell the
#: refinement does not already find, and multiplies the build's time.
CRANK_STEP_RANGE_DEG = (0.05, 30.0)
RAYS_RANGE = (1, 3600)
#: Band half-widths (crank lengths): below 1e-9 the band is float noise on the path.
TOLERANCE_RANGE = (1e-9, 1.0)
SHARD_SIZE_RANGE = (1, 1_000_000)
#: Peak memory of :func:`sweep_linkages` per Sobol point (bytes; 145–214 measured with
#: tracemalloc at 2^18–2^20 points): what the driver's budget check multiplies.
SWEEP_BYTES_PER_SAMPLE = 230


class SweepSpecError(ValueError):
    """A sweep specification that makes no sense (message names the field)."""


@dataclass(frozen=True, slots=True)
class SweepSpec:
    """Everything that decides an atlas's content. Lengths in crank lengths, angles in degrees.

    Attributes
    ----------
    b, c, d : (low, high)
        Log-uniform ranges of coupler, rocker and ground length (crank = 1).
    samples : int
        Sobol points drawn (before the crank-rocker filter).
    seed : int
        Scrambling seed: the same spec always gives the same linkages.
    crank_rockers_only : bool
        Keep only Grashof crank-rockers (a full-turn crank, a rocking rocker).
    branches : tuple of ±1
        Assembly branches; every kept proportion is built on each.
    crank_step_deg : float
        Crank-angle step of the candidate search (Ball points, line scanning).
    rays : int
        Scan rays through the pole per crank step (evenly over 180°).
    tolerances : tuple of float
        Band half-widths (crank lengths) at which dwell intervals are measured.
    min_dwell_deg : float
        Shortest dwell kept; candidates that cannot reach it are pruned early.
    shard_size : int
        Proportions per shard (the unit of work, of commit and of resume).
    """

    name: str = "custom"
    b: tuple[float, float] = (1.2, 6.0)
    c: tuple[float, float] = (1.2, 6.0)
    d: tuple[float, float] = (1.2, 6.0)
    samples: int = 1024
    seed: int = 0
    crank_rockers_only: bool = True
    branches: tuple[int, ...] = (1, -1)
    crank_step_deg: float = 2.0
    rays: int = 36
    tolerances: tuple[float, ...] = (1e-4, 1e-3, 1e-2)
    min_dwell_deg: float = 20.0
    shard_size: int = 64

    def __post_init__(self) -> None:
        for field in ("b", "c", "d"):
            lo, hi = getattr(self, field)
            if not (math.isfinite(lo) and math.isfinite(hi) and PROPORTION_RANGE[0] <= lo <= hi <= PROPORTION_RANGE[1]):
                raise SweepSpecError(
                    f"range {field} must satisfy {PROPORTION_RANGE[0]:g} <= low <= high <= "
                    f"{PROPORTION_RANGE[1]:g} (crank = 1), got ({lo:g}, {hi:g})"
                )
        if not SAMPLES_RANGE[0] <= self.samples <= SAMPLES_RANGE[1]:
            raise SweepSpecError(f"samples must be between 1 and 2^31, got {self.samples}")
        if self.seed < 0:  # numpy's seed sequence takes non-negative integers only
            raise SweepSpecError(f"seed must be >= 0, got {self.seed}")
        if (
            not self.branches
            or any(b not in (1, -1) for b in self.branches)
            or len(set(self.branches)) != len(self.branches)
        ):
            raise SweepSpecError(f"branches must be distinct values from (1, -1), got {self.branches}")
        if not CRANK_STEP_RANGE_DEG[0] <= self.crank_step_deg <= CRANK_STEP_RANGE_DEG[1]:
            raise SweepSpecError(
                f"crank_step_deg must be in [{CRANK_STEP_RANGE_DEG[0]:g}, {CRANK_STEP_RANGE_DEG[1]:g}], "
                f"got {self.crank_step_deg:g}"
            )
        if not RAYS_RANGE[0] <= self.rays <= RAYS_RANGE[1]:
            raise SweepSpecError(f"rays must be between 1 and 3600, got {self.rays}")
        if not self.tolerances or any(not (TOLERANCE_RANGE[0] <= t < TOLERANCE_RANGE[1]) for t in self.tolerances):
            raise SweepSpecError(
                f"tolerances must be in [{TOLERANCE_RANGE[0]:g}, 1) crank lengths, got {self.tolerances}"
            )
        if list(self.tolerances) != sorted(self.tolerances):
            raise SweepSpecError("tolerances must be in increasing order")
        if len(self.tolerances) > MAX_TOLERANCE_LEVELS:
            raise SweepSpecError(f"at most {MAX_TOLERANCE_LEVELS} tolerances, got {len(self.tolerances)}")
        if not 0 < self.min_dwell_deg < 360:
            raise SweepSpecError(f"min_dwell_deg must be in (0, 360), got {self.min_dwell_deg:g}")
        if not SHARD_SIZE_RANGE[0] <= self.shard_size <= SHARD_SIZE_RANGE[1]:
            raise SweepSpecError(f"shard_size must be between 1 and {SHARD_SIZE_RANGE[1]}, got {self.shard_size}")

    def to_dict(self) -> dict[str, Any]:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SweepSpec:
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = set(data) - names
        if unknown:
            raise SweepSpecError(f"unknown sweep field(s): {', '.join(sorted(unknown))}")
        fields = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
        return cls(**fields)

    def to_json(self) -> str:
        """Canonical JSON (sorted keys): what the build table stores."""
        return json.dumps(self.to_dict(), sort_keys=True)

    @property
    def digest(self) -> str:
        """SHA-256 of the canonical JSON, ignoring the preset name."""
        data = self.to_dict()
        data.pop("name")
        return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()

    def replace(self, **changes: Any) -> SweepSpec:
        return dataclasses.replace(self, **changes)


#: Named sweeps. ``demo`` builds in seconds; ``standard`` holds ≥ 20 000 linkages;
#: ``large`` ≥ 1 000 000 (a cluster or a long night).
PRESETS: dict[str, SweepSpec] = {
    "demo": SweepSpec(
        name="demo", b=(1.5, 4.5), c=(1.5, 4.5), d=(1.5, 4.5), samples=1024, crank_step_deg=3.0, rays=24, shard_size=32
    ),
    "standard": SweepSpec(name="standard", samples=2**15, crank_step_deg=2.0, rays=36, shard_size=128),
    "large": SweepSpec(name="large", samples=2**21, crank_step_deg=2.0, rays=36, shard_size=256),
}


@dataclass(frozen=True, slots=True)
class SweepLinkages:
    """The proportions of a sweep (crank = 1), struct of arrays in canonical (draw) order.

    ``sweep_index`` numbers the proportions before branches are applied; each proportion is
    built on every branch of the spec.
    """

    sweep_index: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: np.ndarray
    grashof: np.ndarray

    def __len__(self) -> int:
        return int(self.sweep_index.size)

    def shard(self, index: int, shard_size: int) -> SweepLinkages:
        s = slice(index * shard_size, (index + 1) * shard_size)
        return SweepLinkages(self.sweep_index[s], self.b[s], self.c[s], self.d[s], self.grashof[s])

    def n_shards(self, shard_size: int) -> int:
        return max(1, -(-len(self) // shard_size))


def sweep_linkages(spec: SweepSpec) -> SweepLinkages:
    """Draw the sweep's proportions (deterministic in ``spec``)."""
    from scipy.stats import qmc

    m = max(0, math.ceil(math.log2(spec.samples)))
    unit = qmc.Sobol(d=3, scramble=True, seed=spec.seed).random_base2(m)[: spec.samples]
    lo = np.log([spec.b[0], spec.c[0], spec.d[0]])
    hi = np.log([spec.b[1], spec.c[1], spec.d[1]])
    b, c, d = np.exp(lo + unit * (hi - lo)).T
    kind = grashof_type(1.0, b, c, d)
    keep = kind == GrashofType.CRANK_ROCKER if spec.crank_rockers_only else np.ones(b.size, bool)
    index = np.flatnonzero(keep)
    return SweepLinkages(index, b[keep], c[keep], d[keep], kind[keep])
