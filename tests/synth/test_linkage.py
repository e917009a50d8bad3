"""The linkage record (synth.linkage): the six-bar holds its four-bar and coupler point as one
:class:`CouplerFourBar`, and the mirror key is what a linkage shares with its mirror image."""

from __future__ import annotations

import dataclasses
import math
import pickle

import numpy as np
import pytest

from kinematics.fourbar import fourbar_motion
from synth.linkage import CouplerFourBar, FourBar
from synth.mechanism.sixbar import AssemblyError, OutputDyad, SixBar

DYAD = OutputDyad.rrr(complex(4.219, -0.5853), 0.4984, 2.807, 1)


def test_a_six_bar_holds_its_linkage_as_one_record():
    sb = SixBar(1.0, 3.542, 2.49, 3.938, 1, 3.645, -0.321, DYAD)
    assert sb.fourbar == CouplerFourBar(b=3.542, c=2.49, d=3.938, branch=1, u=3.645, v=-0.321)
    assert (sb.a, sb.b, sb.c, sb.d, sb.branch, sb.u, sb.v) == (1.0, 3.542, 2.49, 3.938, 1, 3.645, -0.321)
    assert [f.name for f in dataclasses.fields(SixBar)] == ["fourbar", "dyad"]
    assert SixBar.of(sb.fourbar, DYAD) == sb and hash(SixBar.of(sb.fourbar, DYAD)) == hash(sb)
    assert pickle.loads(pickle.dumps(sb)) == sb
    twice = sb.scaled(2.0)
    assert twice.fourbar == CouplerFourBar(a=2.0, b=7.084, c=4.98, d=7.876, branch=1, u=7.29, v=-0.642)
    assert isinstance(sb.fourbar, FourBar)


@pytest.mark.parametrize(
    ("args", "error", "message"),
    [
        ((0.0, 3.0, 2.0, 3.0, 1, 0.0, 0.0), AssemblyError, "length a must be finite and > 0, got 0.0"),
        ((1.0, 3.0, 2.0, math.inf, 1, 0.0, 0.0), AssemblyError, "length d must be finite and > 0, got inf"),
        ((1.0, 3.0, 2.0, 3.0, 1, math.nan, 0.0), AssemblyError, "coupler point u must be finite, got nan"),
        ((1.0, 3.0, 2.0, 3.0, 0, 0.0, 0.0), ValueError, "four-bar branch must be \\+1 or -1, not 0"),
    ],
)
def test_a_six_bar_is_validated_as_it_is_built(args, error, message):
    with pytest.raises(error, match=message):
        SixBar(*args, DYAD)


def test_the_mirror_key_is_what_a_linkage_shares_with_its_mirror_image():
    """The other branch with the coupler point (u, −v) is the linkage reflected in its ground
    line: at crank angle φ its coupler point is the reflection of the original's at −φ (the
    same motion, mirrored). Both have one key; another coupler point has another key."""
    fb = CouplerFourBar(b=3.542, c=2.49, d=3.938, branch=1, u=3.645, v=-0.321)
    mirror = dataclasses.replace(fb, branch=-1, v=0.321)
    phi = np.linspace(0.0, 2 * math.pi, 73)

    def path(f: CouplerFourBar, at: np.ndarray) -> np.ndarray:
        m = fourbar_motion(f.a, f.b, f.c, f.d, at, f.branch, order=0)
        assert m.ok.all()
        return m.A + m.e_theta * complex(f.u, f.v)

    np.testing.assert_allclose(path(mirror, phi), np.conj(path(fb, -phi)), atol=1e-12)
    assert mirror.mirror_key() == fb.mirror_key() == (3.542, 2.49, 3.938, 3.645, 0.321)
    assert dataclasses.replace(fb, u=3.7).mirror_key() != fb.mirror_key()
