"""Curvature theory of the coupler motion: the pole and its derivatives, Ball's point and the
double Ball points, the inflection circle and the line scan of conjugate pairs (docs/curvature.md).
No re-exports: import the modules (``from synth.curvature.pole import pole``), or the public names
from :mod:`synth`.
"""
