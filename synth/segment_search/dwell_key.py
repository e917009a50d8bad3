"""The arc's dwell key: how the atlas orders arcs by the RRR dwell they predict.

An RRR output fitted to an arc (rod ρ = the circle's radius, the moving pivot Q resting at its
centre C, rocker L about D) holds its output within a band β while the coupler point stays
within about ε* = L·β/2 of the circle (crank lengths, radians). Away from the dwell Q follows
the point at distance ρ, so |Q − C| ≥ | |P − C| − ρ |, and Q stays on an arc of radius L and
angle S (the swing) through C, whose chord is 2L·sin(S/2): the rocker a swing needs is
L ≈ E / (2 sin(S/2)), E the **excursion** (the path's largest distance from the circle over
the turn; ``synth.segment_search.segments.FoundSegments.excursion``). On ``standard``'s fitted RRR six-bars
L / (E / 2 sin(S/2)) has median 1.01–1.04 (``docs/complete-query.md`` §8).

A stored dwell grows like ε^¼ (four-point contact with the circle), so a row stored with dwell
Δ at path tolerance ε predicts the six-bar dwell

    Δ · (ε*/ε)^¼ = Δ·E^¼ · (β / (4 ε sin(S/2)))^¼.

The first factor, the **dwell key** Δ·E^¼ (rad · crank^¼), is the row's own; the second is
the request's, one number per tolerance level. The atlas orders arc rows by their key, so the
query reads the rows that predict a requested dwell with one walk per level (measured on
``standard``: the RRR six-bars meeting 120°/60° lie in the first ~600 of ~150 000 rows of a
level by this order, against nowhere in particular by the stored dwell alone).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["arc_dwell_key", "arc_key_target", "predicted_rrr_dwell"]


def arc_dwell_key(dwell: ArrayLike, excursion: ArrayLike, tolerance: ArrayLike) -> NDArray[np.float64]:
    """The dwell key Δ·E^¼ of arc rows with stored dwell ``dwell`` (rad) and ``excursion``
    (crank lengths) at path ``tolerance``. The excursion is taken as at least the tolerance:
    the path leaves the band where the dwell ends, so a smaller one is only the fine grid's
    sampling (and a key must stay positive). ``tolerance`` may be an array (one per row).

    The fourth root as two square roots: IEEE square roots are correctly rounded on every path,
    so a row's key is the same float whether it is computed alone or in an array (numpy's
    ``** 0.25`` on an array may take a vector ``pow`` whose last bit differs from a scalar's):
    the stored keys and the content digest do not depend on how rows are batched."""
    return np.asarray(dwell, float) * np.sqrt(np.sqrt(np.maximum(np.asarray(excursion, float), tolerance)))


def arc_key_target(dwell: float, swing: float, band: float, tolerance: float) -> float:
    """The dwell key at ``tolerance`` (crank lengths) that predicts an RRR six-bar dwell of
    ``dwell`` with output ``swing`` and ``band`` (all rad): dwell · (4 ε sin(S/2) / β)^¼."""
    return dwell * (4.0 * tolerance * math.sin(swing / 2) / band) ** 0.25


def predicted_rrr_dwell(key: ArrayLike, swing: float, band: float, tolerance: float) -> NDArray[np.float64]:
    """The RRR six-bar dwell (rad) that rows of dwell ``key`` at ``tolerance`` predict for
    ``swing`` and ``band`` (rad): the inverse of :func:`arc_key_target`."""
    return np.asarray(key, float) * (band / (4.0 * tolerance * math.sin(swing / 2))) ** 0.25
