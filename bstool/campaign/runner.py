"""Running a campaign's evolve runs, one after the other, through the evolve driver
(:func:`~bstool.evolve.driver.plan_new`, :func:`~bstool.evolve.driver.plan_resume`,
:func:`~bstool.evolve.driver.execute`): the same files ``bstool evolve`` writes, in
DIR/runs/MODEL-sSEED.

Everything is checked before the first generation: the campaign folder (a folder holding
another plan's campaign is refused), every run's settings (through the driver's own checks)
and every run folder already there (its checkpoint must record the plan's settings). A run
already finished is kept, an interrupted one resumed from its checkpoint, a missing one
started; a resumed run reaches the files of an uninterrupted one (docs/evolution.md).
"""

from __future__ import annotations

import inspect
import os
import shlex
import time
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bstool import fileio, outputs
from bstool.campaign import plan as cp
from bstool.campaign import record as rec
from bstool.errors import InputError
from bstool.evolve import options as opt
from bstool.evolve.checkpoint import is_run, load_checkpoint
from bstool.evolve.driver import EvolveResult, Generation, Plan, execute, plan_new, plan_resume

RUNS = "runs"
ScheduleFor = Callable[[Plan], Any]
"""The schedule model a stamp-timed run is evaluated on (the command fits it on the twin)."""

_GA_KEYWORDS = frozenset(inspect.signature(opt.ga_params).parameters) - {"model", "seed"}
_PLAN_KEYWORDS = frozenset(inspect.signature(plan_new).parameters) - {
    "model",
    "params",
    "out",
    "force",
}


def keywords(
    spec: cp.RunSpec, settings: Mapping[str, cp.Setting]
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The run's settings as keywords of ``options.ga_params`` and of ``driver.plan_new``.

    Which function takes a setting is read from their signatures, so an option evolve gains
    reaches the driver without a list here; one that neither takes is an error, not ignored.
    """
    ga: dict[str, Any] = {}
    new: dict[str, Any] = {}
    for key, value in spec.settings.items():
        name = settings[key].name if key in settings else key.replace("-", "_")
        if name in _GA_KEYWORDS:
            ga[name] = value
        elif name in _PLAN_KEYWORDS:
            new[name] = value
        else:
            raise InputError(
                f"the campaign cannot pass --{key} of {spec.name} to the evolve driver "
                "(neither options.ga_params nor driver.plan_new takes it)",
                hint="run that setting with bstool evolve, or teach bstool.campaign.runner",
            )
    return ga, new


def build_plan(spec: cp.RunSpec, settings: Mapping[str, cp.Setting], out: Path | None) -> Plan:
    """The driver's plan of a new run (``out=None``: checked only, nothing written)."""
    ga, new = keywords(spec, settings)
    params = opt.ga_params(spec.model, seed=spec.seed, **ga)
    return plan_new(spec.model, params, out=out, **new)


def command_line(spec: cp.RunSpec, folder: Path, settings: Mapping[str, cp.Setting]) -> str:
    """The ``bstool evolve`` command equal to the run (the plan's settings, in its order)."""
    words = ["bstool", "evolve", spec.model]
    for key, value in spec.settings.items():
        s = settings.get(key)
        if s is not None and s.flag:
            if value:
                words.append(f"--{key}")
            continue
        words += [f"--{key}", str(value)]
    words += ["--seed", str(spec.seed), "--out", str(folder)]
    return " ".join(shlex.quote(w) for w in words)


@dataclass
class Run:
    """One run of the campaign, checked: what is in its folder and what will be done."""

    spec: cp.RunSpec
    folder: Path
    expected: Plan  # the driver's plan of the run as the plan says (never executed)
    steps_done: int  # generations saved in the folder (0: none yet)
    command: str

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def total_steps(self) -> int:
        return self.expected.state.total_steps

    @property
    def done(self) -> bool:
        return self.steps_done >= self.total_steps


def _compare(found: Mapping[str, Any], want: Mapping[str, Any], run: str, folder: Path) -> None:
    """Refuse a run folder whose checkpoint records other settings than the plan's."""
    for key in dict.fromkeys([*want, *found]):
        a, b = found.get(key), want.get(key)
        if key == "timing" and a is not None and b is not None:
            a, b = a.get("sha256"), b.get("sha256")
        if key == "gens" and a is not None and b is not None and a <= b:
            continue  # the plan may raise --gens: the run is extended (docs/campaign.md)
        if a != b:
            what = "MODEL" if key == "model" else opt.flag(key)
            raise InputError(
                f"run {run} ({folder}) was started with {what} {a!r}, but the plan says {b!r}",
                hint="the folder belongs to another plan: move it away (the campaign then "
                "evolves the run again), or change the plan to the run's settings",
            )


def check_runs(
    folder: Path, plan: cp.CampaignPlan, settings: Mapping[str, cp.Setting]
) -> list[Run]:
    """Every run of the plan, checked before any work (seed-major order)."""
    runs = []
    for spec in plan.runs():
        where = folder / RUNS / spec.name
        try:
            expected = build_plan(spec, settings, None)
        except InputError as exc:
            raise InputError(
                f"plan: the settings of {spec.name}: {exc.message}",
                hint=exc.hint or "fix [evolve] or [evolve." + spec.model + "] in the plan",
            ) from None
        steps = 0
        if where.is_dir():
            outputs.clean_stale(where / "checkpoint.npz")
            if is_run(where):
                state, extra = load_checkpoint(where)
                want = opt.saved_settings(expected.state, expected.extra)
                _compare(opt.saved_settings(state, extra), want, spec.name, where)
                steps = state.step
            elif any(where.iterdir()):
                raise InputError(
                    f"{where} is not empty and holds no run of bstool evolve",
                    hint="move it away; the campaign then evolves the run there",
                )
        elif where.exists():
            raise InputError(f"{where} is a file, not a run folder", hint="move it away")
        runs.append(Run(spec, where, expected, steps, command_line(spec, where, settings)))
    return runs


def check_folder(folder: Path, plan: cp.CampaignPlan, settings: Mapping[str, cp.Setting]) -> bool:
    """Whether ``folder`` already holds this plan's campaign (True) or is new or empty (False);
    a folder with another plan's campaign, or with other content, is refused."""
    if folder.exists() and not folder.is_dir():
        raise InputError(f"campaign folder {folder} is a file", hint="choose a folder")
    if not folder.is_dir() or not any(folder.iterdir()):
        outputs.check_dir(folder, "campaign folder")
        return False
    recorded = folder / cp.PLAN_FILE
    if not recorded.is_file():
        raise InputError(
            f"{folder} is not empty and holds no campaign ({recorded} is missing)",
            hint="choose a new or empty folder for -o",
        )
    try:
        theirs = cp.load(recorded, settings)
    except InputError as exc:
        raise InputError(
            f"{folder} holds a campaign whose plan cannot be read: {exc.message}",
            hint=exc.hint or "choose another folder for -o",
        ) from None
    diff = cp.differences(theirs, plan)
    if diff:
        raise InputError(
            f"{folder} holds the campaign of another plan ({recorded}): "
            + "; ".join(diff[:3])
            + (f"; and {len(diff) - 3} more" if len(diff) > 3 else ""),
            hint=f"continue it with `bstool campaign {recorded} -o {folder}`, or choose "
            "another -o (to change a campaign on purpose, edit its plan.toml)",
        )
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"cannot write in the campaign folder {folder}")
    return True


def adopt(record: rec.Record, runs: list[Run]) -> None:
    """Note the generations found in run folders the campaign has not evolved itself (a
    folder written by ``bstool evolve`` before the campaign adopted it)."""
    for run in runs:
        r = record.runs.get(run.name)
        if r is None:
            r = record.run(run.name)
            r.adopted_steps = run.steps_done
        r.command = run.command
        r.total_steps = run.total_steps


@dataclass
class Events:
    """What the runner tells its caller (the command draws its progress from these)."""

    run_started: Callable[[Run, int], None] = lambda run, index: None
    generation: Callable[[Run, Generation], None] = lambda run, g: None
    run_ended: Callable[[Run, EvolveResult, float], None] = lambda run, result, s: None


def evolve_all(
    folder: Path,
    runs: list[Run],
    record: rec.Record,
    settings: Mapping[str, cp.Setting],
    *,
    workers: int | None = None,
    cluster: Any = None,
    schedule_for: ScheduleFor | None = None,
    events: Events | None = None,
    on_notice: Callable[[str], None] | None = None,
) -> None:
    """Evolve every run that is not finished, in order; the record is saved after each run
    (and on Ctrl-C, which raises ``EvolveInterrupted`` with the run saved and resumable)."""
    ev = events or Events()
    for index, run in enumerate(runs):
        if run.done:
            continue
        if not is_run(run.folder):  # new, or an empty folder
            driver_plan = build_plan(run.spec, settings, run.folder)
        else:
            given: dict[str, Any] = {"gens": run.expected.state.params.gens}
            timing = run.spec.settings.get("timing")
            if timing is not None:
                given["timing"] = timing
            driver_plan = plan_resume(run.folder, given)
        schedule = None
        if driver_plan.stamp_timed:
            if schedule_for is None:
                raise InputError(f"{run.name} is stamp-timed but no schedule model was given")
            schedule = schedule_for(driver_plan)
        ev.run_started(run, index)
        entry = record.run(run.name)
        start = time.monotonic()
        before = driver_plan.state.step

        def generation(g: Generation, run: Run = run) -> None:
            ev.generation(run, g)

        try:
            result = execute(
                driver_plan,
                workers=workers,
                cluster=cluster,
                on_generation=generation,
                schedule_model=schedule,
                on_notice=on_notice,
            )
        finally:
            entry.wall_s += time.monotonic() - start
            entry.steps += driver_plan.state.step - before
            run.steps_done = driver_plan.state.step
            if run.done:
                entry.finished = rec.now()
            rec.save(folder, record)
        ev.run_ended(run, result, time.monotonic() - start)


def write_plan(folder: Path, text: str) -> None:
    """DIR/plan.toml: a copy of the plan the campaign was started with."""
    fileio.write_text(folder / cp.PLAN_FILE, text)


def run_folders(folder: Path) -> Path:
    return folder / RUNS


def is_campaign(folder: str | os.PathLike[str]) -> bool:
    """A folder ``bstool campaign`` made (or adopted): its plan.toml declares the campaign
    format and it has run folders or a record (a folder merely holding a plan is not one)."""
    d = Path(folder)
    if not ((d / RUNS).is_dir() or (d / rec.RECORD_FILE).is_file()):
        return False
    try:
        text = cp.read_text(d / cp.PLAN_FILE)
    except InputError:
        return False
    try:
        return tomllib.loads(text).get("format") == cp.FORMAT
    except tomllib.TOMLDecodeError:
        return False
