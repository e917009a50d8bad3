"""The one place where text meets markup: every user string the tool writes into HTML, SVG or
an inline ``<script>`` goes through these functions.

User strings (joint and link names from a linkage file, candidate ids, titles, captions) are
data, never markup: a name such as ``</script><script>alert(1)</script>`` must show as those
characters and do nothing. Nor may a name act on what shows it: control characters (C0, DEL,
C1: a terminal's escape sequences; XML 1.0 forbids most of them even as references) and the
bidirectional overrides and isolates (U+202A–202E, U+2066–2069: text that reads in another
order than it is) are shown as visible escapes (``\x1b``, ``\u202e``) by every function here.
Linkage files with such names are refused on reading (``kinematics.assur.linkage_file``);
this is the second line of defence, for text from anywhere else (an atlas, a typed id).

- :func:`terminal` — text printed to a terminal (tables, titles, messages).

- :func:`text` — element content and quoted attribute values in HTML and SVG (XML): ``& < > " '``
  become character references, so a value can neither close its element nor its attribute.
- :func:`plot_text` — text for matplotlib (titles, labels, annotations, legend entries): a
  ``$`` would start mathtext, and an unbalanced formula raises while the figure is drawn; a
  character the font cannot draw becomes U+FFFD.
- :func:`script_json` — a JSON value written inside ``<script>`` (executable or
  ``type="application/json"``): ``< > &`` and U+2028/U+2029 become ``\\uXXXX`` escapes, so
  ``</script>`` or ``<!--`` can never appear and end or confuse the block; the result parses as
  the same JSON. Non-finite numbers are refused (:class:`ValueError`): JSON has none.
"""

from __future__ import annotations

import functools
import html
import json
from collections.abc import Callable

__all__ = ["CONTROLS", "plot_text", "script_json", "terminal", "text"]

#: Characters shown as escapes wherever a user string is written: C0, DEL, C1, and the
#: bidirectional embeddings, overrides and isolates.
CONTROLS = frozenset(
    [
        *map(chr, range(0x20)),
        *map(chr, range(0x7F, 0xA0)),
        *map(chr, range(0x202A, 0x202F)),
        *map(chr, range(0x2066, 0x206A)),
    ]
)
_VISIBLE = str.maketrans({ch: (f"\\x{ord(ch):02x}" if ord(ch) < 0x100 else f"\\u{ord(ch):04x}") for ch in CONTROLS})


def terminal(value: object) -> str:
    """``value`` as text for a terminal: every control character and bidirectional override
    shown as a visible escape (``\x1b``), so that it neither moves the cursor nor reorders
    what follows."""
    return str(value).translate(_VISIBLE)


# The characters that would let JSON text end a <script> element, open an HTML comment or end
# a JavaScript string literal in older engines; each becomes a JSON \uXXXX escape.
_SCRIPT_UNSAFE = str.maketrans(
    {"<": "\\u003c", ">": "\\u003e", "&": "\\u0026", "\u2028": "\\u2028", "\u2029": "\\u2029"}
)


def text(value: object) -> str:
    """``value`` as text for HTML/SVG element content or a quoted attribute value."""
    return html.escape(terminal(value), quote=True)


def plot_text(value: object) -> str:
    """``value`` as literal matplotlib text: every ``$`` escaped, so no mathtext is parsed
    (matplotlib's SVG writer escapes markup characters itself), and every character the
    plotting font has no glyph for shown as U+FFFD (matplotlib would draw an empty box and warn
    on the user's terminal for each one, e.g. for a ``--units`` name in another script)."""
    shown = terminal(value).replace("$", r"\$")
    if shown.isascii():
        return shown
    drawable = _plot_font_has()
    return "".join(ch if drawable(ch) else "\ufffd" for ch in shown)


@functools.cache
def _plot_font_has() -> Callable[[str], bool]:
    """Whether the default matplotlib font (the one the reports draw with) has a glyph for a
    character."""
    from matplotlib import font_manager, ft2font

    font = ft2font.FT2Font(font_manager.findfont(font_manager.FontProperties()))
    return lambda ch: font.get_char_index(ord(ch)) != 0


def script_json(value: object, *, indent: int | None = None) -> str:
    """``value`` as JSON safe to place between ``<script>`` and ``</script>``.

    Raises :class:`ValueError` for NaN or infinity (no output is produced).
    """
    separators = (",", ":") if indent is None else (",", ": ")
    raw = json.dumps(value, separators=separators, indent=indent, allow_nan=False, ensure_ascii=False)
    return raw.translate(_SCRIPT_UNSAFE)
