"""Hostile user strings and a parser-based check that written HTML/SVG shows them as text.

The check parses the document (``html.parser`` for HTML, ``xml.etree`` for SVG) instead of
searching for substrings: what a browser would build is what counts.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from html.parser import HTMLParser

#: Names a linkage file (or a candidate id) could carry: closing the script block, breaking out
#: of an attribute, entities, quotes, line/paragraph separators (JavaScript line terminators in
#: old engines), mathtext for the plots, and a very long name.
HOSTILE = (
    "</script><script>alert(1)</script>",
    '"><svg onload=alert(1)>',
    "a&b &amp; &lt;",
    'it\'s "quoted" `x`',
    "line\u2028para\u2029end",
    "<!--<script>",
    "$\\frac{$ a_b^c",  # matplotlib mathtext, unbalanced: must be shown literally, not parsed
    "x" * 5000 + "</script>",
)


class _Counter(HTMLParser):
    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tags: list[str] = []
        self.attrs: list[str] = []
        self.attr_values: list[str] = []
        self.text: list[str] = []
        self.scripts: list[str] = []
        self._in_script = False

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        self.attrs += [name for name, _ in attrs]
        self.attr_values += [v or "" for _, v in attrs]
        self._in_script = tag == "script"
        if tag == "script":
            self.scripts.append("")

    def handle_startendtag(self, tag, attrs):
        self.handle_starttag(tag, attrs)
        self._in_script = False

    def handle_endtag(self, tag):
        if tag == "script":
            self._in_script = False

    def handle_data(self, data):
        if self._in_script:
            self.scripts[-1] += data
        else:
            self.text.append(data)


def check_html(page: str, name: str, *, scripts: int) -> _Counter:
    """Assert ``page`` has exactly ``scripts`` script elements, no ``on*`` attribute, no element
    a name could have injected (svg inside svg aside), and ``name`` appears as text or as a JSON
    string inside a script. Returns the parse for further checks."""
    p = _Counter()
    p.feed(page)
    p.close()
    assert p.tags.count("script") == scripts, (p.tags.count("script"), scripts)
    assert not [a for a in p.attrs if a.lower().startswith("on")]
    everything = "".join(p.text) + "".join(p.attr_values)
    in_scripts = [s for s in p.scripts if _json_strings_contain(s, name)]
    assert name in everything or in_scripts, "the name does not round-trip as text"
    return p


def _json_strings_contain(script: str, name: str) -> bool:
    """True if a JSON literal inside ``script`` (the whole block, or ``const D = {...};``) holds
    ``name`` as a string."""
    text = script.strip()
    start = text.find("{") if not text.startswith(("{", "[")) else 0
    if start < 0:
        return False
    end = text.find("\n", start) if not text.startswith(("{", "[")) else len(text)
    body = text[start:end].rstrip().rstrip(";")
    try:
        value = json.loads(body)
    except ValueError:
        return False
    return any(name in s for s in _strings(value))


def _strings(value):
    if isinstance(value, str):
        yield value
    elif isinstance(value, dict):
        for v in value.values():
            yield from _strings(v)
    elif isinstance(value, list):
        for v in value:
            yield from _strings(v)


def check_svg(svg: str, name: str | None = None) -> ET.Element:
    """Assert ``svg`` is well-formed XML with no script element and no ``on*`` attribute, and
    (if given) ``name`` appears as some element's text."""
    root = ET.fromstring(svg)
    elements = list(root.iter())
    assert not [e for e in elements if e.tag.rsplit("}", 1)[-1] == "script"]
    assert not [a for e in elements for a in e.attrib if a.rsplit("}", 1)[-1].lower().startswith("on")]
    if name is not None:
        texts = {t for e in elements for t in ((e.text or "").strip(), *e.attrib.values())}
        assert any(name in t for t in texts), "the name does not round-trip as text"
    return root
