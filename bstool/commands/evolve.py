"""``bstool evolve``: the paper's GA (or §3.4 co-evolution) into a run directory.

Only the command line lives here: defaults, checks and the run itself are in
:mod:`bstool.evolve.options` and :mod:`bstool.evolve.driver` (shared with the Python API).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import click
from click.core import ParameterSource

from bstool.controllers.reference import MODELS
from bstool.errors import InputError
from bstool.evolve import options as opt
from bstool.evolve.driver import (
    EvolveInterrupted,
    EvolveResult,
    Generation,
    Plan,
    execute,
    fitness_text,
    plan_new,
    plan_resume,
)
from bstool.evolve.randomize import OPTION_FLAGS, SCORES
from bstool.evolve.scoring import ROBUST_MODES

_D = opt.default


@click.command("evolve")
@click.argument("model", type=click.Choice(MODELS), required=False, metavar="MODEL")
@click.option("--pop", type=click.IntRange(min=2), default=_D("pop"), show_default=True,
              help="POP_SIZE.")  # fmt: skip
@click.option(
    "--gens",
    type=click.IntRange(min=1),
    show_default=opt.default_text("gens"),
    help="MAX_GEN (ca2ddiff: outer loops). With --resume: extend to N.",
)
@click.option("--pc", type=click.FloatRange(0, 1), default=_D("pc"), show_default=True,
              help="Crossover probability P_C.")  # fmt: skip
@click.option(
    "--pm",
    type=click.FloatRange(0, 1),
    show_default=opt.default_text("pm"),
    help="Per-gene mutation probability P_M.",
)
@click.option("--transitions", type=click.IntRange(min=1), default=_D("transitions"),
              show_default=True, help="MAX_TRANS per evaluation.")  # fmt: skip
@click.option("--coevol-gens", type=click.IntRange(min=1), default=_D("coevol_gens"),
              show_default=True, help="ca2ddiff: MAX_COEVOL_GENERATION.")  # fmt: skip
@click.option("--seed", type=click.IntRange(min=0), show_default="a random one, recorded",
              help="Random seed.")  # fmt: skip
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    show_default="the usable CPUs; 1 per Dask thread with --cluster",
    help="Physics threads.",
)
@click.option("--out", "out", type=click.Path(file_okay=False), help="Run directory to create.")
@click.option(
    "--resume",
    type=click.Path(file_okay=False),
    help="Continue the run in this directory from its last checkpoint.",
)
@click.option(
    "--force",
    is_flag=True,
    help="Replace a non-empty --out folder (even an earlier run) instead of refusing.",
)
@click.option(
    "--cluster",
    metavar="ADDRESS",
    help="Evaluate on a Dask scheduler, e.g. tcp://host:8786 (pip install 'bstool[cluster]').",
)
@click.option(
    "--fitness",
    type=click.Choice(opt.FITNESS_KINDS),
    default=_D("fitness"),
    show_default=True,
    help="physics (MuJoCo) or toy (a cheap stand-in to try the pipeline).",
)
@click.option(
    "--stamp-timed",
    is_flag=True,
    help="Physics with each servo moved when a build's stamp would move it (the twin's timing,"
    " from a build of a representative controller; docs/twin.md).",
)
@click.option(
    "--period",
    type=click.FloatRange(min=0, min_open=True),
    help="--stamp-timed: the period the controller will be compiled with (default: compile's).",
)
@click.option(
    "--timing",
    type=click.Path(dir_okay=False),
    help="--stamp-timed: the stamps' measured timing (a bstool.timing/1 file from bstool probe);"
    " its sha256 is recorded with the run.",
)
@click.option(
    "--schedule-builds",
    type=click.IntRange(1, opt.MAX_BUILDS),
    help="--stamp-timed: play each candidate on K builds of random controllers and score the"
    " mean distance (K physics runs per candidate); closer to what a new build walks for the"
    " 2-D CA models [default: one model averaged over two builds]",
)
@click.option(
    "--robust",
    type=click.Choice(ROBUST_MODES),
    is_flag=False,
    flag_value="mean",
    help="Score each candidate over its n leg rotations: mean (the flag alone) or worst.",
)
@click.option(
    "--coevolve-faults",
    is_flag=True,
    help="Co-evolve a population of parasites (sets of failed modules) that hurt the hosts.",
)
@click.option("--parasites", type=click.IntRange(min=2), default=_D("parasites"),
              show_default=True, help="--coevolve-faults: parasite population size.")  # fmt: skip
@click.option("--parasite-k", metavar="K|A..B", default=_D("parasite_k"), show_default=True,
              help="--coevolve-faults: failed modules per parasite.")  # fmt: skip
@click.option(
    "--robot",
    type=click.Path(dir_okay=False),
    help="A robot file (bstool.robot/1, `bstool robot` writes the default): the robot to "
    "evolve for; its values are recorded in best.json and the checkpoint.",
)
@click.option(
    "--randomize",
    is_flag=True,
    help="Score each candidate on K robots drawn from the robot file's [uncertain] ranges "
    "(the default box without one; --randomize-box: a box of its own), the same K for every "
    "candidate of a generation, new ones each generation; best.json is the best on a fixed "
    "validation set (docs/evolution.md).",
)
@click.option("--randomize-samples", type=click.IntRange(min=1),
              help="--randomize: robots per generation, K  [default: 4]")  # fmt: skip
@click.option("--randomize-score", type=click.Choice(SCORES),
              help="--randomize: a candidate's score over its K robots (worst-quarter: the mean "
              "of the lowest quarter)  [default: mean]")  # fmt: skip
@click.option("--validate-every", type=click.IntRange(min=1),
              help="--randomize: measure the generation's best on the validation robots every N "
              "generations (and at the last)  [default: 5]")  # fmt: skip
@click.option("--validation-samples", type=click.IntRange(min=1),
              help="--randomize: validation robots, seeded apart from the training draws "
              "[default: 64]")  # fmt: skip
@click.option("--train-timestep", type=click.FloatRange(0, 0.01, min_open=True), metavar="S",
              help="--randomize: the physics step of the training draws (validation and best.json "
              "stay at the robot's timestep; docs/robot.md 'Timestep fidelity'; the robot's "
              "step or finer: train at the robot's)  [default: 0.003]")  # fmt: skip
@click.option("--randomize-box", type=click.Path(dir_okay=False), metavar="FILE",
              help="--randomize: draw the robots from this robot file's [uncertain] table "
              "instead of the robot's own (e.g. the hard corner of its ranges; robot values in "
              "FILE must be the robot's), and the robot keeps its own uncertainty for sensitivity "
              "and reports "
              "[default: the robot's]")  # fmt: skip
@click.option("--init", type=click.Path(dir_okay=False), metavar="C.json",
              help="Start from this controller of MODEL instead of a random population: row 0 "
              "is it, the others copies mutated with P_M (recorded: file, hash).")  # fmt: skip
@click.option("--quiet", "-q", is_flag=True, help="No progress bar or summary.")
@click.pass_context
def command(
    ctx: click.Context,
    model: str | None,
    out: str | None,
    resume: str | None,
    force: bool,
    workers: int | None,
    cluster: str | None,
    quiet: bool,
    **options: Any,
) -> None:
    """Evolve a MODEL controller (ca1d, ca2dsing, ca2ddiff, nnsig, nnsin) with the paper's GA.

    Fitness is the disc's displacement after MAX_TRANS transitions (eq. 6, shown in cm). The
    run directory gets best.json (a controller file), history.csv and a checkpoint after every
    generation; Ctrl-C stops cleanly and `--resume DIR` continues to the same result.

    --robust scores a candidate over its n leg rotations; --coevolve-faults scores hosts against
    a co-evolving population of module failures (paper §6). See docs/evolution.md.
    """
    # only what the user typed: a default must not count as a different setting on --resume
    given = {
        name: value
        for name, value in options.items()
        if ctx.get_parameter_source(name) is not ParameterSource.DEFAULT
    }
    given["coevolve_faults"] = bool(given.get("coevolve_faults"))
    plan: Plan
    if resume is not None:
        if out is not None and Path(out) != Path(resume):
            raise InputError("give either --out DIR (new run) or --resume DIR, not both")
        if force:
            raise InputError("--force only applies to a new run (--out DIR)")
        given.pop("period", None)
        if given.pop("init", None) is not None:
            raise InputError("--init only applies to a new run", hint="drop --init with --resume")
        extra = _randomize_given(given)
        plan = plan_resume(resume, {**given, **extra, "model": model})  # --timing: by sha256
    else:
        model = opt.check_model(model)
        if out is None:
            raise InputError("missing --out DIR", hint="the run directory to write results to")
        fitness = given.pop("fitness", opt.default("fitness"))
        stamp_timed = bool(given.pop("stamp_timed", False))
        period = given.pop("period", None)
        timing = given.pop("timing", None)
        builds = given.pop("schedule_builds", None)
        robot = given.pop("robot", None)
        init = given.pop("init", None)
        randomize = {k: given.pop(k, None) for k in _RANDOMIZE_OPTIONS}
        plan = plan_new(model, opt.ga_params(model, **given), fitness=fitness, out=out,
                        force=force, stamp_timed=stamp_timed, period=period,
                        timing=timing, schedule_builds=builds, robot=robot,
                        randomize=bool(randomize.pop("randomize")), init=init,
                        **randomize)  # fmt: skip
    _run(plan, workers, cluster, quiet)


_RANDOMIZE_OPTIONS = (
    "randomize",
    "randomize_samples",
    "randomize_score",
    "validate_every",
    "validation_samples",
    "train_timestep",
    "randomize_box",
)


def _randomize_given(given: dict[str, Any]) -> dict[str, Any]:
    """On --resume: the randomize options typed, as the settings to check against the run's."""
    typed = {k: given.pop(k, None) for k in _RANDOMIZE_OPTIONS}
    flag = bool(typed.pop("randomize"))
    if not flag and all(v is None for v in typed.values()):
        return {}
    if all(v is None for v in typed.values()):
        return {"randomize": True}
    checked = opt.randomize_settings(True, *typed.values())["randomize"]  # each value typed
    keys = dict(zip(_RANDOMIZE_OPTIONS[1:], OPTION_FLAGS, strict=True))  # option -> setting
    return {"randomize": {keys[k]: checked[keys[k]] for k, v in typed.items() if v is not None}}


def _mode(plan: Plan) -> str:
    p = plan.state.params
    if p.robust is not None:
        return f" --robust {p.robust}"
    return f" --coevolve-faults ({p.parasites} parasites)" if p.coevolve_faults else ""


def _run(plan: Plan, workers: int | None, cluster: str | None, quiet: bool) -> None:
    from tqdm import tqdm

    state = plan.state
    bar = tqdm(
        total=state.total_steps,
        initial=state.step,
        desc=f"evolve {state.problem.model}{_mode(plan)}",
        unit="gen",
        file=sys.stderr,
        disable=quiet or not sys.stderr.isatty(),
        dynamic_ncols=True,
    )
    start, paid0 = time.perf_counter(), state.cache.evaluations

    def show(g: Generation) -> None:
        rate = (g.evaluations - paid0) / max(time.perf_counter() - start, 1e-9)
        shown = {
            "gen": f"{g.population}:{g.generation}",
            "best": fitness_text(g.best, g.fitness),
            "mean": fitness_text(g.mean, g.fitness),
            "eval/s": f"{rate:.1f}",
        }
        if g.validation is not None:
            shown["validation"] = fitness_text(g.validation, g.fitness)
        bar.set_postfix(shown, refresh=False)
        bar.update(1)

    schedule = fit_schedule(plan, quiet) if plan.stamp_timed else None
    try:
        result = execute(
            plan,
            workers=workers,
            cluster=cluster,
            on_generation=show,
            schedule_model=schedule,
            on_notice=lambda message: bar.write(f"warning: {message}", file=sys.stderr),
        )
    except EvolveInterrupted as exc:
        bar.close()
        click.echo(f"{exc} Continue with: {exc.resume_hint}", err=True)
        raise  # bstool.cli.main ends with "Interrupted." and exit status 130
    bar.close()
    if not quiet:
        click.echo(summary(result))


def fit_schedule(plan: Plan, quiet: bool) -> Any:
    """The schedule model a stamp-timed run is scored on, fitted on the twin from builds of
    random controllers of its model (also used by ``bstool campaign``)."""
    from bstool import timingfile
    from hil_mock.schedule_model import REPRESENTATIVES, schedule_model

    state = plan.state
    if not quiet:
        builds = plan.schedule_builds or REPRESENTATIVES
        click.echo(
            f"fitting the schedule model: {builds} builds of random {state.problem.model}"
            " controllers on the twin (a few seconds each)",
            err=True,
        )
    return schedule_model(
        state.problem.model,
        period=plan.period,
        legs=state.problem.legs,
        modules=state.problem.modules,
        timing=None if plan.timing_file is None else timingfile.load(plan.timing_file),
        builds=plan.schedule_builds,
        spec=None if state.robot is None else state.robot.spec,
    )


def summary(result: EvolveResult) -> str:
    """The lines printed after a run; the fitness with its unit (cm: eq. 6 distance)."""
    s = result.stats
    skipped = s["offspring_skipped"] / s["offspring"] if s["offspring"] else 0.0
    what = (
        f"eq. 6 distance after {result.params.transitions} transitions"
        if result.fitness_kind == "physics"
        else "not a distance"
    )
    if result.randomize is not None:
        what = f"{what}, the mean over {result.randomize['validation_samples']} validation robots"
    lines = [
        f"best fitness {result.fitness_text} ({what}) -> {result.best_json}",
        f"evaluations {s['evaluations']}, cache hits {s['cache_hits']}, "
        f"offspring skipped {s['offspring_skipped']}/{s['offspring']} ({skipped:.1%})",
    ]
    if result.worst_parasite is not None:
        last = next(r for r in reversed(result.history) if r.population == "parasite")
        cells = " ".join(f"{i}.{j}" for i, j in result.worst_parasite)
        lines.append(
            f"most harmful parasite: {cells} failed "
            f"(takes {last.best:.1%} of the hosts' distance on average)"
        )
    return "\n".join(lines)
