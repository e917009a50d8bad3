"""What the query answers: a :class:`QueryResult` (ranked candidates, counts, times) and, when
nothing met the request, a :class:`NoMatch` naming the constraint in the way.
"""

from __future__ import annotations

from dataclasses import dataclass

from synth.query.candidates import Candidate, Request

#: The request's constraints, in the order a no-match names them (see :func:`violations`).
CONSTRAINTS = ("assembly", "dwell", "swing", "step", "transmission", "link_ratio", "arm", "clearance", "acceleration")


#: What a :attr:`NoMatch.reach` figure is the best of: the fitted six-bars meeting every other
#: limit; the six-bars the sample's segments give with their output dyads fitted without the
#: limit (nothing was fitted within it); the stored four-bars near the request (the sample
#: held no segment within the limit).
REACH_AMONG = ("fitted", "fitted without the limit", "four-bars")


@dataclass(frozen=True, slots=True)
class NoMatch:
    """Why nothing met a request.

    Attributes
    ----------
    fitted : int
        Fitted six-bars examined (0: no stored segment was near the request).
    rejected : dict
        Per constraint of :data:`CONSTRAINTS`, how many of them it rejected (a six-bar can
        fail several; ``assembly`` counts those that do not assemble over the turn, toggle or
        revolve, which are not checked further).
    nearest : Candidate or None
        The six-bar closest to meeting the request (the smallest sum of its excesses over the
        limits, angles in degrees, the link ratio in percent of the limit), in the user's units.
    would_meet : Request or None
        The request loosened just enough for ``nearest`` to meet it.
    """

    fitted: int
    rejected: dict[str, int]
    nearest: Candidate | None
    would_meet: Request | None
    #: The one constraint in the way, with a figure: ``(constraint, best, limit)`` where
    #: ``constraint`` is the one the nearest six-bar that misses a single constraint misses,
    #: and ``best`` the best figure on it of every fitted six-bar that meets all the others —
    #: dwell, swing and step: the value nearest the request's (°); transmission: the largest
    #: (°); link ratio, acceleration: the smallest; arm, clearance: the largest (crank
    #: lengths) — against the request's ``limit`` (the requested value for dwell, swing and
    #: step). None when no fitted six-bar misses one constraint alone. With nothing fitted:
    #: the transmission angle when the best figure within reach is below its limit
    #: (:func:`~synth.query.diagnosis.unfitted_reach`).
    reach: tuple[str, float, float] | None = None
    #: Whose figure ``reach`` gives: one of :data:`REACH_AMONG`.
    reach_among: str = "fitted"

    @property
    def failed(self) -> str | None:
        """The constraint that rejected the most six-bars (None if nothing was fitted)."""
        if not self.fitted:
            return None
        return max(CONSTRAINTS, key=lambda k: (self.rejected.get(k, 0), -CONSTRAINTS.index(k)))


@dataclass(frozen=True, slots=True)
class QueryResult:
    request: Request
    candidates: list[Candidate]
    considered: int  #: segments fitted
    simulated: int  #: six-bars simulated
    #: stored dwell angles (rad) around the request when nothing was fitted (else None, None)
    nearest: tuple[float | None, float | None]
    seconds: dict[str, float]
    no_match: NoMatch | None = None
    #: six-bars refined (the returned ones, or the nearest misses when nothing met the
    #: request), and how many of them came out better (the others are kept unchanged)
    refined: tuple[int, int] = (0, 0)
    #: True when nothing in the atlas met the request and the candidates are refined near misses
    from_misses: bool = False
    #: how many of the candidates are near misses refined to meet the request (see FILL)
    misses_met: int = 0
    #: how many of the candidates are six-bars whose output pivot was moved off the fitted one
    #: (:func:`reseat`; their ids carry the dimensions)
    reseated: int = 0
    #: With refinement, an answer of fewer six-bars than ``synth.query.FILL`` (or ``--top``):
    #: per output type, ``(output, constraint, best, limit)``, the one constraint in the way of
    #: more, as :attr:`NoMatch.reach` over the fitted six-bars the answer's were not refined
    #: from (:func:`~synth.query.diagnosis.reach_beyond`); empty otherwise, or when none of
    #: them misses a single constraint.
    short_of: tuple[tuple[str, str, float, float], ...] = ()


class RebuildError(ValueError):
    """A candidate id that cannot be rebuilt from this atlas (message names the id)."""
