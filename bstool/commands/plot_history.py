"""``bstool plot-history``: max and mean fitness per generation of evolve runs, overlaid."""

from __future__ import annotations

from pathlib import Path

import click

from bstool import outputs
from bstool.errors import InputError
from bstool.evolve.checkpoint import HISTORY, read_history


@click.command("plot-history")
@click.argument("runs", nargs=-1, required=True, type=click.Path(exists=True, file_okay=False))
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False),
    default="history.png",
    show_default=True,
    help="Image to write (.png, .svg or .pdf).",
)
@click.option("--title", default="Fitness against generation", show_default=True)
def command(runs: tuple[str, ...], output: str, title: str) -> None:
    """Plot maximum (solid) and average (dashed) fitness against generation for each run
    directory in RUNS (like the paper's Figs 7, 9–11, 15–16). ca2ddiff runs draw one pair of
    curves per population (control rule, leg rule)."""
    suffix = Path(output).suffix.lstrip(".").lower()
    if suffix not in ("png", "svg", "pdf"):
        raise InputError(
            f"cannot write a plot as {output!r}", hint="name the output .png, .svg or .pdf"
        )
    outputs.check_file(output, "plot")
    from bstool.experiments.plots import plot_fitness

    histories = {Path(run_dir).name: read_history(Path(run_dir) / HISTORY) for run_dir in runs}
    plot_fitness(output, histories, title)
    click.echo(f"wrote {output}")
