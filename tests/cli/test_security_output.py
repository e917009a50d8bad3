"""No password of a ``--db`` URL is ever printed: every command, every URL form, success and error.

The URLs point at a port nothing listens on (127.0.0.1:1), so a PostgreSQL connection is
refused at once and each command ends in its one-line error; SQLite URLs name a missing file.
"""

from __future__ import annotations

from urllib.parse import quote

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from cli.main import main
from db.engine import display_target, scrub

# No lower-case letters, '.', '*', space or 0-2: no 4-character stretch of the tool's own words,
# of the masked URL ('***') or of 127.0.0.1:1 can be made from these, so a hit is a leak.
ALPHABET = "QXZJKVW3456789@:/#?%&=+!$()~;,"
PASSWORDS = st.text(ALPHABET, min_size=4, max_size=16)
HOST = "127.0.0.1:1/x"


def url_forms(pw: str, tmp: str) -> dict[str, str]:
    enc = quote(pw, safe="")
    return {
        "userinfo, percent-encoded": f"postgresql+psycopg://u:{enc}@{HOST}",
        "userinfo, raw": f"postgresql+psycopg://u:{pw}@{HOST}",
        "bare postgresql scheme": f"postgresql://u:{enc}@{HOST}",
        "?password=, encoded": f"postgresql+psycopg://u@{HOST}?sslmode=disable&password={enc}",
        "?password=, raw": f"postgresql+psycopg://u@{HOST}?password={pw}",
        "?PassWord= upper case": f"postgresql+psycopg://u@{HOST}?PassWord={enc}",
        "?sslpassword=": f"postgresql+psycopg://u:{enc}@{HOST}?sslpassword={enc}",
        "sqlite URL with ?password=": f"sqlite:///{tmp}/no-folder/missing.sqlite?password={enc}",
        # not URLs: refused before anything is made, the message shows what they look like only
        "libpq key/value string": f"host=127.0.0.1 port=1 user=u password={pw} dbname=x",
        "libpq, password first": f"password={pw} host=127.0.0.1",
        "one slash after the scheme": f"postgresql:/u:{enc}@{HOST}",
        "no colon after the scheme": f"postgres//u:{enc}@{HOST}",
        "a colon only after the scheme": f"postgresql+psycopg:u:{enc}@{HOST}",
        "no scheme": f"u:{pw}@{HOST}",
    }


def commands(url: str, tmp: str) -> dict[str, list[str]]:
    return {
        "atlas info": ["atlas", "info", "--db", url],
        "atlas build": ["atlas", "build", "--db", url, "--preset", "demo", "--workers", "1"],
        "query": ["query", "--db", url, "--dwell", "60", "--swing", "30"],
        "report": ["report", "--db", url, "--candidates", "1-rpr0.0@20", "--out", f"{tmp}/r"],
        "bench query": ["bench", "query", "--db", url],
        "demo": ["demo", "--db", url, "--out", f"{tmp}/d"],
        "bench faults": ["bench", "faults", "--trials", "1", "--db-kind", "postgresql", "--postgres", url],
    }


def _leaks(output: str, pw: str) -> list[str]:
    """The ≥4-character pieces of ``pw`` (as written or percent-encoded) found in ``output``."""
    found = []
    for secret in {pw, quote(pw, safe="")}:
        for i in range(len(secret) - 3):
            piece = secret[i : i + 4]
            if piece in output:
                found.append(piece)
    return found


@pytest.mark.parametrize(
    "command", ["atlas info", "atlas build", "query", "report", "bench query", "demo", "bench faults"]
)
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(pw=PASSWORDS)
@example(pw="QQ@XZ@JJ:KK")  # unescaped '@': SQLAlchemy would read the tail as the host name
@example(pw="Q#X?Z/J:K&V=W")
@example(pw="@3333")  # bench faults: its own engine took the tail for the host (found by hypothesis)
@example(pw="&3333=3")  # the driver names the option a raw "&" makes (found by hypothesis)
@example(pw="&+3333=3")  # ... after decoding "+" (found by hypothesis)
@example(pw="3://")  # a libpq string whose password holds "://" was taken for a URL (found by hypothesis)
def test_no_output_line_contains_the_password(capsys, tmp_path, command, pw):
    tmp = str(tmp_path)
    for form, url in url_forms(pw, tmp).items():
        code = main(commands(url, tmp)[command])
        out, err = capsys.readouterr()
        assert code == 2, (form, out, err)
        assert len(err.strip().splitlines()) == 1, (form, err)
        assert not _leaks(out + err, pw), (form, out + err)


def _db_commands() -> dict[str, list[str]]:
    """Every command of ``dwell`` that takes ``--db`` (found by walking the click group, lazy
    groups included), with the options it needs to get past its parser."""
    import click

    from cli.main import dwell

    found: dict[str, list[str]] = {}

    def walk(command: click.Command, path: tuple[str, ...]) -> None:
        if isinstance(command, click.Group):
            ctx = click.Context(command)
            for name in command.list_commands(ctx):
                walk(command.get_command(ctx, name), (*path, name))
        elif any("--db" in p.opts for p in command.params if isinstance(p, click.Option)):
            found[" ".join(path)] = list(path)

    walk(dwell, ())
    return found


#: what each --db command needs besides --db to reach the atlas
_NEEDS = {
    "query": ["--dwell", "60", "--swing", "30"],
    "report": ["--candidates", "1-rpr0.1@20", "--out", "{tmp}/r"],
    "demo": ["--out", "{tmp}/d"],
    "atlas build": ["--samples", "8", "--workers", "1"],
}
SHAPES = [
    f"host=127.0.0.1 port=1 user=u password={'S3cret'} dbname=db",
    "dbname=db password='S3cret x'",
    "postgresql:/u:S3cret@h/db",
    "postgres//u:S3cret@h/db",
    "postgresql:u:S3cret@h/db",
    "postgresql+psycopg:/u:S3cret@h/db",
    "postgresql;//u:S3cret@h/db",
    "u:S3cret@h/db",
    "./u:S3cret@h/db",
]


@pytest.mark.parametrize("command", sorted(_db_commands()))
def test_connection_string_shapes_are_refused_by_every_db_command(capsys, tmp_path, monkeypatch, command):
    """A libpq key/value string or a URL with a typo in its scheme is one line, exit 2, that
    shows no password — and nothing is made (it would be an SQLite file named after it)."""
    assert {"atlas build", "atlas info", "query", "report", "demo", "bench query"} <= set(_db_commands())
    monkeypatch.chdir(tmp_path)
    for shape in SHAPES:
        argv = [
            *_db_commands()[command],
            "--db",
            shape,
            *(a.replace("{tmp}", str(tmp_path)) for a in _NEEDS.get(command, [])),
        ]
        code = main(argv)
        out, err = capsys.readouterr()
        assert code == 2 and len(err.strip().splitlines()) == 1, (shape, out, err)
        assert "S3cret" not in out + err, (shape, out + err)
        assert "not a database path or URL" in err, (shape, err)
        assert list(tmp_path.iterdir()) == [], (shape, list(tmp_path.iterdir()))
    # the same shapes as bench faults' --postgres
    for shape in SHAPES:
        code = main(["bench", "faults", "--trials", "1", "--db-kind", "postgresql", "--postgres", shape])
        out, err = capsys.readouterr()
        assert code == 2 and "S3cret" not in out + err and len(err.strip().splitlines()) == 1, (shape, err)


def test_an_option_after_a_query_password_is_named_in_the_drivers_message(capsys):
    pytest.importorskip("psycopg")
    code = main(["atlas", "info", "--db", "postgresql://u@127.0.0.1:1/db?password=S3cret&connect_timeout=abc"])
    _, err = capsys.readouterr()
    assert code == 2 and "S3cret" not in err and "connect_timeout" in err, err


@pytest.mark.parametrize(
    ("url", "shown"),
    [
        ("host=h password=S3cret dbname=db", "<a libpq connection string (keys host, password, dbname)>"),
        ("postgresql:/u:S3cret@h/db", "<a URL missing '://' after its scheme 'postgresql'>"),
        ("u:S3cret@h/db", "<a URL without its scheme (user:password@host…)>"),
        ("out//atlas.sqlite", "out//atlas.sqlite"),
        ("postgres/atlas.sqlite", "postgres/atlas.sqlite"),
        ("postgresql+psycopg://u:s3cr@t@h:5/db", "postgresql+psycopg://u:***@h:5/db"),
        ("postgresql+psycopg://u:a/b#c@h/db", "postgresql+psycopg://u:***@h/db"),
        ("postgresql+psycopg://u:a/b#c?d@h/db", "postgresql+psycopg://…"),  # or a query password with "@"?
        ("postgresql://h/db?sslmode=require&password=abc&x=1", "postgresql://h/db?sslmode=require&password=***"),
        ("postgresql://h/db?SSLPASSWORD=abc", "postgresql://h/db?SSLPASSWORD=***"),
        ("postgresql://h/db?passfile=/home/u/.pgpass", "postgresql://h/db?passfile=***"),
        ("postgresql://h/db?password=a%26b", "postgresql://h/db?password=***"),
        ("postgresql://u:secret/db", "postgresql://…"),  # no '@': not host:port, show no more
        ("postgresql://u@h/db", "postgresql://u@h/db"),
        ("postgresql://[::1]:5432/db", "postgresql://[::1]:5432/db"),
        ("atlas.sqlite", "atlas.sqlite"),
    ],
)
def test_display_target(url, shown):
    assert display_target(url) == shown


def test_scrub_removes_raw_and_decoded_secrets():
    url = "postgresql://u:p%40ssw0rd@h/db?password=tok%26en&x=1"
    assert scrub("bad p@ssw0rd and p%40ssw0rd, tok&en", url) == "bad *** and ***, ***"


# ---------------------------------------------------------------------------------------------
# Report folders: whole or not at all, also under SIGKILL
# ---------------------------------------------------------------------------------------------

import hashlib  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import random  # noqa: E402
import shutil  # noqa: E402
import signal  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

DWELL = [str(Path(sys.executable).with_name("dwell"))]


@pytest.fixture(scope="module")
def small_atlas(tmp_path_factory) -> tuple[str, list[str]]:
    """A small demo-settings atlas and two candidate ids from it."""
    from atlas.build import build_atlas
    from atlas.sweep import PRESETS

    path = str(tmp_path_factory.mktemp("atlas") / "small.sqlite")
    build_atlas(path, PRESETS["demo"].replace(samples=256), workers=1)
    out = subprocess.run(
        [*DWELL, "query", "--db", path, "--dwell", "45", "--swing", "40", "--output", "rpr", "--top", "2", "--json"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return path, [c["id"] for c in json.loads(out)["candidates"]]


def _digest(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


@pytest.mark.parametrize("crank", ["1e-320", "0", "-1", "inf", "nan", "1e200"])
def test_report_crank_out_of_range_is_one_line(capsys, tmp_path, crank):
    code = main(
        [
            "report",
            "--db",
            str(tmp_path / "none.sqlite"),
            "--candidates",
            "x",
            "--crank",
            crank,
            "--out",
            str(tmp_path / "r"),
        ]
    )
    out, err = capsys.readouterr()
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--crank" in err, err
    assert not (tmp_path / "r").exists()


def test_report_whose_linkage_file_could_not_be_read_back_is_refused(capsys, tmp_path, small_atlas):
    """`--crank 1e150` is in range, but the six-bar's other links are longer: the report wrote
    a linkage file (coordinates ~3e150) that `dwell analyze linkage` refuses. Now the report is
    refused in one line and writes nothing; a crank that fits writes a file that reads back."""
    path, ids = small_atlas
    code = main(["report", "--db", path, "--candidates", ids[0], "--crank", "1e150", "--out", str(tmp_path / "r")])
    out, err = capsys.readouterr()
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--crank" in err and "1e+150" in err, err
    assert not (tmp_path / "r").exists()
    assert main(["report", "--db", path, "--candidates", ids[0], "--crank", "1e140", "--out", str(tmp_path / "s")]) == 0
    capsys.readouterr()
    (toml,) = (tmp_path / "s").glob("*.toml")
    assert main(["analyze", "linkage", str(toml), "--json"]) == 0, capsys.readouterr().err
    capsys.readouterr()
    # `dwell query --report` likewise, before it shows anything
    code = main(
        [
            "query",
            "--db",
            path,
            "--dwell",
            "45",
            "--swing",
            "40",
            "--output",
            "rpr",
            "--top",
            "2",
            "--no-refine",
            "--crank",
            "1e150",
            "--report",
            str(tmp_path / "q"),
        ]
    )
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and "--crank" in err, err
    assert not (tmp_path / "q").exists()


def test_report_into_a_folder_with_other_files_is_refused(capsys, tmp_path, small_atlas):
    path, ids = small_atlas
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("mine")
    code = main(["report", "--db", path, "--candidates", ids[0], "--out", str(out)])
    _, err = capsys.readouterr()
    assert code == 2 and "thesis.tex" in err and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in out.iterdir()) == ["thesis.tex"]


def test_query_report_into_a_folder_with_other_files_is_refused_before_the_query(capsys, tmp_path, small_atlas):
    path, _ = small_atlas
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("mine")
    code = main(["query", "--db", path, "--dwell", "45", "--swing", "40", "--output", "rpr", "--report", str(out)])
    stdout, err = capsys.readouterr()
    assert code == 2 and "thesis.tex" in err and "--report" in err and len(err.strip().splitlines()) == 1
    assert stdout == ""  # refused before the query ran: no table printed
    assert sorted(p.name for p in out.iterdir()) == ["thesis.tex"]


def test_demo_refuses_a_report_folder_of_the_users_before_building(capsys, tmp_path):
    out = tmp_path / "dwell-out"
    (out / "rpr").mkdir(parents=True)
    (out / "rpr" / "notes.txt").write_text("mine")
    code = main(["demo", "--out", str(out)])
    stdout, err = capsys.readouterr()
    assert code == 2 and "notes.txt" in err and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in out.rglob("*")) == ["notes.txt", "rpr"]  # no atlas built, nothing else made


def test_killed_report_leaves_the_old_or_the_new_report(tmp_path, small_atlas):
    """SIGKILL at a random moment of `dwell report` over an existing report: the folder is
    always byte-identical to the old complete report or to the new complete one."""
    path, ids = small_atlas
    out = tmp_path / "rep"

    def report(args, target):
        return [*DWELL, "report", "--db", path, "--out", str(target), *args]

    old_args, new_args = ["--candidates", ids[0]], ["--candidates", *ids, "--band", "0.2"]
    subprocess.run(report(new_args, tmp_path / "reference"), check=True, capture_output=True)
    new = _digest(tmp_path / "reference")
    t0 = time.perf_counter()
    subprocess.run(report(old_args, out), check=True, capture_output=True)
    full = time.perf_counter() - t0
    old = _digest(out)
    pristine = tmp_path / "old"
    shutil.copytree(out, pristine)
    rng = random.Random(17)
    outcomes = {"old": 0, "new": 0}
    for _ in range(int(os.environ.get("DWELL_KILL_TRIALS", "4"))):
        # back to the old report: its copy (what a kill left beside the folder stays, as after a crash)
        shutil.rmtree(out)
        shutil.copytree(pristine, out)
        proc = subprocess.Popen(report(new_args, out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(rng.uniform(0.3, 1.3) * full)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        now = _digest(out)
        # plots carry their creation date, so a report is recognised by its names and the
        # bytes of its data files (JSON, CSV, README, the page)
        kind = next(
            (
                k
                for k, ref in (("old", old), ("new", new))
                if set(now) == set(ref)
                and all(now[name] == ref[name] for name in now if name.endswith((".json", ".csv", ".txt", ".html")))
            ),
            None,
        )
        assert kind is not None, ("neither the old nor the new report", sorted(now))
        assert all((out / name).stat().st_size > 0 for name in now)
        outcomes[kind] += 1
    assert sum(outcomes.values()) == int(os.environ.get("DWELL_KILL_TRIALS", "4")), outcomes
    print("kill trials:", outcomes)


@pytest.mark.parametrize("command", ["report", "query"])
def test_disk_full_is_one_line_and_keeps_the_old_report(capsys, tmp_path, small_atlas, monkeypatch, command):
    import errno

    path, ids = small_atlas
    out = tmp_path / "rep"
    args = {
        "report": ["report", "--db", path, "--candidates", ids[0], "--out", str(out)],
        "query": [
            "query",
            "--db",
            path,
            "--dwell",
            "45",
            "--swing",
            "40",
            "--output",
            "rpr",
            "--top",
            "1",
            "--report",
            str(out),
        ],
    }[command]
    assert main(args) == 0
    capsys.readouterr()
    before = _digest(out)
    real = Path.write_text

    def full(self, *a, **k):
        if self.name == "index.html":
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, *a, **k)

    monkeypatch.setattr(Path, "write_text", full)
    code = main(args)
    _, err = capsys.readouterr()
    assert code == 2 and len(err.strip().splitlines()) == 1 and "No space left on device" in err, err
    assert _digest(out) == before and sorted(p.name for p in tmp_path.iterdir()) == ["rep"]
