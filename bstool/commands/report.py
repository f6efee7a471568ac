"""``bstool report``: an HTML page comparing evolve runs / controllers."""

from __future__ import annotations

import click

from bstool.commands.robot_option import robot_option


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
@click.option(
    "--stamp-timed",
    is_flag=True,
    help="Every run moves each servo when a build's stamp would (the schedule model of "
    "`bstool evolve --stamp-timed`, docs/twin.md); the perturbed starts stay plain.",
)
@click.option("--period", type=click.FloatRange(min=0, min_open=True), default=None,
              help="--stamp-timed: the period the controllers will be compiled with "
              "(default: compile's).")  # fmt: skip
@click.option("--force", is_flag=True, help="Replace OUT even if it is not an earlier report.")
@click.option(
    "--sensitivity",
    "sensitivity_samples",
    type=click.IntRange(min=0),
    default=16,
    show_default=True,
    metavar="SAMPLES",
    help="How far each gait transfers: SAMPLES robots drawn from the uncertain ranges (the "
    "robot file's, else the default box) and each parameter alone at --sensitivity-points "
    "values, as `bstool sensitivity` (0: skip).",
)
@click.option("--sensitivity-points", type=click.IntRange(min=2), default=3, show_default=True,
              help="Values per parameter of the sensitivity section's sweep.")  # fmt: skip
@robot_option
@click.option("-q", "--quiet", is_flag=True, help="No progress bar or messages.")
@click.pass_context
def command(
    ctx: click.Context,
    inputs: tuple[str, ...],
    out: str,
    transitions: int,
    extrapolate: int,
    multi_samples: int,
    workers: int | None,
    stamp_timed: bool,
    period: float | None,
    force: bool,
    quiet: bool,
    robot: str | None,
    sensitivity_samples: int,
    sensitivity_points: int,
) -> None:
    """Compare INPUTS (evolve run directories or controller files): fitness curves, disc paths,
    mobility under single failures, distance beyond MAX_TRANS, spread over leg rotations, and
    a table of the numbers. Open OUT/index.html in any browser (no network needed).

    Given one campaign folder (made by `bstool campaign`), writes that campaign's report,
    DIR/report unless -o is given: the same page the campaign ends with (docs/campaign.md).
    """
    from bstool.campaign.runner import is_campaign
    from bstool.errors import InputError
    from bstool.experiments import progress
    from bstool.experiments.report import build_report

    if len(inputs) == 1 and is_campaign(inputs[0]):
        from click.core import ParameterSource

        given = [
            f"--{name.replace('_', '-')}"
            for name in (
                "transitions",
                "extrapolate",
                "multi_samples",
                "stamp_timed",
                "period",
                "robot",
                "sensitivity_samples",
                "sensitivity_points",
            )
            if ctx.get_parameter_source(name) is not ParameterSource.DEFAULT
        ]
        if given:
            raise InputError(
                f"{inputs[0]} is a campaign: its report takes {', '.join(given)} from its plan",
                hint="drop them, or change the campaign's plan.toml",
            )
        explicit = ctx.get_parameter_source("out") is not ParameterSource.DEFAULT
        _campaign(inputs[0], out if explicit else None, workers, force, quiet)
        return

    if period is not None and not stamp_timed:
        raise InputError("--period only applies with --stamp-timed", hint="add --stamp-timed")
    schedule_for = None
    evaluation = "plain (every servo moves at each transition boundary)"
    if stamp_timed:
        from bstool.controllers import Controller
        from bstool.robot.robotfile import resolve
        from hil_mock.schedule_model import schedule_model

        def schedule_for(c: Controller) -> object:
            spec = resolve(robot, c.robot, what=c.model)[0].spec
            return schedule_model(c.model, period=period, legs=c.legs, modules=c.modules, spec=spec)

        evaluation = "stamp-timed (each servo moved when its stamp would, schedule model" + (
            ")" if period is None else f", period {period:g} s)"
        )

    if robot is not None and not quiet:
        _robot_notes(inputs, robot)
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
            schedule_for=schedule_for,
            evaluation=evaluation,
            robot=robot,
            sensitivity=(sensitivity_points, sensitivity_samples) if sensitivity_samples else None,
        )
    click.echo(f"report: {index}")


def _campaign(folder: str, out: str | None, workers: int | None, force: bool, quiet: bool) -> None:
    """The report of a campaign folder (its analyses computed first where not cached)."""
    from bstool.campaign import analyses, report
    from bstool.campaign import plan as cp
    from bstool.commands.campaign import analysis_schedule, evolve_settings
    from bstool.experiments import progress

    settings = evolve_settings()
    plan = cp.load(f"{folder}/{cp.PLAN_FILE}", settings)
    with progress.bar("report", None, quiet=quiet) as bar:

        def say(msg: str) -> None:
            if progress.enabled(quiet):
                bar.describe(msg)

        index = report.build(
            folder,
            plan,
            settings,
            out=out,
            force=force,
            workers=workers,
            schedule_for=analysis_schedule,
            progress=analyses.Progress(bar.total, bar, say),
        )
    click.echo(f"report: {index}")


def _robot_notes(inputs: tuple[str, ...], robot: str) -> None:
    """One line per input whose recorded robot --robot differs from."""
    from pathlib import Path

    from bstool.commands.robot_option import resolve_robot
    from bstool.controllers import load_controller

    for item in inputs:
        path = Path(item) / "best.json" if Path(item).is_dir() else Path(item)
        if path.is_file():
            resolve_robot(robot, load_controller(path).robot, str(path))
