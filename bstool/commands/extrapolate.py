"""``bstool extrapolate``: distance beyond MAX_TRANS (paper Fig. 19), and the paper's remedy of
re-initialising the module states every MAX_TRANS transitions."""

from __future__ import annotations

import json

import click
import numpy as np

from bstool.experiments import common
from bstool.experiments.extrapolate import reinit_states
from bstool.experiments.paths import distance_curve


@click.command("extrapolate")
@click.argument("controller", type=click.Path(dir_okay=False))
@click.option("-T", "--transitions", type=click.IntRange(min=1), default=120, show_default=True)
@click.option(
    "--reinit-every",
    type=click.IntRange(min=1),
    default=None,
    help="Also run with the states re-initialised every N transitions (default: the "
    "controller's max_trans, else 30). 0 turns the variant off.",
)
@click.option("--no-reinit", is_flag=True, help="Only the plain run.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("--plot", type=click.Path(dir_okay=False), help="PNG of distance against transition.")
def command(
    controller: str,
    transitions: int,
    reinit_every: int | None,
    no_reinit: bool,
    as_json: bool,
    plot: str | None,
) -> None:
    """Run CONTROLLER for -T transitions and report the distance from the start after each
    one: does it keep going after the MAX_TRANS it was evolved for?"""
    from bstool.sim.batch import BatchEvaluator

    loaded = common.load(controller)
    max_trans = loaded.controller.max_trans or 30
    every = reinit_every or max_trans
    sequences = {"plain": loaded.controller.states(transitions)}
    if not no_reinit:
        sequences[f"reinit every {every}"] = reinit_states(loaded.controller, transitions, every)
    with BatchEvaluator(loaded.spec) as evaluator:
        results = evaluator.evaluate(list(sequences.values()))
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
