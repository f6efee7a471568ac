"""Disc path plot in the style of the paper's Fig. 18 (displacement in cm, start at the origin)."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from bstool import fileio
from bstool.errors import InputError
from bstool.sim.simulator import SimResult


def plot_paths(
    path: str | os.PathLike[str],
    runs: Sequence[tuple[str, SimResult]],
    title: str = "Disc displacement",
) -> None:
    """Write a PNG with one line per (label, result); coordinates relative to each start."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.5, 5.0), dpi=100)
    ax = fig.add_subplot()
    for label, result in runs:
        xy = (np.asarray(result.path) - result.path[0]) * 100.0
        (line,) = ax.plot(xy[:, 0], xy[:, 1], marker=".", markersize=3, linewidth=1.2)
        ax.plot(xy[-1, 0], xy[-1, 1], marker="o", color=line.get_color(), markersize=6)
        line.set_label(f"{label} ({result.distance * 100:.1f} cm)")
    ax.plot([0], [0], marker="s", color="black", markersize=5, label="start")
    ax.axhline(0, color="0.8", linewidth=0.6)
    ax.axvline(0, color="0.8", linewidth=0.6)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    ax.set_title(title)
    ax.grid(True, linewidth=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    try:
        with fileio.atomic_open(path, "wb") as fh:
            fig.savefig(fh, format="png")
    except OSError as exc:  # checked before the work; this is the disk filling up meanwhile
        raise InputError(f"cannot write the plot {path}: {exc.strerror or exc}") from None
