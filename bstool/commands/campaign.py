"""``bstool campaign PLAN.toml -o DIR``: every evolve run of a plan, its analyses and the
report (docs/campaign.md); running it again continues where it stopped."""

from __future__ import annotations

import shlex
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from bstool.campaign import plan as cp

#: evolve's options that are not settings of a run (the campaign sets or takes them)
NOT_SETTINGS = ("out", "resume", "force", "workers", "cluster", "quiet", "seed")


def _long_name(option: click.Option) -> str:
    return next(o for o in option.opts if o.startswith("--"))[2:]


def _setting(option: click.Option) -> cp.Setting:
    """A plan key from one of evolve's click options: its TOML types from the option's type,
    its check the option's own conversion (ranges, choices), so the plan refuses what the
    command line refuses."""
    kind = option.type
    if option.is_flag:
        return cp.Setting(_long_name(option), str(option.name), (bool,), bool, flag=True)
    types: tuple[type, ...] = (str,)
    if isinstance(kind, click.types.IntParamType):
        types = (int,)
    elif isinstance(kind, click.types.FloatParamType):
        types = (int, float)

    def convert(value: Any) -> Any:
        try:
            return kind.convert(value, option, None)
        except click.BadParameter as exc:
            raise ValueError(exc.message) from None

    return cp.Setting(_long_name(option), str(option.name), types, convert)


def evolve_settings() -> dict[str, cp.Setting]:
    """The plan's ``[evolve]`` keys: ``bstool evolve``'s long options, less those that are not
    settings of a run."""
    from bstool.commands.evolve import command as evolve

    out = {}
    for p in evolve.params:
        if isinstance(p, click.Option) and p.name not in NOT_SETTINGS:
            s = _setting(p)
            out[s.key] = s
    return out


def analysis_schedule(controller: Any, period: float | None) -> Any:
    """The schedule model a stamp-timed run's analyses play it on (as ``report --stamp-timed``)."""
    from bstool import timingfile
    from bstool.campaign.analyses import robot_of
    from bstool.commands.simulate_model import evolved_builds, evolved_timing
    from hil_mock.schedule_model import schedule_model

    c = controller
    spec = robot_of(c).spec
    timing_file = evolved_timing(c, "the run's best.json")
    timing = None if timing_file is None else timingfile.load(timing_file)
    return schedule_model(c.model, period=period, legs=c.legs, modules=c.modules, spec=spec,
                          timing=timing, builds=evolved_builds(c))  # fmt: skip


@click.command("campaign")
@click.argument("plan_file", metavar="PLAN.toml", type=click.Path(dir_okay=False))
@click.option(
    "-o",
    "--out",
    required=True,
    type=click.Path(file_okay=False),
    help="Campaign folder: DIR/plan.toml (a copy of the plan), DIR/runs/MODEL-sSEED (one "
    "evolve run each), DIR/analyses, DIR/report. Give the same folder again to continue.",
)
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    help="Physics threads [default: the usable CPUs; 1 per Dask thread with --cluster].",
)
@click.option(
    "--cluster",
    metavar="ADDRESS",
    help="Evaluate the runs on a Dask scheduler, e.g. tcp://host:8786 (the analyses stay local).",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress bar or messages.")
def command(
    plan_file: str, out: str, workers: int | None, cluster: str | None, quiet: bool
) -> None:
    """Run the campaign of PLAN.toml in DIR: one `bstool evolve` run per model and seed
    (seed-major: all models of a seed, then the next), then the plan's analyses on each run
    and DIR/report/index.html with the paper's claims tested over the seeds.

    Running the same command again continues: finished runs are kept, an interrupted one
    resumes from its checkpoint, and nothing is computed twice. A folder holding another
    plan's campaign, or a run folder whose settings are not the plan's, is refused. Ctrl-C
    stops resumably. The plan's format: docs/campaign.md (examples/campaign-small.toml).

    Example: bstool campaign examples/paper.toml -o campaigns/paper --workers 2
    """
    from bstool.campaign import record as rec
    from bstool.campaign import runner
    from bstool.experiments import progress

    settings = evolve_settings()
    text = cp.read_text(plan_file)
    plan = cp.parse(text, settings, plan_file)
    folder = Path(out)
    existing = runner.check_folder(folder, plan, settings)
    runner.check_runs(folder, plan, settings)  # everything is checked before the folder
    folder.mkdir(parents=True, exist_ok=True)
    words = ["bstool", "campaign", plan_file, "-o", out]
    words += [] if workers is None else ["--workers", str(workers)]
    words += [] if cluster is None else ["--cluster", cluster]
    resume_hint = f"continue with: {shlex.join(words)}"
    say = _messages(quiet)
    with rec.lock(folder):
        if not existing:
            runner.write_plan(folder, text)
        runs = runner.check_runs(folder, plan, settings)
        record = rec.load(folder)
        runner.adopt(record, runs)
        for old in record.sessions:  # the lock was free: a session still "running" was killed
            if old.outcome == "running":
                old.outcome = "killed"
        session = rec.Session(shlex.join(words), rec.now())
        record.sessions.append(session)
        rec.save(folder, record)
        start = time.monotonic()

        def checkpoint() -> None:  # after each run: a killed session keeps its time
            session.ended = rec.now()
            session.wall_s = time.monotonic() - start
            rec.save(folder, record)

        try:
            _evolve(folder, runs, record, settings, workers, cluster, quiet, say, checkpoint)
            with progress.bar("analyses", None, quiet=quiet) as bar:
                index = _report(folder, plan, settings, workers, quiet, bar, say, checkpoint)
            session.outcome = "finished"
        except KeyboardInterrupt as exc:
            session.outcome = "interrupted"
            what = str(exc) or "Interrupted; the runs, analyses and record so far are kept."
            click.echo(f"{what} The campaign can {resume_hint}", err=True)
            raise
        except BaseException:
            session.outcome = "failed"
            raise
        finally:
            session.ended = rec.now()
            session.wall_s = time.monotonic() - start
            rec.save(folder, record)
    click.echo(f"report: {index}")


def _messages(quiet: bool) -> Callable[[str], None]:
    def say(text: str) -> None:
        if not quiet:
            click.echo(text, err=True)

    return say


def _evolve(
    folder: Path,
    runs: list[Any],
    record: Any,
    settings: dict[str, cp.Setting],
    workers: int | None,
    cluster: str | None,
    quiet: bool,
    say: Callable[[str], None],
    checkpoint: Callable[[], None],
) -> None:
    from tqdm import tqdm

    from bstool.campaign import pace, runner
    from bstool.commands.evolve import fit_schedule
    from bstool.evolve.driver import EvolveResult, Generation, fitness_text
    from bstool.experiments import progress

    todo = [r for r in runs if not r.done]
    finished = len(runs) - len(todo)
    if not todo:
        say(f"campaign: all {len(runs)} runs are finished")
        return
    say(
        f"campaign: {finished} of {len(runs)} runs finished; evolving {len(todo)} "
        f"({', '.join(r.name for r in todo[:4])}{', ...' if len(todo) > 4 else ''})"
    )
    bar = tqdm(
        total=sum(r.total_steps for r in runs),
        initial=sum(min(r.steps_done, r.total_steps) for r in runs),
        desc="campaign",
        unit="gen",
        file=sys.stderr,
        disable=not progress.enabled(quiet),
        dynamic_ncols=True,
    )
    count = {"done": finished}
    models = {r.name: r.spec.model for r in runs}
    clock = {"start": time.monotonic(), "made": 0}

    def left(current: runner.Run, step: int) -> str:
        """Time left at each model's pace so far (this session's mean pace before any)."""
        remaining = {r.name: r.total_steps - min(r.steps_done, r.total_steps) for r in runs}
        remaining[current.name] = current.total_steps - step
        made = clock["made"]
        fallback = (time.monotonic() - clock["start"]) / made if made else None
        return pace.text(pace.seconds_left(remaining, models, pace.per_model(models, record),
                                           fallback))  # fmt: skip

    def started(run: runner.Run, index: int) -> None:
        bar.set_description(f"campaign {count['done']}/{len(runs)} runs, {run.name}")
        if bar.disable:
            say(
                f"campaign: {run.name} ({index + 1} of {len(runs)}) from generation "
                f"{run.steps_done} of {run.total_steps}"
            )

    def generation(run: runner.Run, g: Generation) -> None:
        clock["made"] += 1
        best = fitness_text(g.best_so_far, g.fitness)
        remaining = left(run, g.step)
        bar.set_postfix(
            {"gen": f"{g.step}/{g.total_steps}", "best": best, "left": remaining}, refresh=False
        )
        bar.update(1)
        if bar.disable and g.step % PROGRESS_EVERY == 0 and g.step < g.total_steps:
            say(
                f"campaign: {run.name} generation {g.step} of {g.total_steps}, best {best}; "
                f"about {remaining} left ({count['done']} of {len(runs)} runs finished)"
            )

    def ended(run: runner.Run, result: EvolveResult, seconds: float) -> None:
        checkpoint()
        count["done"] += 1
        line = (
            f"campaign: {run.name} finished in {seconds / 60:.1f} min, best "
            f"{result.fitness_text} ({count['done']} of {len(runs)} runs)"
        )
        if bar.disable:
            say(line)
        elif not quiet:
            bar.write(line, file=sys.stderr)

    try:
        runner.evolve_all(
            folder,
            runs,
            record,
            settings,
            workers=workers,
            cluster=cluster,
            schedule_for=lambda p: fit_schedule(p, quiet),
            events=runner.Events(started, generation, ended),
            on_notice=lambda message: bar.write(f"warning: {message}", file=sys.stderr),
        )
    finally:
        bar.close()


#: without a progress bar (a log file), a line every this many generations of a run
PROGRESS_EVERY = 10


def _report(
    folder: Path,
    plan: cp.CampaignPlan,
    settings: dict[str, cp.Setting],
    workers: int | None,
    quiet: bool,
    bar: Any,
    say: Callable[[str], None],
    checkpoint: Callable[[], None],
) -> Path:
    from bstool.campaign import analyses
    from bstool.campaign import report as creport
    from bstool.experiments import progress

    last = {"run": ""}

    def describe(text: str) -> None:
        if progress.enabled(quiet):
            bar.describe(text)
            return
        run = text.split(":")[0]
        if run != last["run"]:  # a log gets one line per run
            last["run"] = run
            say(f"... analyses of {run}" if ":" in text else f"... {text}")

    return creport.build(
        folder,
        plan,
        settings,
        workers=workers,
        schedule_for=analysis_schedule,
        progress=analyses.Progress(bar.total, bar, describe),
        analysed=checkpoint,  # the report shows the wall time up to its writing
    )
