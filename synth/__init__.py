"""Synthesis of six-bar dwell mechanisms, pure and vectorized: arrays in, frozen
struct-of-arrays dataclasses out, degenerate cases as :class:`kinematics.Status` flags.

The public names of the modules are re-exported here (``from synth import simulate``), the way
shapely's package does; each module's own ``__all__`` says what is public:

* curvature theory of the coupler motion: :mod:`synth.pole`, :mod:`synth.ball`,
  :mod:`synth.double_ball`, :mod:`synth.inflection`, :mod:`synth.line_scan`;
* the names of segment and output kinds: :mod:`synth.kinds`;
* the six-bar and its exact simulation: :mod:`synth.sixbar`; the windowed range of a sampled
  output ψ(φ) (swing, dwell intervals, output deviation): :mod:`synth.output_range`; what a
  user is shown about a six-bar: :mod:`synth.figures`, :mod:`synth.buildability`;
* output dyads fitted to a dwell segment: :mod:`synth.dyad`;
* the query: :mod:`synth.candidates`, :mod:`synth.query`.

Not re-exported: the segment search of the atlas build, :mod:`synth.segments` and
:mod:`synth.dwell_bounds` (``from synth.segments import ...``): ``dwell --help`` loads every
command, hence this package, and those two would add ~25 ms to each start.

Some functions share their module's name (:func:`pole`, :func:`line_scan`,
:func:`buildability`): here the name is the function; import the module with
``importlib.import_module("synth.pole")`` or ``from synth.pole import ...``.
"""

import importlib as _importlib

from synth.ball import *  # noqa: F403
from synth.buildability import *  # noqa: F403
from synth.candidates import *  # noqa: F403
from synth.double_ball import *  # noqa: F403
from synth.dyad import *  # noqa: F403
from synth.figures import *  # noqa: F403
from synth.inflection import *  # noqa: F403
from synth.kinds import *  # noqa: F403
from synth.line_scan import *  # noqa: F403
from synth.output_range import *  # noqa: F403
from synth.pole import *  # noqa: F403
from synth.query import *  # noqa: F403
from synth.sixbar import *  # noqa: F403

#: The modules whose ``__all__`` is re-exported.
_MODULES = ("ball", "buildability", "candidates", "double_ball", "dyad", "figures", "inflection", "kinds", "line_scan",
            "output_range", "pole", "query", "sixbar")

__all__ = sorted(name for module in _MODULES for name in _importlib.import_module(f"synth.{module}").__all__)
