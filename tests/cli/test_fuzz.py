"""Fuzzing the ``dwell`` command: random argument lists for every command and subcommand (found
by walking the click group, lazy groups included), random mechanism files for
``dwell analyze linkage``.

Whatever is typed, the answer is exit status 0 or 2 — never a traceback — and nothing is half
written: after exit 2 the working folder (outputs, atlases) is exactly as before; after exit 0
every new or changed file is complete (a PNG ends in IEND, an SVG/HTML/JSON document is whole,
an atlas opens and is complete) and ``--json`` output is strict JSON (no NaN or Infinity).

Arguments mix every real option name with edge values (negative, zero, huge, nan, inf, empty,
non-numbers, unicode, missing values) and unknown options, on top of a valid base line, so
that examples get past the parser into the command. Each example runs in-process through
``cli.main.main`` (which maps errors to exit statuses; ``CliRunner.invoke`` on the group would
bypass it) inside ``CliRunner.isolation`` (captured stdio), in a fresh folder. Sizes are kept
small: an example whose parsed options would make a long run (many samples, worker pools, a
fine crank step, …) is rejected before it runs; commands that cannot be bounded that way
(``bench faults``, commands this file does not know) are fuzzed up to their option parser.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
import sqlite3
import subprocess
import sys
import tempfile
import tomllib
import traceback
import xml.etree.ElementTree as ET
from pathlib import Path

import click
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from cli.main import dwell, main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "linkages"

# ------------------------------------------------------------------------------- the commands


def _walk(command: click.Command, path: tuple[str, ...], parent: click.Context | None):
    ctx = click.Context(command, info_name=path[-1] if path else "dwell", parent=parent)
    yield path, command
    if isinstance(command, click.Group):
        for name in command.list_commands(ctx):
            yield from _walk(command.get_command(ctx, name), (*path, name), ctx)


COMMANDS: dict[tuple[str, ...], click.Command] = dict(_walk(dwell, (), None))
GROUPS = [p for p, c in COMMANDS.items() if isinstance(c, click.Group)]
LEAVES = [p for p, c in COMMANDS.items() if not isinstance(c, click.Group)]


def test_every_command_is_found():
    assert {(), ("analyze",), ("atlas",), ("bench",)} <= set(GROUPS)
    assert {
        ("demo",),
        ("query",),
        ("report",),
        ("curvature",),
        ("analyze", "fourbar"),
        ("analyze", "linkage"),
        ("analyze", "slider-crank"),
        ("analyze", "shaper"),
        ("atlas", "build"),
        ("atlas", "info"),
        ("bench", "kinematics"),
        ("bench", "curvature"),
        ("bench", "stability"),
        ("bench", "atlas"),
        ("bench", "faults"),
    } <= set(LEAVES)


# ------------------------------------------------------------------------ the example's world


class World:
    """One example's folder: a small valid atlas, a foreign SQLite file, a text file, …"""

    def __init__(self, folder: Path, atlas: Path, candidate: str, hostile: dict[str, bytes] | None = None):
        self.folder = folder
        self.candidate = candidate
        shutil.copyfile(atlas, folder / "atlas.sqlite")
        for name, data in (hostile or {}).items():  # damaged atlases and side files of other databases
            (folder / name).write_bytes(data)
        (folder / "loop.sqlite").symlink_to(folder / "loop2.sqlite")
        (folder / "loop2.sqlite").symlink_to(folder / "loop.sqlite")
        con = sqlite3.connect(folder / "foreign.sqlite")
        con.execute("create table things(x)")
        con.commit()
        con.close()
        (folder / "notes.txt").write_text("not an atlas\n")
        (folder / "empty.sqlite").write_bytes(b"")
        (folder / "existing.png").write_bytes(b"old")
        (folder / "sub").mkdir()


#: ``--db`` values: the valid atlas, and everything that is not one
DB_VALUES = [
    "atlas.sqlite",
    "new.sqlite",
    "foreign.sqlite",
    "notes.txt",
    "empty.sqlite",
    "sub",
    "none/a.sqlite",
    "",
    ":memory:",
    "sqlite://",
    "nosuchdialect://x/y",
    "postgresql://u@127.0.0.1:1/x",
    "sqlite:///new2.sqlite",
    "/proc/dwell.sqlite",
    "ätlas.sqlite",
    "-",
    "--db",
]
#: What no output may show: the password of the connection strings below.
SECRET = "S3cret"
#: ``--db`` values shaped like connection strings (a libpq key/value string, URLs with a typo
#: in the scheme or none): refused before anything is made, without the password
CONNECTION_STRINGS = [
    f"host=127.0.0.1 port=1 user=u password={SECRET} dbname=db",
    f"dbname=db password='{SECRET} x'",
    f"postgresql:/u:{SECRET}@h/db",
    f"postgres//u:{SECRET}@h/db",
    f"postgresql:u:{SECRET}@h/db",
    f"postgresql+psycopg:/u:{SECRET}@h/db",
    f"u:{SECRET}@h/db",
    f"postgresql;//u:{SECRET}@h/db",
]
#: damaged atlases, and atlases with another database's side file beside them (World)
HOSTILE_ATLASES = [
    "journal.sqlite",
    "wal.sqlite",
    "numeric-kind.sqlite",
    "many-samples.sqlite",
    "no-shard-row.sqlite",
    "paused.sqlite",
]
DB_VALUES += [*CONNECTION_STRINGS, *HOSTILE_ATLASES, "loop.sqlite"]
#: refused by every command that opens an atlas, whatever else the line does (``none/a.sqlite``
#: is not: ``--out none`` makes its folder): ``dwell demo`` gets one of these, never a build
BAD_DB_VALUES = [
    "foreign.sqlite",
    "notes.txt",
    "sub",
    "nosuchdialect://x/y",
    *CONNECTION_STRINGS,
    *HOSTILE_ATLASES,
    "loop.sqlite",
]
PATH_VALUES = [
    "out.png",
    "out.svg",
    "out.html",
    "out.pdf",
    "existing.png",
    "notes.txt",
    "sub",
    "sub/x.svg",
    "none/x.png",
    "",
    ".",
    "/proc/dwell.png",
    "ünïcode.svg",
    "out",
    "sub/deeper/out",
    "-",
]
EDGE_NUMBERS = [
    "0",
    "-0",
    "1",
    "-1",
    "2",
    "0.5",
    "1e-320",
    "1e308",
    "-1e308",
    "1e999",
    "nan",
    "-nan",
    "NaN",
    "inf",
    "-inf",
    "Infinity",
    "9" * 40,
    "2147483648",
    "-2147483649",
    "9223372036854775808",
    "360",
    "-360",
    "720",
    "1e-9",
    "1e150",
    "1e151",
    "1e-150",
    "1e-151",
    "1e50",
    "-1e51",
    "1e100",
    "1e75",
]  # and the CLI's limits
NOT_NUMBERS = [
    "",
    " ",
    "abc",
    "1,5",
    "1.2.3",
    "٣",
    "1_000",
    "0x10",
    "-",
    "½",
    "1e",
    "e5",
    "\u00a0",
    "🙂",
    "None",
    "true",
    "[1]",
]
UNKNOWN = ["--nope", "-x", "--", "--a=1", "--db=", "-h", "--HELP", "--json=1", "---", "--é"]

numbers = (
    st.sampled_from(EDGE_NUMBERS)
    | st.sampled_from(NOT_NUMBERS)
    | st.floats(allow_nan=True).map(repr)
    | st.integers(-(10**6), 10**6).map(str)
)
small_ints = st.sampled_from(["1", "2", "3", "4", "8", "0", "-1", "-5", "1.5", "", "x", "99999999999999999999", "nan"])
texts = st.text(max_size=12) | st.sampled_from(["", "-", "--json", "rpr", "rrr", "any", "demo", "standard", "mm"])


def _lists(items: st.SearchStrategy) -> st.SearchStrategy:
    return st.lists(items, min_size=0, max_size=4).map(",".join)


#: values of text options that carry structure, by option name
STRUCTURED = {
    "--n": _lists(small_ints),
    "--crank-lengths": _lists(numbers),
    "--rpms": _lists(numbers),
    "--tolerances": _lists(st.sampled_from(["1e-4", "1e-3", "0.01", "0.1", "0", "-1", "nan", "x", "2"])),
    "--resolutions": _lists(
        st.tuples(st.sampled_from(["10", "6", "0", "-1", "nan", "x"]), st.sampled_from(["6", "0", "-2", "x", "8"])).map(
            ":".join
        )
    )
    | texts,
    "--cv-bounds": st.tuples(st.sampled_from(["a", "b", "c", "d", "e", ""]), numbers, numbers).map(
        lambda t: f"{t[0]}={t[1]}:{t[2]}"
    )
    | texts,
    "--candidates": st.sampled_from(
        [
            "{candidate}",
            "1-rpr0.0@20",
            "x",
            "",
            "{candidate} {candidate}",
            "99999999999-rrr0.0@30",
            "1-dbl0.9@nan",
            "1-rpr0.0@1e999",
        ]
    )
    | texts,
    "--output": st.sampled_from(["rpr", "rrr", "any", "RPR", "dbl", ""]) | texts,
    "--preset": st.sampled_from(["demo", "standard", "large", "nope", ""]),
    "--db-kind": st.sampled_from(["sqlite", "postgresql", "both", "x"]),
}
#: options whose values set how much work a run does: mostly small, sometimes invalid
SIZES = {
    "--samples",
    "--shard-size",
    "--rays",
    "--workers",
    "--angles",
    "--repeat",
    "--linkages",
    "--batch",
    "--double-ball-linkages",
    "--proportions",
    "--dwell-samples",
    "--build",
    "--ingest",
    "--reference-rays",
    "--top",
    "--trials",
    "--kills",
    "--phases",
    "--configuration",
    "--dwells",
}


def _value(param: click.Parameter, name: str) -> st.SearchStrategy:
    if name == "--db":
        return st.sampled_from(DB_VALUES)
    if name in STRUCTURED:
        return STRUCTURED[name]
    if name in SIZES:
        return small_ints
    kind = param.type
    if isinstance(kind, click.Path | click.File):
        return st.sampled_from(PATH_VALUES)
    if isinstance(kind, click.Choice):
        return st.sampled_from(list(kind.choices)) | texts
    if isinstance(kind, click.types.IntParamType | click.types.FloatParamType):
        return numbers
    return texts


@st.composite
def _option_tokens(draw, command: click.Command) -> list[str]:
    params = [p for p in command.params if isinstance(p, click.Option)]
    choice = draw(st.integers(0, 9))
    if choice == 0 or not params:
        return [draw(st.sampled_from(UNKNOWN) | texts)]
    param = draw(st.sampled_from(params))
    name = draw(st.sampled_from(param.opts + param.secondary_opts))
    if param.is_flag or name in param.secondary_opts:
        return [name]
    return [name, *(draw(_value(param, name)) for _ in range(max(param.nargs, 1)))]


#: four-bar shapes where the closed forms degenerate: a crank-rocker, a change point
#: (s + l = p + q), a parallelogram (the coupler translates), a rhombus (a = b = c = d)
SHAPES = [("1", "3", "2.5", "3"), ("1", "2", "2.5", "3.5"), ("1", "3", "1", "3"), ("2", "2", "2", "2")]
#: a valid line per command (or several): fuzzed options come after it and override it
BASE = {
    ("analyze", "fourbar"): [["--a", a, "--b", b, "--c", c, "--d", d] for a, b, c, d in SHAPES],
    ("analyze", "slider-crank"): ["--crank", "50", "--rod", "150"],
    ("analyze", "shaper"): ["--crank", "60", "--rod", "300", "--link", "150", "--height", "200"],
    ("curvature",): [["--a", a, "--b", b, "--c", c, "--d", d, "--phi", "60"] for a, b, c, d in SHAPES],
    ("atlas", "build"): [
        "--db",
        "built.sqlite",
        "--samples",
        "8",
        "--shard-size",
        "4",
        "--crank-step",
        "10",
        "--rays",
        "8",
        "--workers",
        "1",
        "--no-progress",
    ],
    ("atlas", "info"): ["--db", "atlas.sqlite"],
    ("query",): ["--db", "atlas.sqlite", "--dwell", "40", "--swing", "20", "--dwell-tol", "10", "--swing-tol", "5"],
    ("report",): ["--db", "atlas.sqlite", "--candidates", "{candidate}", "--out", "report"],
    ("bench", "kinematics"): ["--n", "1,10", "--angles", "36", "--repeat", "1"],
    ("bench", "curvature"): [
        "--linkages",
        "5",
        "--angles",
        "10",
        "--rays",
        "6",
        "--repeat",
        "1",
        "--double-ball-linkages",
        "1",
    ],
    ("bench", "stability"): ["--n", "200"],
    ("bench", "atlas"): [
        "--proportions",
        "1",
        "--resolutions",
        "10:6",
        "--reference-step",
        "10",
        "--reference-rays",
        "8",
        "--dwell-samples",
        "1",
    ],
}


@st.composite
def arguments(draw, path: tuple[str, ...]) -> list[str]:
    command = COMMANDS[path]
    base = BASE.get(path, [])
    if base and isinstance(base[0], list):
        base = draw(st.sampled_from(base))
    argv = list(base) if draw(st.integers(0, 4)) else []
    for _ in range(draw(st.sampled_from([0, 1, 1, 1, 2, 2, 3, 4]))):
        argv += draw(_option_tokens(command))
    if argv and draw(st.integers(0, 7)) == 0:
        argv = argv[:-1]  # an option left without its value
    return argv


# ----------------------------------------------------------------------- keeping runs short


def _count(start: float | None, stop: float | None, step: float | None, default_step: float = 30.0) -> float:
    start = 0.0 if start is None else start
    stop = start + 360.0 if stop is None else stop
    step = default_step if step is None else step
    with contextlib.suppress(ArithmeticError, ValueError):
        if step > 0 and stop >= start:
            return (stop - start) / step
    return 0.0  # refused by the command before any work


def _angles_ok(p: dict) -> bool:
    return _count(p.get("phi_from"), p.get("phi_to"), p.get("phi_step")) <= 2000


def _atlas_build_ok(p: dict) -> bool:
    from atlas.sweep import SweepSpecError
    from cli.atlas import parse_range, parse_tolerances, sweep_spec_from_options

    try:
        spec = sweep_spec_from_options(
            p["preset"],
            {
                "samples": p["samples"],
                "seed": p["seed"],
                "b": parse_range(p["b_range"]),
                "c": parse_range(p["c_range"]),
                "d": parse_range(p["d_range"]),
                "crank_step_deg": p["crank_step"],
                "rays": p["rays"],
                "tolerances": parse_tolerances(p["tolerances"]),
                "min_dwell_deg": p["min_dwell"],
                "shard_size": p["shard_size"],
            },
        )
    except SweepSpecError:
        return True  # refused at once
    return (
        p["workers"] == 1
        and spec.samples <= 16
        and spec.crank_step_deg >= 5
        and spec.rays <= 16
        and len(spec.tolerances) <= 4
    )


def _sizes(text: str | None, limit: int) -> bool:
    try:
        return all(int(x) <= limit for x in (text or "").split(",") if x.strip())
    except ValueError:
        return True


def _resolutions_ok(text: str) -> bool:
    try:
        pairs = [(float(s), int(r)) for s, r in (item.split(":") for item in text.split(","))]
    except ValueError:
        return True
    return len(pairs) <= 2 and all(s >= 5 and r <= 12 for s, r in pairs)


#: command → does a run with these parsed options stay small? Commands not listed here are only
#: fuzzed up to their option parser (an unknown option is appended).
AFFORDABLE = {
    ("analyze", "fourbar"): lambda p: _angles_ok(p) and len(p.get("cv_bounds") or {}) <= 2,
    ("analyze", "slider-crank"): _angles_ok,
    ("analyze", "shaper"): _angles_ok,
    ("analyze", "linkage"): lambda p: _count(p.get("x_from"), p.get("x_to"), p.get("x_step")) <= 400,
    ("curvature",): lambda p: p["rays"] <= 500,
    ("atlas", "build"): _atlas_build_ok,
    ("atlas", "info"): lambda p: True,
    ("query",): lambda p: p["report_dir"] is None or p["top"] <= 2,
    ("report",): lambda p: len(p["ids"]) + len(p["more_ids"]) <= 2,
    ("demo",): lambda p: p["target"] in BAD_DB_VALUES,
    ("bench", "kinematics"): lambda p: _sizes(p["sizes"], 100) and p["angles"] <= 360 and p["repeat"] <= 2,
    ("bench", "curvature"): lambda p: (
        p["linkages"] * p["angles"] <= 2000 and p["rays"] <= 50 and p["repeat"] <= 2 and p["n_double"] <= 2
    ),
    ("bench", "stability"): lambda p: p["n_cases"] <= 2000,
    ("bench", "atlas"): lambda p: (
        p["proportions"] <= 2
        and _resolutions_ok(p["resolutions"])
        and p["reference_step"] >= 5
        and p["reference_rays"] <= 12
        and p["dwell_samples"] <= 2
        and (p["build_samples"] <= 8 and p["workers"] == 1 or p["build_samples"] == 0)
    ),
}


def parsed_options(path: tuple[str, ...], argv: list[str]) -> dict | None:
    """The options as the command will see them, or None when parsing refuses them."""
    ctx = None
    with CliRunner().isolation():
        try:
            for depth, name in enumerate(("dwell", *path)):
                command = COMMANDS[path[:depth]]
                ctx = click.Context(command, info_name=name, parent=ctx)
            leaf = COMMANDS[path]
            return leaf.make_context(path[-1], list(argv), parent=ctx.parent).params
        except Exception:  # noqa: BLE001 - refused (or a bug, which the real run shows with its traceback)
            return None


# ------------------------------------------------------------------------------ the contract


FOLDER = b"<folder>"


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file (its sha256), folder and symbolic link (where it points) under ``folder``,
    by relative name."""
    return {
        str(p.relative_to(folder)): (
            b"<link>" + os.readlink(p).encode()
            if p.is_symlink()
            else FOLDER
            if p.is_dir()
            else hashlib.sha256(p.read_bytes()).digest()
        )
        for p in sorted(folder.rglob("*"))
    }


def _strict_json(text: str):
    def refuse(token):
        raise ValueError(f"{token} in JSON output")

    return json.loads(text, parse_constant=refuse)


def _complete(path: Path) -> str | None:
    """Why ``path`` is not a complete file of its kind (None if it is)."""
    data = path.read_bytes()
    suffix = path.suffix.lower()
    if not data:
        return "empty"
    if suffix == ".png":
        return (
            None if data.startswith(b"\x89PNG\r\n\x1a\n") and data.rstrip().endswith(b"IEND\xaeB`\x82") else "cut PNG"
        )
    if suffix == ".svg":
        try:
            ET.fromstring(data)
        except ET.ParseError as exc:
            return f"bad SVG: {exc}"
        return None
    if suffix == ".html":
        return None if data.rstrip().lower().endswith(b"</html>") else "cut HTML"
    if suffix == ".json":
        try:
            _strict_json(data.decode())
        except ValueError as exc:
            return f"bad JSON: {exc}"
        return None
    if suffix == ".dxf":
        return None if data.rstrip().endswith(b"EOF") else "cut DXF"
    if suffix == ".sqlite" or data.startswith(b"SQLite format 3\x00"):
        from db import open_atlas
        from db.summary import atlas_summary

        engine = open_atlas(str(path), readonly=True)
        try:
            build = atlas_summary(engine).build
        finally:
            engine.dispose()
        return None if build is not None and build["status"] == "complete" else f"incomplete atlas: {build}"
    return None


def _side_file(name: str, before: dict[str, bytes], after: dict[str, bytes]) -> bool:
    """SQLite's write-ahead log (empty) and index beside a database file: what any reader of
    a WAL-mode file leaves, not content."""
    for suffix in ("-wal", "-shm"):
        if name.endswith(suffix) and name[: -len(suffix)] in after:
            return suffix == "-shm" or after[name] == hashlib.sha256(b"").digest()
    return False


def run_and_check(world: World, path: tuple[str, ...], argv: list[str]) -> tuple[int, str, str]:
    argv = [a.replace("{candidate}", world.candidate) for a in argv]
    before = snapshot(world.folder)
    runner = CliRunner()
    with runner.isolation() as (out, err, _):
        try:
            rc = main([*path, *argv])
            crash = None
        except BaseException:  # noqa: BLE001 - whatever escapes main is the finding
            rc, crash = None, traceback.format_exc()
    stdout = out.getvalue().decode("utf-8", "replace")
    stderr = err.getvalue().decode("utf-8", "replace")
    shown = f"dwell {' '.join(map(repr, [*path, *argv]))}\nstderr: {stderr[-2000:]}"
    assert crash is None, f"{shown}\n{crash}"
    assert rc in (0, 2) or (rc == 1 and path == ("query",)), f"exit {rc}: {shown}"  # 1: a query found none
    assert SECRET not in stdout + stderr, f"the password is shown: {shown}"
    assert "Traceback" not in stderr, shown
    after = snapshot(world.folder)
    changed = {n for n in after if before.get(n) != after[n] and not _side_file(n, before, after)}
    if rc == 2:
        errors = [line for line in stderr.splitlines() if line.startswith("dwell: error: ")]
        assert len(errors) == 1 and stderr.rstrip("\n").splitlines()[-1] == errors[0], shown
        assert changed == set() and set(before) <= set(after), f"exit 2 but files changed: {changed}: {shown}"
    else:
        assert set(before) <= set(after), f"files removed: {set(before) - set(after)}: {shown}"
        for name in changed - {n for n in after if after[n] == FOLDER}:
            problem = _complete(world.folder / name)
            assert problem is None, f"{name}: {problem}: {shown}"
    return rc, stdout, stderr


# ------------------------------------------------------------------------------------ tests


@pytest.fixture(scope="module")
def small_atlas(tmp_path_factory) -> tuple[Path, str, dict[str, bytes]]:
    """A small complete atlas, the id of a candidate it answers, and the World's hostile files."""
    from atlas import SweepSpec
    from atlas.build import build_atlas
    from cli.query import answer
    from db import open_atlas
    from synth.query.candidates import Request

    path = tmp_path_factory.mktemp("fuzz") / "atlas.sqlite"
    spec = SweepSpec(
        name="fuzz", b=(1.5, 4.5), c=(1.5, 4.5), d=(1.5, 4.5), samples=16, crank_step_deg=3.0, rays=24, shard_size=8
    )
    build_atlas(str(path), spec, workers=1)
    engine = open_atlas(str(path), readonly=True)
    try:
        request = Request.from_degrees(dwell=40.0, dwell_tol=10.0, swing=20.0, swing_tol=5.0, top=1)
        found = answer(engine, request)
    finally:
        engine.dispose()
    for side in ("-wal", "-shm"):
        Path(f"{path}{side}").unlink(missing_ok=True)
    assert found.candidates, "the small atlas must answer the base query"
    return path, found.candidates[0].id, _hostile(path, tmp_path_factory.mktemp("hostile"))


def _hostile(atlas: Path, work: Path) -> dict[str, bytes]:
    """File name → bytes of the World's hostile atlases (:data:`HOSTILE_ATLASES`) and the
    side files of other databases that lie beside two of them."""
    from db.engine import SQLITE_PAGE_SIZE

    other = work / "other.sqlite"
    con = sqlite3.connect(other)
    con.execute(f"PRAGMA page_size={SQLITE_PAGE_SIZE}")
    con.execute("create table t (x)")
    con.executemany("insert into t values (?)", [("x" * 400,)] * 500)
    con.commit()
    con.close()
    # another database's hot journal: its writer killed after changed pages reached the file
    writer = (
        "import os, signal, sqlite3, sys\n"
        "con = sqlite3.connect(sys.argv[1], isolation_level=None)\n"
        "con.execute('PRAGMA cache_size=1'); con.execute('BEGIN'); con.execute('PRAGMA user_version=9')\n"
        "con.execute(\"update t set x = 'y' || x\")\n"
        "os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    assert subprocess.run([sys.executable, "-c", writer, str(other)]).returncode == -9
    journal = Path(f"{other}-journal").read_bytes()
    # another database's write-ahead log with the atlas's page size
    con = sqlite3.connect(other)
    con.execute("PRAGMA journal_mode=WAL")
    con.execute("PRAGMA wal_autocheckpoint=0")
    con.execute("PRAGMA user_version=9")
    con.execute("insert into t values ('z')")
    con.commit()
    wal = Path(f"{other}-wal").read_bytes()
    con.close()

    def spoiled(*statements: str, wal_mode: bool = False) -> bytes:
        copy = work / "copy.sqlite"
        shutil.copyfile(atlas, copy)
        con = sqlite3.connect(copy)
        con.execute("PRAGMA ignore_check_constraints=ON")
        con.execute("PRAGMA writable_schema=ON")
        for sql in statements:
            con.execute(sql)
        con.commit()
        if wal_mode:
            con.execute("PRAGMA journal_mode=WAL")
        con.close()
        data = copy.read_bytes()
        copy.unlink()
        return data

    kind = ("UPDATE sqlite_master SET sql = replace(sql, 'kind VARCHAR(12)', 'kind INTEGER') WHERE name = 'segment'",)
    return {
        "journal.sqlite": atlas.read_bytes(),
        "journal.sqlite-journal": journal,
        "wal.sqlite": spoiled(
            "UPDATE build SET status = 'building', content_digest = NULL",
            "DELETE FROM shard WHERE shard_index = (SELECT max(shard_index) FROM shard)",
            wal_mode=True,
        ),
        "wal.sqlite-wal": wal,
        "numeric-kind.sqlite": _numeric_kind(spoiled(*kind), work),
        "many-samples.sqlite": spoiled("UPDATE build SET spec_json = json_set(spec_json, '$.samples', 'many')"),
        "no-shard-row.sqlite": spoiled("DELETE FROM shard WHERE shard_index = 0"),
        "paused.sqlite": spoiled("UPDATE build SET status = 'paused'"),
    }


def _numeric_kind(data: bytes, work: Path) -> bytes:
    """``data`` (an atlas whose schema declares ``segment.kind`` INTEGER) with one kind stored
    as an integer, then the declaration put back: what a flipped bit of a record header does."""
    path = work / "kind.sqlite"
    path.write_bytes(data)
    con = sqlite3.connect(path)
    con.execute("PRAGMA ignore_check_constraints=ON")
    con.execute("UPDATE segment SET kind = 7 WHERE id = (SELECT min(id) FROM segment)")
    con.commit()
    con.execute("PRAGMA writable_schema=ON")
    con.execute(
        "UPDATE sqlite_master SET sql = replace(sql, 'kind INTEGER', 'kind VARCHAR(12)') WHERE name = 'segment'"
    )
    con.commit()
    con.close()
    data = path.read_bytes()
    path.unlink()
    return data


@contextlib.contextmanager
def world_for(small_atlas):
    with tempfile.TemporaryDirectory(prefix="dwell-fuzz-") as tmp, contextlib.chdir(tmp):
        yield World(Path(tmp), *small_atlas)


#: ``DWELL_FUZZ_SCALE=10`` multiplies every example budget below (a long local hunt)
SCALE = float(os.environ.get("DWELL_FUZZ_SCALE") or 1)
FUZZ = settings(
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture, HealthCheck.filter_too_much],
)
#: examples per command: commands that run for real in an example get fewer
BUDGET = {
    ("atlas", "build"): 25,
    ("query",): 25,
    ("report",): 15,
    ("bench", "kinematics"): 6,
    ("bench", "atlas"): 12,
    ("bench", "curvature"): 20,
    ("analyze", "linkage"): 25,
    ("demo",): 25,
}


@pytest.mark.parametrize("path", LEAVES, ids=" ".join)
def test_random_arguments_exit_0_or_2_and_write_all_or_nothing(path, small_atlas, monkeypatch):
    monkeypatch.delenv("DWELL_ATLAS", raising=False)
    # the kinematics bench times runs of at least 200 000 positions: what is fuzzed here is its
    # exit codes and files, not its timings, which fewer positions per run leave unchanged
    monkeypatch.setattr("cli.bench.kinematics.MIN_POSITIONS_PER_RUN", 2_000)
    budget = round(BUDGET.get(path, 40) * SCALE)

    @settings(FUZZ, max_examples=budget)
    @given(
        argv=arguments(path),
        db=st.sampled_from(BAD_DB_VALUES),
        linkage=st.sampled_from(sorted(EXAMPLES.glob("*.toml"))),
    )
    def fuzz(argv, db, linkage):
        if path == ("demo",):
            argv = [*argv, "--db", db]  # a refused atlas: the demo never builds here
        if path == ("analyze", "linkage"):
            argv = [str(linkage), *argv]
        with world_for(small_atlas) as world:
            affordable = AFFORDABLE.get(path)
            if affordable is None:
                argv = [*argv, "--not-an-option-of-this-command"]
            else:
                params = parsed_options(path, [a.replace("{candidate}", world.candidate) for a in argv])
                assume(params is None or affordable(params))
            rc, out, err = run_and_check(world, path, argv)
            params = parsed_options(path, argv) if rc == 0 else None
            if params and params.get("as_json"):
                _strict_json(out)

    fuzz()


@pytest.mark.parametrize("path", GROUPS, ids=lambda p: " ".join(("dwell", *p)))
def test_random_arguments_to_groups(path, small_atlas):
    command = COMMANDS[path]
    names = sorted(command.list_commands(click.Context(command)))

    @settings(FUZZ, max_examples=round(30 * SCALE))
    @given(
        tokens=st.lists(
            st.sampled_from(names) | st.sampled_from(UNKNOWN) | st.sampled_from(["--version", "--help"]) | texts,
            max_size=3,
        )
    )
    def fuzz(tokens):
        with world_for(small_atlas) as world:
            # whatever subcommand the tokens name stops at its parser: nothing long runs here
            run_and_check(world, path, [*tokens, "--not-an-option-of-this-command"])

    fuzz()


# ------------------------------------------------------------------- what fuzzing has found

FOURBAR = ["--a", "1", "--b", "3", "--c", "2.5", "--d", "3"]
#: lines that gave a traceback or left files behind, with the one error line they give now
#: (None: they now succeed)
FOUND = [
    (
        ["analyze", "slider-crank", "--crank", "1e-150", "--rod", "150"],
        "the slider's stroke is below floating-point resolution (it stops at s = 150 only)",
    ),
    (
        ["analyze", "shaper", "--crank", "1e-150", "--rod", "300", "--link", "150", "--height", "200"],
        "the slider's stroke is below floating-point resolution",
    ),
    (
        ["analyze", "slider-crank", "--crank", "50", "--rod", "150", "--guide-angle", "9223372036854775808"],
        "Invalid value for '--guide-angle': must be -36000 <= x <= 36000",
    ),
    (["bench", "stability", "--n", "200", "--seed", "-2147483649"], "Invalid value for '--seed'"),
    (["bench", "stability", "--n", "1"], None),  # no near-toggle case drawn
    (["bench", "kinematics", "--n", "1", "--seed", "-1"], "Invalid value for '--seed'"),
    (["bench", "curvature", "--linkages", "1", "--seed", "-1"], "Invalid value for '--seed'"),
    (
        ["atlas", "build", "--db", "new.sqlite", "--samples", "4", "--seed", "-1"],
        "Invalid value for '--seed': must be a whole number from 0",
    ),
    (
        [
            "atlas",
            "build",
            "--db",
            "new.sqlite",
            "--samples",
            "4",
            "--tolerances",
            ",".join(f"{0.001 + 0.01 * i:g}" for i in range(40)),
        ],
        "at most 32 tolerances, got 40",
    ),
    (["demo", "--out", "made/here", "--db", "foreign.sqlite"], "is a database of another application"),
    (["demo", "--out", "/proc/dwell-out", "--db", "foreign.sqlite"], "--out: cannot write into '/proc/dwell-out'"),
    (
        ["report", "--db", "atlas.sqlite", "--candidates", "{candidate}", "--out", "/proc/dwell-report"],
        "--out: cannot write into '/proc/dwell-report'",
    ),
    (
        ["query", "--db", "atlas.sqlite", "--dwell", "40", "--swing", "20", "--report", "/proc/dwell-report"],
        "--report: cannot write into '/proc/dwell-report'",
    ),
    (["analyze", "fourbar", *FOURBAR, "--plot", "/proc/dwell.png"], "cannot write '/proc/dwell.png'"),
    (
        ["analyze", "fourbar", *FOURBAR, "--b", "1e308"],
        "Invalid value for '--b': must be 1e-150 <= x <= 1e+150 (a length)",
    ),
    (
        ["analyze", "fourbar", *FOURBAR, "--a", "1e-320", "--d", "1e-320"],
        "Invalid value for '--a': must be 1e-150 <= x",
    ),
    (["curvature", *FOURBAR, "--phi", "10", "--b", "1e200", "--c", "1e200"], "Invalid value for '--b'"),
    (
        ["analyze", "linkage", str(EXAMPLES / "class3_sixbar.toml"), "--rpm", "1e308", "--json"],
        "Invalid value for '--rpm': must be -1e+50 <= x <= 1e+50",
    ),
    (["analyze", "fourbar", *FOURBAR, "--omega", "1e200", "--json"], "Invalid value for '--omega'"),
    (["analyze", "slider-crank", "--crank", "1", "--rod", "3", "--alpha", "-1e300"], "Invalid value for '--alpha'"),
    # a range of a sliver of a degree was taken for a whole turn, and its only angle dropped
    (["analyze", "slider-crank", "--crank", "50", "--rod", "150", "--to", "1e-150"], None),
    (["analyze", "fourbar", *FOURBAR, "--from", "10", "--to", "10.0000000001"], None),
    (["analyze", "linkage", str(EXAMPLES / "fourbar.toml"), "--to", "1e-150"], None),
    # a deviation window shorter than the simulation's crank step held no sample
    (
        ["report", "--db", "atlas.sqlite", "--candidates", "{candidate}", "--out", "report", "--dwell", "1e-9"],
        "--dwell must be at least 1°",
    ),
    (
        ["query", "--db", "atlas.sqlite", "--dwell", "0.3", "--dwell-tol", "50", "--swing", "20"],
        "--dwell must be at least 1°",
    ),
    # the linkage file's assembly configuration was matched at the user's scale: at 1e100 the
    # assembly solver's squares overflowed and no configuration matched (a traceback)
    (["report", "--db", "atlas.sqlite", "--candidates", "{candidate}", "--out", "report", "--crank", "1e100"], None),
    # the rhombus's Ball-point track lies on a line: every piece overlapped every other (40 GB)
    (["curvature", "--a", "1", "--b", "1", "--c", "1", "--d", "1", "--phi", "10", "--double-ball"], None),
    # click's "unexpected extra arguments" echoed a connection string's password as typed
    (
        ["demo", "--", "--db", "host=127.0.0.1 port=1 user=u password=S3cret dbname=db"],
        "Got unexpected extra arguments (--db <a libpq connection string",
    ),
    (
        ["query", "--db", "atlas.sqlite", "--dwell", "40", "--swing", "20", "extra", "postgresql://u:S3cret@h/db"],
        "Got unexpected extra arguments (extra postgresql://u:***@h/db)",
    ),
]


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="uses /proc as a folder nobody can write into")
@pytest.mark.parametrize("argv, message", FOUND, ids=[f"{i}-{'-'.join(a[:2])}" for i, (a, _) in enumerate(FOUND)])
def test_what_fuzzing_found(small_atlas, argv, message):
    with world_for(small_atlas) as world:
        path = next(p for p in sorted(COMMANDS, key=len, reverse=True) if tuple(argv[: len(p)]) == p)
        rc, out, err = run_and_check(world, path, argv[len(path) :])
        if message is None:
            assert rc == 0, err
        else:
            assert rc == 2 and message in err, err


#: mechanism files (an example with one value replaced) that gave a traceback, and the error now
FOUND_FILES = [
    (
        "scotch_yoke.toml",
        "length = 40",
        "length = 1e308",
        "'length' must be a finite number of magnitude at most 1e+150",
    ),
    ("fourbar.toml", "D = [100, 0]", "D = [100, 1e200]", "ground point 'D' y must be a finite number of magnitude"),
    ("fourbar.toml", "length = 50", f"length = {10**400}", "'length' must be a finite number of magnitude"),
]


@pytest.mark.parametrize(
    "example, old, new, message", FOUND_FILES, ids=[f"{i}-{e}" for i, (e, *_) in enumerate(FOUND_FILES)]
)
def test_what_fuzzing_found_in_mechanism_files(small_atlas, example, old, new, message):
    text = (EXAMPLES / example).read_text()
    assert old in text
    with world_for(small_atlas) as world:
        (world.folder / "mech.toml").write_text(text.replace(old, new, 1))
        rc, out, err = run_and_check(world, ("analyze", "linkage"), ["mech.toml"])
        assert rc == 2 and message in err, err


# ------------------------------------------------------------------------- mechanism files

EVIL_TOML = [
    "nan",
    "inf",
    "-inf",
    "0",
    "-1",
    "1e308",
    "1e-320",
    '"x"',
    "[]",
    "{}",
    "true",
    "[1, 2, 3]",
    "[nan, 0]",
    '"🙂"',
    "-0.0",
    "9" * 30,
]
EVIL_JSON = st.recursive(
    st.none() | st.booleans() | st.floats() | st.integers(-(10**20), 10**20) | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner, max_size=3),
    max_leaves=6,
)
_NUMBER = re.compile(r"(?<![\w.\"])-?\d+(\.\d+)?(?![\w.\"])")


@st.composite
def linkage_files(draw) -> tuple[str, bytes]:
    """(file name, bytes): a valid example mutated, truncated, converted to JSON and broken, or noise."""
    example = draw(st.sampled_from(sorted(EXAMPLES.glob("*.toml"))))
    text = example.read_text()
    kind = draw(st.sampled_from(["number", "line", "truncate", "json", "bytes", "text"]))
    if kind == "number":
        spots = list(_NUMBER.finditer(text))
        for _ in range(draw(st.integers(1, 3))):
            m = draw(st.sampled_from(spots))
            text = text[: m.start()] + draw(st.sampled_from(EVIL_TOML)) + text[m.end() :]
            spots = list(_NUMBER.finditer(text)) or spots[:0]
            if not spots:
                break
        return "mech.toml", text.encode()
    if kind == "line":
        lines = text.splitlines()
        i = draw(st.integers(0, len(lines) - 1))
        edit = draw(st.sampled_from(["drop", "twice", "swap"]))
        if edit == "drop":
            del lines[i]
        elif edit == "twice":
            lines.insert(i, lines[i])
        else:
            j = draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
        return "mech.toml", "\n".join(lines).encode()
    if kind == "truncate":
        return "mech.toml", text.encode()[: draw(st.integers(0, len(text.encode())))]
    if kind == "json":
        data = tomllib.loads(text)
        node = data
        keys = []
        while isinstance(node, dict) and node and draw(st.booleans()):
            key = draw(st.sampled_from(sorted(node)))
            keys.append(key)
            if not isinstance(node[key], dict):
                break
            node = node[key]
        if isinstance(node, dict) and node:
            key = draw(st.sampled_from(sorted(node)))
            if draw(st.booleans()):
                node[key] = draw(EVIL_JSON)
            else:
                del node[key]
        name = draw(st.sampled_from(["mech.json", "mech.JSON", "mech.toml"]))
        return name, json.dumps(data).encode()
    if kind == "bytes":
        return draw(st.sampled_from(["mech.toml", "mech.json", "mech"])), draw(st.binary(max_size=200))
    return draw(st.sampled_from(["mech.toml", "mech.json"])), draw(st.text(max_size=200)).encode(
        "utf-8", "surrogatepass"
    )


@settings(FUZZ, max_examples=round(120 * SCALE))
@given(file=linkage_files(), options=st.lists(_option_tokens(COMMANDS[("analyze", "linkage")]), max_size=2))
def test_random_mechanism_files_exit_0_or_2(small_atlas, file, options):
    name, data = file
    argv = [name, *(t for group in options for t in group)]
    with world_for(small_atlas) as world:
        (world.folder / name).write_bytes(data)
        params = parsed_options(("analyze", "linkage"), argv)
        assume(params is None or AFFORDABLE[("analyze", "linkage")](params))
        rc, out, err = run_and_check(world, ("analyze", "linkage"), argv)
        if rc == 0 and params and params.get("as_json"):
            _strict_json(out)


# ------------------------------------------------------------------- a few real processes


DWELL = [sys.executable, "-c", "import sys; from cli.main import main; sys.exit(main())"]


@pytest.mark.parametrize(
    "argv",
    [
        [b"analyze", b"fourbar", b"--a", b"\xff\xfe", b"--b", b"3", b"--c", b"2.5", b"--d", b"3"],  # not UTF-8
        [b"curvature", b"--a", b"1", b"--b", b"3", b"--c", b"2.5", b"--d", b"3", b"--phi", "٣٠".encode()],
        [b"atlas", b"info", b"--db", b"\xff.sqlite"],
    ],
    ids=["non-utf8-value", "arabic-digits", "non-utf8-path"],
)
def test_odd_bytes_in_a_real_process(tmp_path, argv):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("LC_", "PYTHONIOENCODING", "DWELL_ATLAS"))}
    proc = subprocess.run(
        [*map(str.encode, DWELL), *argv], cwd=tmp_path, capture_output=True, timeout=120, env={**env, "LANG": "C"}
    )
    err = proc.stderr.decode("utf-8", "replace")
    assert proc.returncode in (0, 2) and "Traceback" not in err, err
    if proc.returncode == 2:
        assert err.count("\n") == 1 and err.startswith("dwell: error: "), err
    assert list(tmp_path.iterdir()) == []


def test_a_closed_stdout_is_not_a_traceback(tmp_path):
    # `dwell analyze ... | head -1`: the reader goes away while the table is printed
    proc = subprocess.Popen(
        [
            *DWELL,
            "analyze",
            "fourbar",
            "--a",
            "1",
            "--b",
            "3",
            "--c",
            "2.5",
            "--d",
            "3",
            "--from",
            "0",
            "--to",
            "360",
            "--step",
            "0.5",
        ],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    proc.stdout.readline()
    proc.stdout.close()
    err = proc.stderr.read().decode()
    proc.wait(timeout=120)
    assert "Traceback" not in err and "BrokenPipeError" not in err, err
    assert proc.returncode in (0, 1, 2, 141, -13), err  # 141/-13: SIGPIPE, like any Unix tool
