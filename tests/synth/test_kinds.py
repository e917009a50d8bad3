"""synth.kinds: the enums keep the strings the atlas stores and the candidate ids show."""

import pytest
from sqlalchemy import CheckConstraint

from db.schema import Segment
from synth.kinds import SEGMENT_KINDS, OutputKind, OutputTag, SegmentKind
from synth.mechanism.sixbar import OutputDyad
from synth.query.candidate_ids import candidate_id, parse_candidate_id


def test_segment_kinds_keep_their_stored_spelling_and_codes():
    assert [k.value for k in SEGMENT_KINDS] == ["line", "arc", "double_line"]
    assert [k.code for k in SEGMENT_KINDS] == [0, 1, 2]
    assert SegmentKind("double_line") is SegmentKind.DOUBLE_LINE and SegmentKind.ARC == "arc"


def test_the_schema_check_is_built_from_the_enum():
    (check,) = [
        c for c in Segment.__table__.constraints if isinstance(c, CheckConstraint) and c.name == "ck_segment_kind"
    ]
    assert str(check.sqltext) == "kind IN ('line', 'arc', 'double_line')"


def test_output_kinds_and_tags():
    assert [k.value for k in OutputKind] == ["RPR", "RRR"]
    assert [t.value for t in OutputTag] == ["rpr", "rrr", "dbl"]
    assert [t.dyad for t in OutputTag] == [OutputKind.RPR, OutputKind.RRR, OutputKind.RPR]
    assert OutputDyad("rrr", 1 + 1j, 2.0, 3.0, -1).kind is OutputKind.RRR
    with pytest.raises(ValueError, match="'RPR', 'RRR'"):
        OutputDyad("RRP", 0j)


@pytest.mark.parametrize("tag", list(OutputTag))
def test_candidate_ids_are_unchanged(tag):
    text = candidate_id(1234500007, tag, 1, 0, None)
    assert text == f"1234500007-{tag.value}1.0@free"
    assert parse_candidate_id(text) == (1234500007, tag, 1, 0, None)
    assert parse_candidate_id(text)[1] is tag
