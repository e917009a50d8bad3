"""Every module path the product's text names exists: a dotted name under ``synth.`` or
``kinematics.`` (``synth.mechanism.sixbar.simulate``) imports and resolves, and a file path
under a package folder (``synth/query/refine.py``) is a file — in the product's modules
(docstrings and comments included), ``docs/`` and the README. A module moved or split leaves
no reader sent to where it was."""

from __future__ import annotations

import importlib
import importlib.util
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("kinematics", "synth", "atlas", "db", "report", "cli")
#: Dotted names of the pure layers: the other packages' names are also local variables
#: (``atlas.target``, ``db.name``), which a text scan cannot tell apart.
DOTTED = re.compile(r"(?<![\w./])((?:synth|kinematics)(?:\.[A-Za-z_]\w*)+)")
PATH = re.compile(rf"(?<![\w/])((?:{'|'.join(PACKAGES)})/[\w/]+\.py)\b")


def _texts() -> list[Path]:
    product = [p for top in PACKAGES for p in sorted((ROOT / top).rglob("*.py")) if ".venv" not in p.parts]
    return product + sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]


def resolves(name: str) -> bool:
    """Whether ``name`` is a module, or a module's attribute path (``pkg.mod.func.attr``)."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        module = ".".join(parts[:k])
        try:
            if importlib.util.find_spec(module) is None:
                continue
        except ModuleNotFoundError:  # a parent of ``module`` is no package
            continue
        obj = importlib.import_module(module)
        for attribute in parts[k:]:
            if not hasattr(obj, attribute):
                return False
            obj = getattr(obj, attribute)
        return True
    return False


def stale(path: Path) -> list[str]:
    """``line: name`` for every name in ``path`` that names no module or file of the checkout."""
    out = []
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        out += [f"{number}: {m.group(1)}" for m in DOTTED.finditer(line) if not resolves(m.group(1))]
        out += [f"{number}: {m.group(1)}" for m in PATH.finditer(line) if not (ROOT / m.group(1)).is_file()]
    return out


def test_every_module_path_the_text_names_exists():
    paths = _texts()
    assert len(paths) > 150
    found = [f"{p.relative_to(ROOT)}:{line}" for p in paths for line in stale(p)]
    assert not found, "names of modules that do not exist:\n" + "\n".join(found)


def test_the_scan_finds_a_stale_path(tmp_path):
    """The pre-rooms flat modules (``synth.sixbar``, ``synth/refine.py``) are what it catches;
    a public name re-exported by ``synth`` and a current path pass."""
    doc = tmp_path / "page.md"
    doc.write_text(
        "see `synth.sixbar.simulate` and synth/refine.py;\n"
        "`synth.simulate`, synth.mechanism.sixbar.SixBar.scaled, synth/query/refine.py\n",
        encoding="utf-8",
    )
    assert stale(doc) == ["1: synth.sixbar.simulate", "1: synth/refine.py"]
