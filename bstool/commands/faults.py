"""``bstool faults``: degree of mobility when modules fail (paper §5.1, Fig. 17), single or
several at a time."""

from __future__ import annotations

import json
import math

import click

from bstool import outputs
from bstool.commands.robot_option import robot_option
from bstool.commands.robot_option import say_note as _say_note
from bstool.experiments import common, progress
from bstool.experiments.mobility import (
    FaultRun,
    SingleFaults,
    distances_with,
    random_failures,
    single_failures,
    summarize,
)


@click.command("faults")
@click.argument("controller", type=click.Path(dir_okay=False))
@click.option(
    "-T",
    "--transitions",
    type=click.IntRange(min=1),
    default=None,
    help="Transitions per run (default: the controller's max_trans, else 30).",
)
@click.option(
    "--k",
    "ks",
    type=click.IntRange(min=1),
    multiple=True,
    help="Fail K random modules at once instead of each alone; repeatable (e.g. "
    "--k 1 --k 2 ... --k 5).",
)
@click.option(
    "--samples",
    type=click.IntRange(min=1),
    default=30,
    show_default=True,
    help="Random failure sets per K.",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the random sets.")
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    default=None,
    help="Physics threads (default: all cores).",
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option(
    "--plot",
    type=click.Path(dir_okay=False),
    help="PNG: bars per failed module (Fig. 17), or the M_D curve against K.",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
@robot_option
def command(
    controller: str,
    transitions: int | None,
    ks: tuple[int, ...],
    samples: int,
    seed: int,
    workers: int | None,
    as_json: bool,
    plot: str | None,
    quiet: bool,
    robot: str | None,
) -> None:
    """Fail each module of CONTROLLER alone (n·m runs) and report the degree of mobility
    M_D = distance with the failure / distance without × 100 % (eq. 15), with the paper's
    summary: how many single failures keep ≥ 80 % and 100 % of the mobility.

    With --k, fail K random modules at once, --samples times per K."""
    if plot:
        outputs.check_file(plot, "plot")  # before minutes of simulation, not after
    from bstool.sim.batch import BatchEvaluator

    loaded = common.load(controller, robot)
    _say_note(loaded.note, as_json)
    T = common.default_transitions(loaded.controller, transitions)
    cells = loaded.controller.legs * loaded.controller.modules
    runs = 1 + (sum(min(samples, math.comb(cells, k)) for k in set(ks)) if ks else cells)
    with (
        BatchEvaluator(loaded.spec, workers=workers) as evaluator,
        progress.bar("faults", runs, quiet=quiet) as bar,
    ):
        evaluate = distances_with(evaluator, bar)
        if not ks:
            result = single_failures(loaded.controller, evaluate, T)
        else:
            baseline = evaluate([loaded.controller.states(T)])[0]
            by_k: dict[int, list[FaultRun]] = {}
            for k in sorted(set(ks)):
                by_k[k] = random_failures(
                    loaded.controller, evaluate, T, k, samples, seed=seed + k, baseline=baseline
                )
    if not ks:
        _report_single(loaded.name, result, T, as_json)
        if plot:
            from bstool.experiments.plots import plot_single_failures

            plot_single_failures(plot, {loaded.name: result})
        return
    _report_multi(loaded.name, baseline, by_k, T, seed, as_json)
    if plot:
        from bstool.experiments.plots import plot_multi_failures

        plot_multi_failures(plot, {loaded.name: by_k})


def _report_single(name: str, result: SingleFaults, T: int, as_json: bool) -> None:
    if as_json:
        click.echo(json.dumps({"controller": name, "transitions": T, **result.to_json()}))
        return
    click.echo(f"{name}: healthy distance {result.baseline * 100:.2f} cm after {T} transitions")
    table = result.table
    header = "leg  " + " ".join(f"{'M' + str(j):>7}" for j in range(table.shape[1]))
    click.echo("degree of mobility M_D (%) of each module failed alone:")
    click.echo(header)
    for i, row in enumerate(table):
        click.echo(f"L{i:<3} " + " ".join(f"{v:7.1f}" for v in row))
    n = len(result.runs)
    click.echo(f"keep >= 80 % mobility:  {result.count_at_least(80.0)}/{n} single failures")
    click.echo(f"keep 100 % mobility:    {result.count_at_least(100.0)}/{n} single failures")


def _report_multi(
    name: str, baseline: float, by_k: dict[int, list[FaultRun]], T: int, seed: int, as_json: bool
) -> None:
    stats = {k: summarize(runs) for k, runs in by_k.items()}
    if as_json:
        click.echo(json.dumps({
            "controller": name, "transitions": T, "seed": seed, "baseline_distance": baseline,
            "by_k": {str(k): {**stats[k], "mobility": [r.mobility for r in by_k[k]],
                              "failed": [[str(m) for m in r.failed] for r in by_k[k]]}
                     for k in by_k},
        }))  # fmt: skip
        return
    click.echo(f"{name}: healthy distance {baseline * 100:.2f} cm after {T} transitions")
    click.echo(f"{'K':>3} {'runs':>5} {'median':>8} {'q1':>8} {'q3':>8} {'min':>8} {'>=80%':>6}")
    for k, runs in by_k.items():
        s = stats[k]
        keep = sum(1 for r in runs if r.mobility >= 80.0)
        click.echo(
            f"{k:>3} {len(runs):>5} {s.get('median', float('nan')):8.1f} "
            f"{s.get('q1', float('nan')):8.1f} {s.get('q3', float('nan')):8.1f} "
            f"{s.get('min', float('nan')):8.1f} {keep:>6}"
        )
