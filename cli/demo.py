"""``dwell demo``: the main job on the embedded defaults.

Until the atlas exists, the demo analyses a crank-rocker four-bar and the quick-return
shaper: it prints their tables and writes JSON, motion diagrams and drawings.
"""

from __future__ import annotations

import contextlib
import io
import time
from pathlib import Path

import click

#: The demo's mechanisms, as the ``dwell`` arguments a user would type.
DEMO_ANALYSES = {
    "fourbar": ["analyze", "fourbar", "--a", "1", "--b", "3", "--c", "2.5", "--d", "3", "--point", "1.2", "0.8"],
    "shaper": ["analyze", "shaper", "--crank", "60", "--rod", "300", "--link", "150", "--height", "200", "--offset", "30"],
}


@click.command("demo")
@click.option("--out", "out_dir", default="dwell-out", show_default=True, type=click.Path(file_okay=False),
              help="Folder for the tables, JSON, plots and drawings.")
def demo(out_dir: str) -> None:
    """Analyse a crank-rocker four-bar and a quick-return shaper; write tables and plots."""
    from cli.main import main as run_dwell

    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise click.BadParameter(f"{out_dir!r} exists and is not a folder", param_hint="--out")
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    for name, args in DEMO_ANALYSES.items():
        click.echo(f"\n$ dwell {' '.join(args)}")
        files = ["--plot", str(out / f"{name}_motion.png"), "--draw", str(out / f"{name}.svg")]
        buffer = io.StringIO()
        with contextlib.redirect_stdout(buffer):
            code = run_dwell(args + files)
        click.echo(buffer.getvalue(), nl=False)
        (out / f"{name}.txt").write_text(buffer.getvalue())
        if code == 0:
            buffer = io.StringIO()
            with contextlib.redirect_stdout(buffer):
                code = run_dwell(args + ["--json"])
            (out / f"{name}.json").write_text(buffer.getvalue())
        if code != 0:
            raise click.ClickException(f"demo step {name!r} failed with exit status {code}")
    click.echo(f"\nwrote tables (.txt, .json), motion diagrams (.png) and drawings (.svg) to {out.resolve()} "
               f"in {time.perf_counter() - start:.1f} s")
