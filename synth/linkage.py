"""The linkage every six-bar is built on, as one record: a four-bar (:class:`FourBar`: crank
``a``, coupler ``b``, rocker ``c``, ground ``d``, assembly branch) and that four-bar with its
coupler point (:class:`CouplerFourBar`: ``u``, ``v``). The atlas's ``linkage`` rows
(``db.rows.linkage_columns``), the query's segment rows (:mod:`synth.query.segment_rows`) and
the six-bar (:class:`synth.mechanism.sixbar.SixBar`) carry these fields through this record,
under these names.

One record serves one linkage (floats) and a batch (arrays of one shape: a struct of arrays,
so that the atlas's and the query's kernels stay vectorized over rows). Lengths are in one unit
with the crank ``a`` (1 in the atlas: crank-normalised); ground pivots A0 = 0, B0 = d.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["CouplerFourBar", "FourBar"]

#: A length of one linkage, or of each linkage of a batch.
Length = float | NDArray[np.float64]
#: An assembly branch (±1) of one linkage, or of each linkage of a batch.
Branches = int | NDArray[np.int64]


@dataclass(frozen=True, slots=True, kw_only=True)
class FourBar:
    """A four-bar (one, or a batch as arrays of one shape). Built with keywords.

    Attributes
    ----------
    b, c, d : float or float64 array
        Coupler, rocker and ground lengths (the crank's unit).
    branch : int or int64 array
        Assembly branch, +1 or −1 (:class:`~kinematics.status.Branch`).
    a : float or float64 array
        Crank length; 1 (the default) in the atlas, whose linkages are crank-normalised.
    """

    b: Length
    c: Length
    d: Length
    branch: Branches
    a: Length = 1.0


@dataclass(frozen=True, slots=True, kw_only=True)
class CouplerFourBar(FourBar):
    """A four-bar with a coupler point (one, or a batch as arrays of one shape). Built with
    keywords.

    Attributes
    ----------
    u, v : float or float64 array
        The coupler point p = u + iv in the coupler's frame (origin at the crank pin A, x-axis
        along A → B), in the crank's unit.
    """

    u: Length
    v: Length

    def mirror_key(self) -> tuple[float, float, float, float, float]:
        """What a linkage shares with its mirror image (one linkage): its lengths to 1e-9 and
        its coupler point to 1e-3 with ``v`` unsigned. The other assembly branch of a four-bar,
        with the coupler point (u, −v), is the mirror image of the linkage and moves the same
        way: the query keeps one six-bar of such a pair (:func:`synth.query.evaluate.distinct`)."""
        return (round(self.b, 9), round(self.c, 9), round(self.d, 9), round(self.u, 3), round(abs(self.v), 3))
