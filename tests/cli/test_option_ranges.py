"""Every numeric option of every command against the value classes of issue 17: subnormals,
±0, −1, ±1e308, inf/nan text, a 400-digit integer and the empty string.

Exhaustive, not sampled: each (command, option, value) is run in-process on top of the
command's valid base line (``test_fuzz.BASE``), with the fuzz tests' contract
(``test_fuzz.run_and_check``): exit 0 or 2, no traceback, one ``dwell: error:`` line on exit 2
and the folder byte-identical after it; complete files after exit 0. Where the parsed line
would be a long run (``test_fuzz.AFFORDABLE``) only the option parser is run, which must refuse
or accept without an exception other than click's usage errors. The tally is printed.

Numeric options are found by walking the click tree (``test_fuzz.COMMANDS``): every option
whose type is a float or int (ranges included) and the list options that carry numbers.
"""

from __future__ import annotations

import click
import pytest
from test_fuzz import AFFORDABLE, BASE, COMMANDS, EXAMPLES, parsed_options, run_and_check, small_atlas, world_for  # noqa: F401

#: The value classes of issue 17.
VALUES = ["5e-324", "1e-320", "0", "-0", "-1", "1e308", "-1e308", "inf", "-inf", "nan", "9" * 400, ""]
#: Refused by every option, whatever its range (a subnormal float has lost its precision).
SUBNORMALS = ("5e-324", "1e-320")
#: Text options that hold numbers, and how a value is placed in them.
NUMBER_LISTS = {
    "--n": "1,{v}",
    "--crank-lengths": "1,{v}",
    "--rpms": "{v}",
    "--tolerances": "0.001,{v}",
    "--resolutions": "{v}:6",
    "--cv-bounds": "a={v}:2",
}
#: The analyze commands' list options act only with --stats.
NEEDS = {"--crank-lengths": ["--stats"], "--rpms": ["--stats"], "--cv-bounds": ["--stats"]}


def _numeric(param: click.Parameter) -> bool:
    kind = param.type
    return isinstance(kind, click.types.FloatParamType | click.types.IntParamType) or param.opts[0] in NUMBER_LISTS


CASES = [
    (path, param)
    for path, command in COMMANDS.items()
    if not isinstance(command, click.Group)
    for param in command.params
    if isinstance(param, click.Option) and not param.is_flag and _numeric(param)
]


def test_every_numeric_option_is_found():
    names = {(" ".join(path), param.opts[0]) for path, param in CASES}
    assert {
        ("query", "--crank"),
        ("report", "--crank"),
        ("analyze fourbar", "--step"),
        ("analyze linkage", "--from"),
        ("atlas build", "--crank-step"),
        ("atlas build", "--samples"),
        ("bench atlas", "--reference-step"),
        ("bench atlas", "--resolutions"),
        ("bench kinematics", "--n"),
        ("bench curvature", "--rays"),
        ("bench query", "--repeat"),
        ("query", "--min-transmission"),
        ("curvature", "--phi"),
    } <= names
    assert len(CASES) >= 90


#: Base lines for commands the fuzz tests give none (their argument is a file).
FILES = {("analyze", "linkage"): [str(EXAMPLES / "fourbar.toml")]}


def _argv(path, param, value: str) -> list[str]:
    base = BASE.get(path, FILES.get(path, []))
    if base and isinstance(base[0], list):
        base = base[0]
    name = param.opts[0]
    text = NUMBER_LISTS.get(name, "{v}").format(v=value)
    return [*base, *NEEDS.get(name, []), name, *([text] * max(param.nargs, 1))]


@pytest.mark.parametrize("path", sorted({path for path, _ in CASES}), ids=" ".join)
def test_hostile_values_of_every_numeric_option(small_atlas, path, capsys):  # noqa: F811 - the fixture
    tally = {"run": 0, "exit 2": 0, "parser only": 0}
    for p, param in CASES:
        if p != path:
            continue
        for value in VALUES:
            argv = _argv(path, param, value)
            parsed = parsed_options(path, [a.replace("{candidate}", "1-rpr0.0@20") for a in argv])
            affordable = AFFORDABLE.get(path)
            subnormal = value in SUBNORMALS
            if parsed is not None and (affordable is None or not affordable(parsed)):
                # (a list option is text to the parser: the command checks its numbers)
                assert not subnormal or param.opts[0] in NUMBER_LISTS, (
                    path,
                    param.opts[0],
                    value,
                    "a subnormal passed the parser",
                )
                tally["parser only"] += 1  # accepted by the parser, too long to run here
                continue
            with world_for(small_atlas) as world:
                rc, _, _ = run_and_check(world, path, argv)
            assert rc == 2 or not subnormal, (path, param.opts[0], value, "a subnormal was accepted")
            tally["run"] += 1
            tally["exit 2"] += rc == 2
    with capsys.disabled():
        print(f"\n{' '.join(path)}: {tally}")
    assert tally["run"] + tally["parser only"] > 0


def test_request_errors_name_the_options():
    """A request's field names (in backticks) become the options that set them, one line, exit 2."""
    from cli.errors import InputError
    from cli.options import flag_names, request_errors
    from synth.query.candidates import Request

    assert (
        flag_names("`step` 50 is more than `swing` 30 (± `swing_tol`)")
        == "--step 50 is more than --swing 30 (± --swing-tol)"
    )
    with pytest.raises(InputError, match=r"^--min-transmission must be in \[0, 90\) degrees, got 95$"):
        with request_errors():
            Request.from_degrees(dwell=60.0, swing=30.0, min_transmission=95.0)


@pytest.mark.parametrize(
    "path, argv",
    [
        # found by a random-seed run of test_fuzz: the pool's call queue overflowed a C int
        (
            ("query",),
            [
                "--db",
                "atlas.sqlite",
                "--dwell",
                "40",
                "--swing",
                "20",
                "--dwell-tol",
                "10",
                "--swing-tol",
                "5",
                "--complete",
                "--workers",
                "99999999999999999999",
            ],
        ),
        (("atlas", "build"), ["--db", "new.sqlite", "--preset", "demo", "--workers", "257"]),
    ],
)
def test_more_workers_than_a_pool_takes_is_bad_input(small_atlas, path, argv):  # noqa: F811 - the fixture
    """``--workers`` beyond atlas.pool.MAX_WORKERS: one line naming the option, exit 2,
    nothing written (no traceback from the pool)."""
    with world_for(small_atlas) as world:
        rc, _, err = run_and_check(world, path, argv)
    assert rc == 2
    assert "--workers" in err and "256" in err
