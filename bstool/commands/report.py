"""``bstool report``: an HTML page comparing evolve runs / controllers."""

from __future__ import annotations

import click


@click.command("report")
@click.argument("inputs", nargs=-1, required=True, type=click.Path(exists=False))
@click.option(
    "-o",
    "--out",
    type=click.Path(file_okay=False),
    default="report",
    show_default=True,
    help="Folder for index.html, report.json and the PNGs, replaced as a whole. It must be "
    "new, empty or an earlier report (else --force), and never holds the INPUTS.",
)
@click.option("-T", "--transitions", type=click.IntRange(min=1), default=30, show_default=True,
              help="MAX_TRANS for paths, failures and rotations.")  # fmt: skip
@click.option("--extrapolate", type=click.IntRange(min=2), default=120, show_default=True,
              help="Transitions of the extrapolation curves.")  # fmt: skip
@click.option(
    "--multi-failures",
    "multi_samples",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    metavar="SAMPLES",
    help="Also fail K = 1..5 random modules at once, SAMPLES sets per K, and plot the median "
    "M_D against K per controller (0: skip; costs 5 x SAMPLES runs per controller).",
)
@click.option("--workers", type=click.IntRange(min=1), default=None, help="Physics threads.")
@click.option("--force", is_flag=True, help="Replace OUT even if it is not an earlier report.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar or messages.")
def command(
    inputs: tuple[str, ...],
    out: str,
    transitions: int,
    extrapolate: int,
    multi_samples: int,
    workers: int | None,
    force: bool,
    quiet: bool,
) -> None:
    """Compare INPUTS (evolve run directories or controller files): fitness curves, disc paths,
    mobility under single failures, distance beyond MAX_TRANS, spread over leg rotations, and
    a table of the numbers. Open OUT/index.html in any browser (no network needed)."""
    from bstool.experiments import progress
    from bstool.experiments.report import build_report

    with progress.bar("report", None, quiet=quiet) as bar:

        def say(msg: str) -> None:
            if progress.enabled(quiet):
                bar.describe(msg)
            elif not quiet:
                click.echo(f"... {msg}", err=True)

        index = build_report(
            inputs,
            out,
            transitions,
            extrapolate,
            workers,
            progress=say,
            multi_samples=multi_samples,
            force=force,
            runs_done=bar,
            runs_total=bar.total,
        )
    click.echo(f"report: {index}")
