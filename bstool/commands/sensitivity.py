"""``bstool sensitivity``: how far gaits transfer to robots other than the nominal one."""

from __future__ import annotations

import json
import sys
from typing import Any

import click

from bstool.commands.robot_option import robot_option, say_note
from bstool.experiments.sensitivity import DEFAULT_POINTS, DEFAULT_SAMPLES


@click.command("sensitivity")
@click.argument("controllers", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option(
    "--points",
    type=click.IntRange(min=2),
    default=DEFAULT_POINTS,
    show_default=True,
    help="Values per parameter in the one-at-a-time sweep (ends included).",
)
@click.option(
    "--samples",
    type=click.IntRange(min=1),
    default=DEFAULT_SAMPLES,
    show_default=True,
    help="Random robots in the joint sample.",
)
@click.option(
    "--seed",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="Seed of the joint sample (the same robots for every controller).",
)
@click.option(
    "-T",
    "--transitions",
    type=click.IntRange(min=1),
    default=None,
    help="Transitions per run (default: the first controller's max_trans, else 30).",
)
@click.option(
    "--stamp-timed",
    is_flag=True,
    help="Move each servo when a build's stamp would (the schedule model of `bstool "
    "evolve --stamp-timed`, at the period each controller was evolved at).",
)
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    default=None,
    help="Physics threads (default: the usable CPUs; 1 per Dask thread with --cluster).",
)
@click.option(
    "--cluster", metavar="ADDRESS", help="Evaluate on a Dask scheduler, e.g. tcp://host:8786."
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object (metres).")
@click.option(
    "--plot",
    type=click.Path(dir_okay=False),
    help="PNG: distance against each parameter, and the joint sample's spread.",
)
@robot_option
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
def command(
    controllers: tuple[str, ...],
    points: int,
    samples: int,
    seed: int,
    transitions: int | None,
    stamp_timed: bool,
    workers: int | None,
    cluster: str | None,
    as_json: bool,
    plot: str | None,
    robot: str | None,
    quiet: bool,
) -> None:
    """Run each CONTROLLER on robots drawn from the robot's uncertain ranges (the robot file's
    [uncertain] table, else the default box of docs/robot.md): every parameter alone over its
    range (--points values), and --samples robots drawn from all ranges at once (seeded: the
    same robots for every controller). Prints the nominal distance, the joint sample's mean,
    10th percentile, worst and worst-10 % mean, the fraction of the nominal distance kept, per
    parameter the value that hurts most, and the Spearman correlation of the joint sample's
    distances with each parameter (which ones the losses go with: measure those first)."""
    from tqdm import tqdm

    from bstool import outputs
    from bstool.cpus import usable_cpus
    from bstool.errors import InputError
    from bstool.experiments import common
    from bstool.experiments import sensitivity as sens
    from bstool.robot.robotfile import resolve

    if plot:
        outputs.check_file(plot, "plot")  # before any simulation
    loaded = [common.load(path, robot) for path in controllers]
    first = loaded[0]
    chosen = first.robot or resolve(robot, None)[0]
    say_note(first.note, as_json)
    for item in loaded[1:]:  # the same robots for all: the first one's (or --robot)
        if robot is None and item.controller.robot != first.controller.robot:
            click.echo(
                f"note: {item.path} was evolved for another robot than {first.path}; both run "
                f"on {chosen.source}",
                err=True,
            )
    T = common.default_transitions(first.controller, transitions)
    plan = sens.design(chosen, points=points, samples=samples, seed=seed)
    threads = workers or (1 if cluster else usable_cpus())
    labels = common.unique_labels(controllers)
    results = []
    with tqdm(
        total=plan.count * len(loaded),
        unit="run",
        desc="sensitivity",
        file=sys.stderr,
        disable=quiet or as_json or None,
    ) as bar:
        for label, item in zip(labels, loaded, strict=True):
            if item.controller.legs != chosen.spec.legs:  # pragma: no cover - sizes are fixed
                raise InputError(f"{item.path} is for another robot size")
            evaluate = _evaluator(item.controller, chosen.spec, stamp_timed, threads, cluster)
            try:
                run = sens.chunked(evaluate, max(1, 2 * threads), bar.update)
                results.append(sens.measure(label, item.controller.states(T), plan, run))
            finally:
                close = getattr(evaluate, "close", None)
                if close is not None:
                    close()
    if plot:
        sens.plot(results, plan, plot)
    if as_json:
        out: dict[str, Any] = {
            "transitions": T,
            "stamp_timed": stamp_timed,
            "robot": chosen.to_json(),
            "box": chosen.box.to_toml_table(),
            "points": points,
            "samples": samples,
            "seed": seed,
            "controllers": [r.to_json() for r in results],
            "units": "m",
        }
        click.echo(json.dumps(out))
        return
    click.echo(f"robot: {chosen.source}; uncertain: {chosen.box.describe()}")
    click.echo(f"{T} transitions, {'stamp-timed' if stamp_timed else 'plain'} physics")
    click.echo(sens.table(results, plan))
    if plot:
        click.echo(f"plot: {plot}")


class _Evaluate:
    """The evolve evaluator of one controller, as ``(sequences, robots) -> distances``."""

    def __init__(self, evaluator: Any) -> None:
        self.evaluator = evaluator

    def __call__(self, seqs: list[Any], robots: list[Any]) -> list[float]:
        return [float(d) for d in self.evaluator(seqs, robot=robots)]

    def close(self) -> None:
        close = getattr(self.evaluator, "close", None)
        if close is not None:
            close()


def _evaluator(
    ctrl: Any, spec: Any, stamp_timed: bool, workers: int, cluster: str | None
) -> _Evaluate:
    from bstool.evolve.fitness import PhysicsFitness, StampTimedFitness

    factory: Any
    if stamp_timed:
        from bstool.commands.simulate_model import evolved_builds, evolved_period
        from hil_mock.schedule_model import schedule_model

        model = schedule_model(
            ctrl.model,
            period=evolved_period(ctrl),
            legs=ctrl.legs,
            modules=ctrl.modules,
            builds=evolved_builds(ctrl),
            spec=spec,
        )
        factory = StampTimedFitness(model, ctrl.legs, ctrl.modules, workers, spec)
    else:
        factory = PhysicsFitness(ctrl.legs, ctrl.modules, workers, spec)
    if cluster:
        from bstool.evolve.cluster import DaskEvaluator

        return _Evaluate(DaskEvaluator(cluster, factory))
    return _Evaluate(factory.build())
