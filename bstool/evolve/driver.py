"""Running an evolution from Python or the CLI: check the run folder, build the evaluator,
save after every generation, report progress to a callback, and stop resumably on Ctrl-C.

No printing, no click, no ``sys.exit``: ``bstool evolve`` draws its progress bar and summary
from the same :class:`Generation` and :class:`EvolveResult` a notebook gets.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bstool import outputs
from bstool.controllers import Controller
from bstool.cpus import usable_cpus
from bstool.errors import InputError
from bstool.evolve import options as opt
from bstool.evolve.checkpoint import (
    BEST,
    CHECKPOINT,
    HISTORY,
    is_run,
    load_checkpoint,
    save_outputs,
)
from bstool.evolve.engine import GAParams, HistoryRow, RunState, new_run, run
from bstool.evolve.fitness import (
    Evaluator,
    EvaluatorFactory,
    PhysicsFitness,
    StampTimedFitness,
    ToyFitness,
)
from bstool.evolve.problem import Problem

if TYPE_CHECKING:
    from bstool.robot.robotfile import Robot
    from bstool.sim.timed import ScheduleSource


def fitness_text(value: float, kind: str) -> str:
    """A fitness for people: physics in cm (eq. 6 distance, as the plots), toy unit-less."""
    if kind == "physics":
        return f"{value * 100:.2f} cm"
    return f"{value:.4g} (toy units)"


@dataclass(frozen=True)
class Generation:
    """What ``on_generation`` receives after every evaluated generation (a history row)."""

    population: str  # "main"; "leg"/"control" (ca2ddiff); "host" (--coevolve-faults)
    generation: int  # index within that population
    best: float  # best fitness of the generation (metres with physics)
    mean: float
    paid: int  # simulations this generation cost (cache misses)
    evaluations: int  # simulations paid by the run so far
    step: int  # generations evaluated so far, all populations
    total_steps: int
    best_so_far: float  # the fitness of best.json now
    fitness: str  # "physics" | "toy"
    parasite: HistoryRow | None = None  # --coevolve-faults: the parasites' row
    validation: float | None = None  # --randomize: the best's validation mean, when measured


@dataclass(frozen=True)
class EvolveResult:
    """The outcome of :func:`evolve` / :func:`resume` (also of an interrupted run)."""

    model: str
    controller: Controller | None  # the best so far (None before the first generation)
    fitness: float  # its fitness (metres with physics; see ``fitness_kind``)
    fitness_kind: str
    history: tuple[HistoryRow, ...]
    params: GAParams
    path: Path | None  # the run folder (None: out=None, nothing written)
    completed: bool
    stats: dict[str, int] = field(default_factory=dict)
    worst_parasite: tuple[tuple[int, int], ...] | None = None  # --coevolve-faults: L.M cells
    randomize: dict[str, Any] | None = None  # --randomize: its settings (fitness = validation)

    @property
    def best_json(self) -> Path | None:
        return None if self.path is None else self.path / BEST

    @property
    def fitness_text(self) -> str:
        return fitness_text(self.fitness, self.fitness_kind)


class EvolveInterrupted(KeyboardInterrupt):
    """Ctrl-C during a run: everything up to the last finished generation is saved.

    A :class:`KeyboardInterrupt`, so a notebook cell or script stops as usual; ``result``
    holds the partial :class:`EvolveResult`, ``resume_hint`` how to continue.
    """

    def __init__(self, result: EvolveResult) -> None:
        self.result = result
        step = result.stats.get("saved_step" if result.path else "step", 0)
        done = f"after {step} of {result.stats.get('total_steps', 0)}"
        if result.path is None:
            msg = f"interrupted {done} generations; nothing saved (out=None)"
            self.resume_hint = "give out=DIR to make a run resumable"
        else:
            msg = f"Interrupted {done} generations; everything so far is saved in {result.path}."
            self.resume_hint = f"bstool evolve --resume {result.path}"
        super().__init__(msg)


@dataclass
class Plan:
    """A checked run, not started: its state, settings and where it goes."""

    state: RunState
    extra: dict[str, Any]  # saved with the checkpoint: {"fitness": kind}
    directory: Path | None
    fresh: bool  # a new run: save once before the first generation
    replace: bool = False  # the folder exists with other content (--force): swap it whole
    saved_step: int | None = None  # the step the folder's checkpoint holds (None: not yet)
    timing_file: str | None = None
    """``--timing`` of a stamp-timed run: the bstool.timing/1 file to fit the schedule model
    with (its sha256 is in ``extra["timing"]``; None: the timing estimate)."""

    @property
    def fitness(self) -> str:
        return str(self.extra.get("fitness", "physics"))

    @property
    def stamp_timed(self) -> bool:
        """Candidates run stamp-timed (``--stamp-timed``: a ScheduleModel is needed)."""
        return bool(self.extra.get("stamp_timed"))

    @property
    def schedule_builds(self) -> int:
        """``--schedule-builds`` of a stamp-timed run (0: not given, one model averaged over
        two builds)."""
        return int(self.extra.get("schedule_builds", 0))

    @property
    def randomized(self) -> bool:
        return self.extra.get("randomize") is not None

    @property
    def period(self) -> float | None:
        """``--period`` of a stamp-timed run (None: compile's default)."""
        value = self.extra.get("period")
        return None if value is None else float(value)


def check_out(out: str | os.PathLike[str], *, force: bool = False) -> tuple[Path, bool]:
    """Check a new run's folder before any work; (path, must replace existing content).

    A non-empty folder is refused unless ``force``: with the hint to resume when it is an
    evolve run (its checkpoint's format says so), else to pick another folder. ``force``
    never replaces the current folder or one containing it.
    """
    p = Path(out)
    if not force and is_run(p):
        raise InputError(
            f"{p} already holds a run of bstool evolve",
            hint=f"continue it with --resume {p}, choose another --out, "
            "or add --force to start a new run in its place",
        )
    if force:
        here = Path.cwd().resolve()
        if p.resolve() == here or p.resolve() in here.parents:
            raise InputError(
                f"--force would replace {p}: it is the current folder or contains it",
                hint="give a run folder inside the current one",
            )
    outputs.check_dir(p, "run folder", force=force, ours=is_run)
    return p, p.is_dir() and any(p.iterdir())


def plan_new(
    model: str,
    params: GAParams,
    *,
    fitness: str = "physics",
    out: str | os.PathLike[str] | None = None,
    force: bool = False,
    stamp_timed: bool = False,
    period: float | None = None,
    timing: str | os.PathLike[str] | None = None,
    schedule_builds: int | None = None,
    robot: Any = None,
    randomize: bool = False,
    randomize_samples: int | None = None,
    randomize_score: str | None = None,
    validate_every: int | None = None,
    validation_samples: int | None = None,
    train_timestep: float | None = None,
    randomize_box: str | os.PathLike[str] | Robot | None = None,
    init: str | os.PathLike[str] | None = None,
) -> Plan:
    """A new run, checked; ``robot``: a robot file (or ``bstool.robot.robotfile.Robot``),
    recorded by value; ``randomize``: score on random robots (docs/evolution.md)."""
    from bstool.evolve.randomize import Randomize

    kind = opt.check_fitness(fitness)
    extra: dict[str, Any] = {"fitness": kind}
    extra.update(opt.stamp_timed_settings(kind, stamp_timed, period, timing, schedule_builds))
    extra.update(
        opt.randomize_settings(
            randomize,
            randomize_samples,
            randomize_score,
            validate_every,
            validation_samples,
            train_timestep,
            randomize_box,
        )
    )
    loaded, record = opt.robot_settings(robot)
    extra.update(record)
    if "randomize" in extra:
        from bstool.robot.robotfile import Robot

        box = Randomize.from_json(extra["randomize"]).training_box(loaded or Robot())
        opt.check_box_robot(randomize_box, loaded or Robot())
        if loaded is not None and not box.ranges:
            raise InputError(
                f"--randomize: {loaded.source} has an empty [uncertain] table, so every robot "
                "drawn would be the nominal one",
                hint="give the table some ranges, or drop it for the default box, or evolve "
                "without --randomize",
            )
    directory, replace = (None, False) if out is None else check_out(out, force=force)
    problem = Problem(opt.check_model(model), transitions=params.transitions)
    file = None if timing is None else str(timing)
    start = None
    if init is not None:
        from bstool.controllers import load_controller

        ctrl = load_controller(init)
        if ctrl.model != problem.model:
            raise InputError(
                f"--init {init} is a {ctrl.model} controller, not {problem.model}",
                hint=f"give a {problem.model} controller, or evolve {ctrl.model}",
            )
        start = problem.chromosomes(ctrl)
        extra["init"] = {"file": str(init), "controller_hash": ctrl.hash()}
    state = new_run(problem, params, start)
    state.robot = loaded
    if "randomize" in extra:
        state.randomize = Randomize.from_json(extra["randomize"])
    return Plan(state, extra, directory, True, replace, timing_file=file)


def plan_resume(directory: str | os.PathLike[str], given: Mapping[str, Any]) -> Plan:
    """Load the run in ``directory``, check ``given`` against it, remove what a killed writer
    left there (temporaries of best.json, history.csv, the checkpoint, a swapped folder)."""
    state, extra = load_checkpoint(directory)
    given = dict(given)
    timing = given.pop("timing", None)
    opt.check_resume(state, extra, directory, given)
    timing_file = opt.resume_timing(extra, timing, directory)
    d = Path(directory)
    for name in (BEST, HISTORY, CHECKPOINT):
        outputs.clean_stale(d / name)
    outputs.clean_stale(d)
    return Plan(state, extra, d, False, saved_step=state.step, timing_file=timing_file)


def factory_for(
    kind: str,
    problem: Problem,
    workers: int,
    schedule_model: ScheduleSource | None = None,
    spec: Any = None,
) -> EvaluatorFactory:
    """The run's evaluator factory; ``spec``: the nominal robot (None: the default one)."""
    if kind == "toy":
        return ToyFitness()
    if schedule_model is not None:
        return StampTimedFitness(schedule_model, problem.legs, problem.modules, workers, spec)
    return PhysicsFitness(legs=problem.legs, modules=problem.modules, workers=workers, spec=spec)


def result_of(plan: Plan) -> EvolveResult:
    from bstool.evolve.scoring import parasite_cells

    st = plan.state
    worst = None
    if st.parasites is not None:
        worst = tuple(parasite_cells(st.parasites[0], st.problem.modules))
    saved = st.step if plan.saved_step is None else plan.saved_step
    stats = {**st.stats(), "step": st.step, "total_steps": st.total_steps, "saved_step": saved}
    return EvolveResult(
        model=st.problem.model,
        controller=st.best_controller(),
        fitness=(
            st.validated.validation
            if st.validated is not None
            else st.best_fitness
            if st.best_row is not None
            else float("nan")
        ),
        fitness_kind=plan.fitness,
        history=tuple(st.history),
        params=st.params,
        path=plan.directory,
        completed=st.done,
        stats=stats,
        worst_parasite=worst,
        randomize=plan.extra.get("randomize"),
    )


def _check_builds(builds: int, schedule_model: Any) -> None:
    """The schedule model must be the one the run records (its fitness replays on it)."""
    have = len(getattr(schedule_model, "variants", ()))
    if have != builds:
        what = f"an ensemble of {have} builds" if have else "one model (two builds' mean)"
        want = f"{builds} builds" if builds else "one model (two builds' mean)"
        raise InputError(
            f"this run is evaluated on {want}, but the schedule model given is {what}",
            hint=f"pass schedule_model(model, period=..., builds={builds})",
        )


def execute(
    plan: Plan,
    *,
    workers: int | None = None,
    cluster: Any = None,
    on_generation: Callable[[Generation], None] | None = None,
    schedule_model: ScheduleSource | None = None,
    on_notice: Callable[[str], None] | None = None,
) -> EvolveResult:
    """Run ``plan`` to its end. Physics uses ``workers`` threads (default: the usable CPUs;
    1 per Dask thread with ``cluster``, an address or a ``dask.distributed.Client``).
    ``on_notice`` gets what a run has to say while it waits (a cluster with no workers;
    default: a ``RuntimeWarning``).
    A stamp-timed plan needs ``schedule_model`` (``hil_mock.schedule_model.schedule_model``
    of the plan's model and period: ``bstool evolve --stamp-timed`` derives it)."""
    state = plan.state
    threads = opt.check_workers(workers) or (1 if cluster else usable_cpus())
    if plan.stamp_timed and schedule_model is None:
        raise InputError(
            "this run is stamp-timed but no schedule model was given",
            hint="run it with `bstool evolve --stamp-timed`, or pass schedule_model="
            "hil_mock.schedule_model.schedule_model(model, period=..., builds=...)",
        )
    if plan.stamp_timed:
        _check_builds(plan.schedule_builds, schedule_model)
    spec = None if state.robot is None else state.robot.spec
    sched = schedule_model if plan.stamp_timed else None
    factory = factory_for(plan.fitness, state.problem, threads, sched, spec)
    validator_factory = None
    if state.randomize is not None and state.randomize.train_timestep is not None:
        # training on a coarser step; validation (best.json's fitness) at the robot's own
        from bstool.robot import RobotSpec

        nominal = spec if spec is not None else RobotSpec()
        coarse = state.randomize.training_spec(nominal)
        if coarse is not nominal:
            validator_factory = factory
            factory = factory_for(plan.fitness, state.problem, threads, sched, coarse)

    def build(f: EvaluatorFactory) -> Evaluator:
        if cluster:
            from bstool.evolve.cluster import DaskEvaluator

            return DaskEvaluator(cluster, f, notify=on_notice)
        return f.build()

    evaluator = build(factory)
    validator = None if validator_factory is None else build(validator_factory)

    def save(st: RunState) -> None:
        if plan.directory is None:
            return
        if plan.replace:
            with outputs.staged_dir(plan.directory) as tmp:
                save_outputs(st, tmp, plan.extra)
            plan.replace = False
        else:
            save_outputs(st, plan.directory, plan.extra)
        plan.saved_step = st.step

    def after_step(st: RunState, row: HistoryRow) -> None:
        save(st)
        if on_generation is not None:
            parasite = st.history[-1] if st.history[-1].population == "parasite" else None
            on_generation(
                Generation(
                    row.population,
                    row.generation,
                    row.best,
                    row.mean,
                    row.evaluations,
                    st.cache.evaluations,
                    st.step,
                    st.total_steps,
                    st.best_fitness,
                    plan.fitness,
                    parasite,
                    row.validation,
                )
            )

    try:
        if plan.fresh:
            save(state)  # the run folder (and a checkpoint) exists from the start
            plan.fresh = False
        run(state, evaluator, after_step, validator)
    except KeyboardInterrupt as exc:
        if isinstance(exc, EvolveInterrupted):
            raise
        raise EvolveInterrupted(result_of(plan)) from None
    finally:
        for ev in (evaluator, validator):
            close = getattr(ev, "close", None)
            if close is not None:
                close()
    return result_of(plan)


def evolve(
    model: str,
    *,
    pop: int | None = None,
    gens: int | None = None,
    pc: float | None = None,
    pm: float | None = None,
    transitions: int | None = None,
    coevol_gens: int | None = None,
    seed: int | None = None,
    robust: str | None = None,
    coevolve_faults: bool = False,
    parasites: int | None = None,
    parasite_k: Any = None,
    fitness: str = "physics",
    workers: int | None = None,
    cluster: Any = None,
    out: str | os.PathLike[str] | None = None,
    force: bool = False,
    on_generation: Callable[[Generation], None] | None = None,
    stamp_timed: bool = False,
    period: float | None = None,
    schedule_model: ScheduleSource | None = None,
    timing: str | os.PathLike[str] | None = None,
    schedule_builds: int | None = None,
    robot: Any = None,
    randomize: bool = False,
    randomize_samples: int | None = None,
    randomize_score: str | None = None,
    validate_every: int | None = None,
    validation_samples: int | None = None,
    train_timestep: float | None = None,
    randomize_box: str | os.PathLike[str] | Robot | None = None,
    init: str | os.PathLike[str] | None = None,
) -> EvolveResult:
    """Evolve a ``model`` controller, as ``bstool evolve`` does (same defaults, same files).

    ``robot``: a robot file or ``bstool.robot.robotfile.Robot`` (``--robot``); ``randomize``
    and the ``randomize_*``/``validat*``/``train_timestep`` keywords: ``--randomize`` and its
    options (``randomize_box``: a robot file or ``Robot`` whose ``[uncertain]`` table is the
    box to train on, apart from the robot's own uncertainty).

    ``stamp_timed=True`` (``--stamp-timed``, ``period`` = ``--period``, ``timing`` =
    ``--timing``, a bstool.timing/1 file recorded by sha256, ``schedule_builds`` =
    ``--schedule-builds``, None: one averaged model) needs the ``schedule_model`` of
    ``model`` at that period and timing (``hil_mock.schedule_model.schedule_model(model,
    period=period, timing=bstool.timingfile.load(timing), builds=schedule_builds or 0)``).

    ``None`` means the default (docs/evolution.md; a random seed is drawn and recorded).
    ``out`` is the run folder (best.json, history.csv, checkpoint after every generation); with
    ``out=None`` nothing is written and the run cannot be resumed. ``on_generation`` gets a
    :class:`Generation` after each one. Ctrl-C (or a ``KeyboardInterrupt`` raised by the
    callback) raises :class:`EvolveInterrupted` once the last finished generation is saved.
    Bad settings or folders raise :class:`~bstool.errors.InputError` before any work.
    """
    params = opt.ga_params(
        model,
        pop=pop,
        gens=gens,
        pc=pc,
        pm=pm,
        transitions=transitions,
        coevol_gens=coevol_gens,
        seed=seed,
        robust=robust,
        coevolve_faults=coevolve_faults,
        parasites=parasites,
        parasite_k=parasite_k,
    )
    opt.check_workers(workers)
    plan = plan_new(
        model, params, fitness=fitness, out=out, force=force, stamp_timed=stamp_timed,
        period=period, timing=timing, schedule_builds=schedule_builds, robot=robot,
        randomize=randomize, randomize_samples=randomize_samples,
        randomize_score=randomize_score, validate_every=validate_every,
        validation_samples=validation_samples, train_timestep=train_timestep,
        randomize_box=randomize_box, init=init,
    )  # fmt: skip
    return execute(
        plan,
        workers=workers,
        cluster=cluster,
        on_generation=on_generation,
        schedule_model=schedule_model,
    )


def resume(
    out: str | os.PathLike[str],
    *,
    gens: int | None = None,
    workers: int | None = None,
    cluster: Any = None,
    on_generation: Callable[[Generation], None] | None = None,
    schedule_model: ScheduleSource | None = None,
) -> EvolveResult:
    """Continue the run in folder ``out`` from its checkpoint (``gens`` may extend it); it
    reaches the same files as a run never interrupted. Raises ``InputError`` when ``out``
    holds no run or ``gens`` is below what is done. A stamp-timed run needs its
    ``schedule_model`` again."""
    opt.check_workers(workers)
    plan = plan_resume(out, {"gens": gens})
    return execute(
        plan,
        workers=workers,
        cluster=cluster,
        on_generation=on_generation,
        schedule_model=schedule_model,
    )
