"""Short candidate ids: what the query's table shows in place of the full id.

A full id (:func:`synth.query.candidate_ids.candidate_id`) names the six-bar exactly — its segment,
output dyad, slot, tolerance level, swing and, refined, its dimensions in base64url — and runs to
70 characters. The short id keeps what a person reads (the segment and the output dyad) and
adds five characters of a hash of the whole full id::

    2947500003-rrr0.2@30                                                     → 2947500003-rrr-k3lap
    991900016-rrr1.2@30~BkCQh0U__OzUQJiDoECCWatAU0AkwA64VUEPfUs_pehpQNDG0A   → 991900016-rrr-e2f2y

It is a pure function of the full id (the same six-bar always gets the same short id) and is at
most :data:`MAX_LENGTH` characters. It cannot be turned back into the full id on its own:
``dwell report`` looks it up among the ids the query has shown (:mod:`cli.shown_ids`).
"""

from __future__ import annotations

import base64
import hashlib
import re

__all__ = ["HASH_CHARS", "MAX_LENGTH", "SHORT_ID", "short_id"]

#: Characters of the hash: base32 (a–z, 2–7), 25 bits — two different six-bars of one
#: segment and output dyad share a short id with odds of 1 in 33 million.
HASH_CHARS = 5
#: Longest short id: a segment id of up to 14 digits (atlases of up to 10^8 linkages, db/rows.py)
#: plus ``-rrr-`` and the hash.
MAX_LENGTH = 24
_SEGMENT_DIGITS = MAX_LENGTH - len("-rrr-") - HASH_CHARS
#: A short id as typed (ASCII): segment digits, output dyad, hash.
SHORT_ID = re.compile(rf"([0-9]{{1,{_SEGMENT_DIGITS}}})-(rpr|rrr|dbl)-([a-z2-7]{{{HASH_CHARS}}})", re.ASCII)
_HEAD = re.compile(r"\s*([0-9]+)-(rpr|rrr|dbl)", re.ASCII)


def short_id(full_id: str) -> str:
    """``<segment>-<rpr|rrr|dbl>-<hash>`` of a candidate id as ``dwell query`` prints it.

    Parameters
    ----------
    full_id : str
        ``<segment>-<output><slot>.<level>@<swing>[~<dimensions>]``.

    Returns
    -------
    str
        At most :data:`MAX_LENGTH` characters; the hash is of ``full_id`` as given (UTF-8),
        so ids that differ in any character differ in it (but for the odds of
        :data:`HASH_CHARS`). A segment id longer than 14 digits keeps its last 14.

    Raises
    ------
    ValueError
        If ``full_id`` does not start as a candidate id does.
    """
    head = _HEAD.match(full_id)
    if head is None:
        raise ValueError(f"not a candidate id: {full_id!r}")
    digest = hashlib.sha256(full_id.encode("utf-8")).digest()
    tag = base64.b32encode(digest).decode("ascii")[:HASH_CHARS].lower()
    return f"{head.group(1)[-_SEGMENT_DIGITS:]}-{head.group(2)}-{tag}"
