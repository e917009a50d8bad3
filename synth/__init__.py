"""Synthesis of six-bar dwell mechanisms, pure and vectorized: arrays in, frozen
struct-of-arrays dataclasses out, degenerate cases as :class:`kinematics.Status` flags.

Four rooms, each a package (what imports what: curvature ← segment search; six-bar ← query):

* :mod:`synth.curvature` — curvature theory of the coupler motion: :mod:`~synth.curvature.pole`,
  :mod:`~synth.curvature.ball`, :mod:`~synth.curvature.double_ball`,
  :mod:`~synth.curvature.inflection`, :mod:`~synth.curvature.line_scan`;
* :mod:`synth.segment_search` — the atlas build's dwell segments of coupler curves:
  :mod:`~synth.segment_search.segments`, their measures, bounds and keys;
* :mod:`synth.mechanism` — the six-bar and its exact simulation (:mod:`~synth.mechanism.sixbar`),
  the windowed range of a sampled output ψ(φ) (:mod:`~synth.mechanism.output_range`), what a user
  is shown about a six-bar (:mod:`~synth.mechanism.figures`, :mod:`~synth.mechanism.buildability`),
  output dyads fitted to a dwell segment (:mod:`~synth.mechanism.dyad`);
* :mod:`synth.query` — the query: requests and candidates (:mod:`~synth.query.candidates`), the
  stage (:func:`synth.query.answer`) and its refinement (:mod:`~synth.query.refine`).

Beside them: the linkage every six-bar is built on, one record for the atlas's rows, the query's
segment rows and the six-bar (:mod:`synth.linkage`: :class:`FourBar`, :class:`CouplerFourBar`),
the names of segment and output kinds (:mod:`synth.kinds`), the common array types
(:mod:`synth.types`) and the compiled kernels' row split (:mod:`synth.parallel_rows`). Each
compiled ``*_kernel.py`` sits beside the numpy module it twins.

The public names of the modules are re-exported here (``from synth import simulate``), the way
shapely's package does; each module's own ``__all__`` says what is public. Not re-exported: the
segment search of the atlas build (``from synth.segment_search.segments import ...``): ``dwell
--help`` loads every command, hence this package, and it would add ~25 ms to each start.

Some functions share their module's name (:func:`pole`, :func:`line_scan`,
:func:`buildability`): here the name is the function; import the module with
``importlib.import_module("synth.curvature.pole")`` or ``from synth.curvature.pole import ...``.
"""

import importlib as _importlib

from synth.curvature.ball import *  # noqa: F403
from synth.curvature.double_ball import *  # noqa: F403
from synth.curvature.inflection import *  # noqa: F403
from synth.curvature.line_scan import *  # noqa: F403
from synth.curvature.pole import *  # noqa: F403
from synth.kinds import *  # noqa: F403
from synth.linkage import *  # noqa: F403
from synth.mechanism.buildability import *  # noqa: F403
from synth.mechanism.dyad import *  # noqa: F403
from synth.mechanism.figures import *  # noqa: F403
from synth.mechanism.output_range import *  # noqa: F403
from synth.mechanism.sixbar import *  # noqa: F403
from synth.query import *  # noqa: F403
from synth.query.candidate_ids import *  # noqa: F403
from synth.query.candidates import *  # noqa: F403

#: The modules whose ``__all__`` is re-exported (no name is exported by two of them).
_MODULES = (
    "curvature.ball",
    "curvature.double_ball",
    "curvature.inflection",
    "curvature.line_scan",
    "curvature.pole",
    "kinds",
    "linkage",
    "mechanism.buildability",
    "mechanism.dyad",
    "mechanism.figures",
    "mechanism.output_range",
    "mechanism.sixbar",
    "query",
    "query.candidate_ids",
    "query.candidates",
)

__all__ = sorted(name for module in _MODULES for name in _importlib.import_module(f"synth.{module}").__all__)
