"""Motion diagrams (matplotlib): displacement, velocity and acceleration vs crank angle."""

from __future__ import annotations

from pathlib import Path

from report.escape import plot_text
from report.folder import staged_file
from report.motion_table import MotionTable

__all__ = ["plot_motion"]


def plot_motion(table: MotionTable, outputs: list[str], path: str | Path, title: str = "") -> Path:
    """Stack one subplot per named column of ``table`` against its crank angle (first column).

    The file type follows the suffix (``.png`` or ``.svg``).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    phi = table.columns[0]
    fig, axes = plt.subplots(len(outputs), 1, sharex=True, figsize=(7.5, 2.3 * len(outputs) + 0.6))
    axes = [axes] if len(outputs) == 1 else list(axes)
    for ax, name in zip(axes, outputs):
        col = table.column(name)
        ax.plot(phi.values, col.values, lw=1.6)
        ax.set_ylabel(plot_text(f"{col.label or col.name} [{col.unit}]"), fontsize=9)
        ax.axhline(0.0, color="0.6", lw=0.6)
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel(f"crank angle [{phi.unit}]")
    axes[-1].set_xlim(phi.values.min(), phi.values.max())
    if title:
        axes[0].set_title(plot_text(title), fontsize=10)
    fig.tight_layout()
    path = Path(path)
    with staged_file(path) as tmp:  # a killed run leaves the old file or the new one (report/folder.py)
        fig.savefig(tmp, dpi=120, format=path.suffix.lstrip(".").lower() or None)
    plt.close(fig)
    return path
