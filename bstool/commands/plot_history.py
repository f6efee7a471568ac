"""``bstool plot-history``: max and mean fitness per generation of evolve runs, overlaid."""

from __future__ import annotations

from pathlib import Path

import click

from bstool import fileio
from bstool.errors import InputError
from bstool.evolve.checkpoint import HISTORY, read_history

_POPULATION_LABEL = {"main": "", "control": " control rule", "leg": " leg rule"}


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
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    curves = 0
    for run_dir in runs:
        rows = read_history(Path(run_dir) / HISTORY)
        for pop in dict.fromkeys(r.population for r in rows):
            mine = [r for r in rows if r.population == pop]
            colour = colours[curves % len(colours)]
            label = f"{Path(run_dir).name}{_POPULATION_LABEL.get(pop, ' ' + pop)}"
            gens = [r.generation for r in mine]
            ax.plot(gens, [r.best for r in mine], color=colour, label=f"{label} max")
            ax.plot(gens, [r.mean for r in mine], color=colour, ls="--", label=f"{label} mean")
            curves += 1
    ax.set_xlabel("generation")
    ax.set_ylabel("fitness (distance, m)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    fig.tight_layout()
    with fileio.atomic_open(output, "wb") as fh:
        fig.savefig(fh, format=suffix)
    plt.close(fig)
    click.echo(f"wrote {output}")
