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
    }


def commands(url: str, tmp: str) -> dict[str, list[str]]:
    return {
        "atlas info": ["atlas", "info", "--db", url],
        "atlas build": ["atlas", "build", "--db", url, "--preset", "demo", "--workers", "1"],
        "query": ["query", "--db", url, "--dwell", "60", "--swing", "30"],
        "report": ["report", "--db", url, "--candidates", "x", "--out", f"{tmp}/r"],
        "bench query": ["bench", "query", "--db", url],
        "demo": ["demo", "--db", url, "--out", f"{tmp}/d"],
    }


def _leaks(output: str, pw: str) -> list[str]:
    """The ≥4-character pieces of ``pw`` (as written or percent-encoded) found in ``output``."""
    found = []
    for secret in {pw, quote(pw, safe="")}:
        for i in range(len(secret) - 3):
            piece = secret[i:i + 4]
            if piece in output:
                found.append(piece)
    return found


@pytest.mark.parametrize("command", ["atlas info", "atlas build", "query", "report", "bench query", "demo"])
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(pw=PASSWORDS)
@example(pw="QQ@XZ@JJ:KK")  # unescaped '@': SQLAlchemy would read the tail as the host name
@example(pw="Q#X?Z/J:K&V=W")
def test_no_output_line_contains_the_password(capsys, tmp_path, command, pw):
    tmp = str(tmp_path)
    for form, url in url_forms(pw, tmp).items():
        code = main(commands(url, tmp)[command])
        out, err = capsys.readouterr()
        assert code == 2, (form, out, err)
        assert len(err.strip().splitlines()) == 1, (form, err)
        assert not _leaks(out + err, pw), (form, out + err)


@pytest.mark.parametrize(("url", "shown"), [
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
])
def test_display_target(url, shown):
    assert display_target(url) == shown


def test_scrub_removes_raw_and_decoded_secrets():
    url = "postgresql://u:p%40ssw0rd@h/db?password=tok%26en&x=1"
    assert scrub("bad p@ssw0rd and p%40ssw0rd, tok&en", url) == "bad *** and ***, ***"
