"""``dwell analyze fourbar ... --stats``: the four-bar as a pulsating-transmission stage.

Statistics of the output angular velocity over a turn (mean, variance, coefficient of
variation, transmission-ratio extremes) for every crank length × input speed, as a table, JSON
and a plot, and the link lengths within bounds that minimise the coefficient of variation
(:mod:`kinematics.fourbar_stats`). ``cli/analyze/fourbar.py`` applies :func:`stats_options`
and hands over to :func:`run_stats` when ``--stats`` is given.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import click
import numpy as np

from cli.options import LENGTH, RPM
from kinematics.fourbar import check_lengths
from kinematics.fourbar_stats import CLUTCHES, minimise_cv, output_speed_stats
from kinematics.status import Status
from report.motion_table import Column, MotionTable

__all__ = ["run_stats", "stats_options"]


#: Most values of --crank-lengths and of --rpms: the table has one row per pair of them.
MAX_LIST = 1000


def _list_of(kind) -> Callable:
    """Callback: ``"1,2.5,4"`` → [1.0, 2.5, 4.0], each value checked as ``kind`` (a
    :class:`cli.options.Bounded`: its range), at most :data:`MAX_LIST` of them."""

    def check(ctx: click.Context, param: click.Parameter, value: str | None) -> list[float] | None:
        if value is None:
            return None
        items = [x for x in value.split(",") if x.strip()]
        if not items:
            raise click.BadParameter(f"expected comma-separated numbers, got {value!r}", ctx, param)
        if len(items) > MAX_LIST:
            raise click.BadParameter(f"at most {MAX_LIST} values, got {len(items)}", ctx, param)
        return [kind.convert(x, param, ctx) for x in items]

    return check


def _bounds(ctx: click.Context, param: click.Parameter, value: tuple[str, ...]) -> dict[str, tuple[float, float]]:
    """Callback: ``("a=10:30", "c=40:90")`` → {"a": (10, 30), "c": (40, 90)}."""
    out = {}
    for item in value:
        name, _, rng = item.partition("=")
        lo, _, hi = rng.partition(":")
        if name not in ("a", "b", "c", "d"):
            raise click.BadParameter(f"{name!r} is not a link length (use a, b, c or d)", ctx, param)
        if not _:
            raise click.BadParameter(f"expected NAME=LOW:HIGH (e.g. a=10:30), got {item!r}", ctx, param)
        pair = (LENGTH.convert(lo, param, ctx), LENGTH.convert(hi, param, ctx))
        if not pair[0] <= pair[1]:
            raise click.BadParameter(f"bounds must satisfy LOW <= HIGH, got {item!r}", ctx, param)
        out[name] = pair
    return out


def stats_options(f: Callable) -> Callable:
    """Add ``--stats``, ``--crank-lengths``, ``--rpms``, ``--phases``, ``--clutch``, ``--cv-bounds``."""
    options = [
        click.option(
            "--stats",
            is_flag=True,
            help="Output-speed statistics over a turn (pulsating-transmission stage) instead of the motion table.",
        ),
        click.option(
            "--crank-lengths",
            callback=_list_of(LENGTH),
            metavar="L1,L2,..",
            help="With --stats: crank lengths to compare (default --a).",
        ),
        click.option(
            "--rpms",
            callback=_list_of(RPM),
            metavar="N1,N2,..",
            help="With --stats: input speeds [rev/min] to compare (default --rpm, or 60).",
        ),
        click.option(
            "--phases",
            type=click.IntRange(min=1, max=12),
            default=1,
            show_default=True,
            help="With --stats: identical stages driven 360/N deg apart onto one output.",
        ),
        click.option(
            "--clutch",
            type=click.Choice(CLUTCHES),
            default="freewheel",
            show_default=True,
            help="With --stats: a one-way clutch passes the forward strokes (freewheel), or none.",
        ),
        click.option(
            "--cv-bounds",
            multiple=True,
            callback=_bounds,
            metavar="NAME=LOW:HIGH",
            help="With --stats: bounds of a link length (a, b, c, d) for the minimum coefficient of "
            "variation; repeat for several (default a between the --crank-lengths).",
        ),
    ]
    for option in reversed(options):
        f = option(f)
    return f


def run_stats(
    a,
    b,
    c,
    d,
    branch,
    stats,
    crank_lengths,
    rpms,
    as_json,
    plot,
    *,
    rpm=None,
    phases=1,
    clutch="freewheel",
    cv_bounds=None,
    units="mm",
) -> None:
    """Print the statistics table (or JSON), the minimum-c_v link lengths, and write the plot."""
    if not stats:
        return
    check_lengths(a=a, b=b, c=c, d=d)
    lengths = list(crank_lengths) if crank_lengths else [a]
    speeds = list(rpms) if rpms else [rpm if rpm is not None else 60.0]
    st = output_speed_stats(lengths, b, c, d, speeds, branch, phases=phases, clutch=clutch)
    bounds = dict(cv_bounds or {})
    if not bounds and len(lengths) > 1:
        bounds = {"a": (min(lengths), max(lengths))}
    best = (
        minimise_cv({"a": a, "b": b, "c": c, "d": d}, bounds, branch, phases=phases, clutch=clutch) if bounds else None
    )

    bad = (st.status & Status.NOT_ASSEMBLABLE) != 0
    shown = lambda v: np.where(bad, np.nan, v).ravel()  # noqa: E731 - display only: "-" / null
    cv_shown = np.where((st.status & Status.AT_INFINITY) != 0, np.nan, st.cv)
    table = MotionTable(
        {
            "type": "fourbar-stats",
            "b": b,
            "c": c,
            "d": d,
            "branch": branch,
            "phases": phases,
            "clutch": clutch,
            "length_unit": units,
        },
        [
            Column("crank", units, st.crank_length.ravel(), "crank length"),
            Column("n_in", "rpm", st.rpm.ravel(), "input speed"),
            Column("mean_out", "rad/s", shown(st.mean), "mean output speed"),
            Column("mean_out", "rpm", shown(st.mean * 30 / np.pi), "mean output speed"),
            Column("std_out", "rad/s", shown(st.std), "standard deviation of the output speed"),
            Column("variance_out", "rad^2/s^2", shown(st.variance), "variance of the output speed"),
            Column("cv", "", shown(cv_shown), "coefficient of variation"),
            Column("ratio_min", "", shown(st.ratio_min), "smallest transmission ratio"),
            Column("ratio_max", "", shown(st.ratio_max), "largest transmission ratio"),
        ],
        _summary(st, bounds, best),
    )
    if as_json:
        doc = table.to_json()
        doc = {"mechanism": doc["mechanism"], "stats": doc["positions"], "summary": doc["summary"]}
        click.echo(json.dumps(doc, indent=1, allow_nan=False))
    else:
        click.echo(
            f"Four-bar output-speed statistics: b={b:g} c={c:g} d={d:g} branch {branch:+d}, "
            f"{phases} stage(s), clutch {clutch}"
        )
        click.echo("")
        click.echo(table.to_text())
        click.echo("")
        for key, value in table.summary.items():
            click.echo(f"{key}: {value}")
    if plot is not None:
        _plot(st, Path(plot), units, best)
        click.echo(f"wrote {plot}", err=True)


def _summary(st, bounds: dict, best) -> dict:
    summary: dict = {
        "definition": "output speed over one turn at constant input speed; cv = std/mean (independent of rpm); "
        "ratio = rocker/crank angular velocity before the clutch",
    }
    cannot = sorted({float(x) for x, s in zip(st.crank_length[:, 0], st.status[:, 0]) if s & Status.NOT_ASSEMBLABLE})
    if cannot:
        summary["crank_lengths_without_full_turn"] = cannot
    if best is not None:
        summary["cv_minimum"] = {
            "bounds": {k: list(v) for k, v in bounds.items()},
            "a": best.a,
            "b": best.b,
            "c": best.c,
            "d": best.d,
            "cv": best.cv,
            "mean_ratio": best.mean_ratio,
            "evaluations": best.evaluations,
        }
    else:
        summary["cv_minimum"] = "give several --crank-lengths or --cv-bounds to minimise the coefficient of variation"
    return summary


def _plot(st, path: Path, units: str, best) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = (st.status[:, 0] & Status.NOT_ASSEMBLABLE) == 0
    L = st.crank_length[:, 0]
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7.5, 7.5))
    for j, n in enumerate(st.rpm[0]):
        axes[0].plot(L[ok], st.mean[ok, j] * 30 / np.pi, "o-", lw=1.4, ms=3, label=f"{n:g} rpm in")
    axes[0].set_ylabel("mean output speed [rpm]", fontsize=9)
    axes[0].legend(fontsize=8)
    cv_ok = ok & ((st.status[:, 0] & Status.AT_INFINITY) == 0)
    axes[1].plot(L[cv_ok], st.cv[cv_ok, 0], "o-", lw=1.4, ms=3, color="tab:red")
    if best is not None:
        axes[1].axhline(best.cv, color="0.5", lw=0.8, ls="--", label=f"minimum {best.cv:.4g} at a={best.a:.4g}")
        axes[1].legend(fontsize=8)
    axes[1].set_ylabel("coefficient of variation", fontsize=9)
    axes[2].plot(L[ok], st.ratio_max[ok, 0], "o-", lw=1.4, ms=3, label="largest")
    axes[2].plot(L[ok], st.ratio_min[ok, 0], "o-", lw=1.4, ms=3, label="smallest")
    axes[2].set_ylabel("transmission ratio", fontsize=9)
    axes[2].legend(fontsize=8)
    axes[2].set_xlabel(f"crank length [{units}]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[0].set_title("Four-bar as a pulsating-transmission stage", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
