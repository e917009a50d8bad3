"""Atlas build: sweep definition, sharded deterministic batch build, progress, resume."""

from atlas.sweep import PRESETS, SweepLinkages, SweepSpec, SweepSpecError, sweep_linkages

__all__ = ["PRESETS", "SweepLinkages", "SweepSpec", "SweepSpecError", "sweep_linkages"]
