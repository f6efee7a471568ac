"""``bstool extrapolate``: distance beyond MAX_TRANS (paper Fig. 19), and the paper's remedy of
re-initialising the module states every MAX_TRANS transitions."""

from __future__ import annotations

import json

import click
import numpy as np

from bstool import outputs
from bstool.commands.robot_option import robot_option
from bstool.commands.robot_option import say_note as _say_note
from bstool.experiments import common, progress
from bstool.experiments.extrapolate import reinit_states, run_with_progress
from bstool.experiments.paths import distance_curve


@click.command("extrapolate")
@click.argument("controller", type=click.Path(dir_okay=False))
@click.option("-T", "--transitions", type=click.IntRange(min=1), default=120, show_default=True)
@click.option(
    "--reinit-every",
    type=click.IntRange(min=0),
    default=None,
    help="Also run with the states re-initialised every N transitions (default: the "
    "controller's max_trans, else 30). 0 turns the variant off (like --no-reinit).",
)
@click.option("--no-reinit", is_flag=True, help="Only the plain run.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("--plot", type=click.Path(dir_okay=False), help="PNG of distance against transition.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
@robot_option
def command(
    controller: str,
    transitions: int,
    reinit_every: int | None,
    no_reinit: bool,
    as_json: bool,
    plot: str | None,
    quiet: bool,
    robot: str | None,
) -> None:
    """Run CONTROLLER for -T transitions and report the distance from the start after each
    one: does it keep going after the MAX_TRANS it was evolved for?"""
    if plot:
        outputs.check_file(plot, "plot")
    loaded = common.load(controller, robot)
    _say_note(loaded.note, as_json)
    max_trans = loaded.controller.max_trans or 30
    every = max_trans if reinit_every is None else reinit_every
    sequences = {"plain": loaded.controller.states(transitions)}
    if not no_reinit and every > 0:
        sequences[f"reinit every {every}"] = reinit_states(loaded.controller, transitions, every)
    with progress.bar("extrapolate", None, quiet=quiet, unit="transition") as bar:
        results = run_with_progress(loaded.spec, list(sequences.values()), bar, bar.total)
    curves = {name: distance_curve(r.path) for name, r in zip(sequences, results, strict=True)}
    if as_json:
        click.echo(json.dumps({
            "controller": loaded.name, "transitions": transitions, "max_trans": max_trans,
            "curves": {name: c.tolist() for name, c in curves.items()},
        }))  # fmt: skip
    else:
        click.echo(f"{loaded.name}: distance from start (cm), MAX_TRANS = {max_trans}")
        marks = sorted({t for t in (max_trans, transitions // 2, transitions) if t <= transitions})
        click.echo(f"{'':22}" + "".join(f"{'T=' + str(t):>10}" for t in marks) + f"{'peak':>14}")
        for name, c in curves.items():
            peak = int(np.argmax(c))
            click.echo(
                f"{name:22}" + "".join(f"{c[t] * 100:10.1f}" for t in marks)
                + f"{c[peak] * 100:8.1f} @ {peak}"
            )  # fmt: skip
    if plot:
        from bstool.experiments.plots import plot_distance_curves

        plot_distance_curves(plot, curves, max_trans, title=f"{loaded.name}: beyond MAX_TRANS")
