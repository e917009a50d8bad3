"""Synth's common types: array aliases, the thresholds that decide when a curvature quantity is
degenerate, and the flag sets the kernels test (flags: :class:`kinematics.Status`). One
definition each, used by the pole, the inflection circle, Ball's point, the line scan and the
double Ball points. Lengths relative to the linkage size, angles in radians.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinematics.status import Status

__all__ = ["ANY_FLAG", "C128", "F64", "FAR", "INVALID", "MAX_CONDITION", "RAY_EPS", "U16"]

F64 = NDArray[np.float64]
C128 = NDArray[np.complex128]
U16 = NDArray[np.uint16]

#: Distances beyond ``FAR`` × linkage size count as infinite (see ``synth.curvature.pole``'s notes).
FAR = 1e6
#: Condition number L/(min(b, c)·|sin(θ − γ)|) above which an instant is ``ILL_CONDITIONED``.
MAX_CONDITION = 100.0
#: Angle (rad) from the pole tangent or normal below which a ray is degenerate.
RAY_EPS = 1e-9

#: Every flag: ``on_degenerate="raise"`` raises on any of them.
ANY_FLAG = Status(sum(int(f) for f in Status))
#: Instant flags after which no curvature quantity at that instant is meaningful.
INVALID = int(
    Status.NOT_ASSEMBLABLE
    | Status.TOGGLE
    | Status.ILL_CONDITIONED
    | Status.POLE_AT_INFINITY
    | Status.INFLECTION_CIRCLE_COLLAPSED
)
