"""``bstool sensitivity``: how far gaits transfer to robots other than the nominal one."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import click

from bstool.commands.robot_option import robot_option, say_note
from bstool.experiments.sensitivity import DEFAULT_POINTS, DEFAULT_SAMPLES


@click.command("sensitivity")
@click.argument("controllers", nargs=-1, required=True, type=click.Path(exists=True))
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
    distances with each parameter (which ones the losses go with: measure those first).
    From 10 robots up, also the 95 % bootstrap intervals of the mean and the 10th percentile
    (how sure they are with this many robots).

    A CONTROLLER may be a build folder (a `bstool compile` output): its controller, each servo
    moving when the build's own programs do on the twin (as `simulate --build`), not when the
    schedule model predicts: what the stamps you flash would walk on each robot."""
    from tqdm import tqdm

    from bstool import outputs
    from bstool.cpus import usable_cpus
    from bstool.errors import InputError
    from bstool.experiments import common
    from bstool.experiments import sensitivity as sens
    from bstool.robot.robotfile import resolve

    if plot:
        outputs.check_file(plot, "plot")  # before any simulation
    builds = {path: _build(path) for path in controllers if Path(path).is_dir()}
    loaded = [
        common.load(str(builds[path].controller_file) if path in builds else path, robot)
        for path in controllers
    ]
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
        for label, item, path in zip(labels, loaded, controllers, strict=True):
            if item.controller.legs != chosen.spec.legs:  # pragma: no cover - sizes are fixed
                raise InputError(f"{item.path} is for another robot size")
            build = builds.get(path)
            source = None if build is None else _build_schedule(build, item.controller, T)
            evaluate = _evaluator(
                item.controller, chosen.spec, stamp_timed, threads, cluster, source
            )
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
            "timing": {
                label: _timing(path, builds, stamp_timed)
                for label, path in zip(labels, controllers, strict=True)
            },
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
    how = {_timing(path, builds, stamp_timed) for path in controllers}
    if len(how) == 1:
        click.echo(f"{T} transitions, {how.pop()}")
    else:
        click.echo(f"{T} transitions; timing:")
        for label, path in zip(labels, controllers, strict=True):
            click.echo(f"  {label}: {_timing(path, builds, stamp_timed)}")
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


def _timing(path: str, builds: dict[str, Any], stamp_timed: bool) -> str:
    if path in builds:
        return f"stamp-timed physics on the build's own programs ({path})"
    return "stamp-timed physics (schedule model)" if stamp_timed else "plain physics"


def _build(path: str) -> Any:
    """The build of a CONTROLLER argument that is a folder (it must hold its controller)."""
    from bstool.commands.simulate_build import load_matching
    from bstool.errors import InputError

    if not (Path(path) / "manifest.json").is_file():
        raise InputError(
            f"{path}: a folder, but not a build (no manifest.json)",
            hint="give a controller file (C.json, RUN/best.json) or a `bstool compile` output",
        )
    return load_matching(path, None)[0]


def _build_schedule(build: Any, ctrl: Any, transitions: int) -> Any:
    """The build's own schedule of ``transitions`` transitions (the twin without physics)."""
    from bstool.errors import InputError
    from hil_mock.schedule_extract import build_schedule

    if (build.legs, build.modules) != (ctrl.legs, ctrl.modules):  # pragma: no cover - fixed
        raise InputError(f"{build.root}: the build is for another robot size")
    return build_schedule(build, ctrl.states(transitions))


def _evaluator(
    ctrl: Any,
    spec: Any,
    stamp_timed: bool,
    workers: int,
    cluster: str | None,
    source: Any = None,
) -> _Evaluate:
    """``source``: a build's own schedule (BuildSchedule), else the schedule model when
    ``stamp_timed``, else plain physics."""
    from bstool.evolve.fitness import PhysicsFitness, StampTimedFitness

    factory: Any
    if source is not None:
        factory = StampTimedFitness(source, ctrl.legs, ctrl.modules, workers, spec)
    elif stamp_timed:
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
