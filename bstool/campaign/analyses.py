"""The plan's analyses on each finished run's best.json, cached per run and analysis in
DIR/analyses/RUN/NAME.json with the digest of their inputs: the analysis and its parameters,
the sha256 of best.json, how the controller is played (plain or stamp-timed at its period) and
:data:`VERSION`. A cached result whose digest matches is used as it is; a changed best.json
(or plan) computes it again.

Every analysis is deterministic (seeded draws), so a cached result equals a fresh one.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bstool import fileio
from bstool.campaign import plan as cp
from bstool.controllers import Controller, load_controller
from bstool.errors import InputError
from bstool.experiments import initial, mobility
from bstool.experiments.extrapolate import reinit_states
from bstool.experiments.paths import distance_curve, path_shape
from bstool.experiments.report import batch_runner
from bstool.robot import RobotSpec
from bstool.robot.robotfile import Robot, resolve

FOLDER = "analyses"
FORMAT = "bstool.campaign-analysis/1"
#: raise when an analysis computes something else from the same inputs (cached results go)
VERSION = 1
MULTI_K = (1, 2, 3, 4, 5)

ScheduleFor = Callable[[Controller, float | None], Any]
"""The schedule model of a stamp-timed controller at a period (the command fits it)."""


@dataclass(frozen=True)
class Job:
    """One analysis of one run: its name and parameters (both part of the digest)."""

    name: str
    params: dict[str, Any]


def jobs(plan: cp.CampaignPlan, transitions: int) -> list[Job]:
    """The analyses the plan asks for on a run of MAX_TRANS ``transitions`` ("base", the
    healthy run's path, is always made: every figure starts from it)."""
    a = plan.analyses
    out = [Job("base", {"transitions": transitions})]
    if a.faults:
        out.append(Job("faults", {"transitions": transitions}))
    if a.multi_failures:
        out.append(
            Job(
                "multi-failures",
                {"transitions": transitions, "samples": a.multi_failures, "k": list(MULTI_K)},
            )
        )
    if a.extrapolate is not None:
        every = a.reinit_every or transitions
        out.append(Job("extrapolate", {"transitions": a.extrapolate, "reinit_every": every}))
    if a.sensitivity is not None:
        out.append(Job("sensitivity", {"transitions": transitions, **vars(a.sensitivity)}))
    if a.initial_states is not None:
        init = a.initial_states
        out.append(
            Job(
                "initial-states",
                {"transitions": transitions, "k": list(init.k), "samples": init.samples},
            )
        )
    return out


def robot_of(controller: Controller) -> Robot:
    """The robot a run was evolved for (recorded in its best.json; else the default): its
    analyses run on its nominal values, randomized runs included."""
    return resolve(None, controller.robot, what="best.json")[0]


def evaluation(controller: Controller) -> dict[str, Any]:
    """How a run's controller is played: as it was evolved (its ``ga`` says stamp-timed and
    the period), on the nominal robot it was evolved for (part of best.json)."""
    ga = controller.ga or {}
    if ga.get("stamp_timed"):
        how = {"kind": "stamp-timed", "period": ga.get("period")}
        # the schedule model it was scored on: --schedule-builds, and --timing by its sha256
        if ga.get("schedule_builds"):
            how["builds"] = ga["schedule_builds"]
        if isinstance(ga.get("timing"), dict):
            how["timing_sha256"] = ga["timing"].get("sha256")
        return how
    return {"kind": "plain"}


def digest(job: Job, best: bytes, how: dict[str, Any]) -> str:
    obj = {
        "analysis": job.name,
        "version": VERSION,
        "params": job.params,
        "evaluation": how,
        "best_sha256": hashlib.sha256(best).hexdigest(),
    }
    return hashlib.sha256(json.dumps(obj, sort_keys=True).encode()).hexdigest()


def result_path(folder: Path, run: str, name: str) -> Path:
    return folder / FOLDER / run / f"{name}.json"


def cached(path: Path, key: str) -> dict[str, Any] | None:
    """The cached result at ``path`` if its digest is ``key`` (anything else: None)."""
    if not path.is_file():
        return None
    try:
        data = fileio.read_json(path, "analysis result")
    except InputError:
        return None
    if not isinstance(data, dict) or data.get("format") != FORMAT or data.get("inputs") != key:
        return None
    result = data.get("result")
    return result if isinstance(result, dict) else None


def simulations(job: Job, controller: Controller) -> int:
    """Physics runs ``job`` makes (the progress bar's total)."""
    cells = controller.legs * controller.modules
    p = job.params
    if job.name == "faults":
        return cells + 1
    if job.name == "multi-failures":
        return 1 + sum(min(p["samples"], math.comb(cells, k)) for k in p["k"])
    if job.name == "extrapolate":
        return 2
    if job.name == "initial-states":
        return 1 + len(p["k"]) * p["samples"]
    if job.name == "sensitivity":
        return _design(controller, p).count
    return 1


def _design(controller: Controller, p: dict[str, Any]) -> Any:
    from bstool.experiments import sensitivity

    return sensitivity.design(
        robot_of(controller), points=p["points"], samples=p["samples"], seed=p["seed"]
    )


Run = Callable[[Sequence[np.ndarray]], list[Any]]


def compute(job: Job, c: Controller, run: Run, on_robots: Any = None) -> dict[str, Any]:
    """The result of ``job`` (JSON-ready; distances in metres, M_D in percent).
    ``on_robots(sequences, robots) -> distances`` plays sequences on other robots (the
    sensitivity analysis)."""
    p = job.params
    T = int(p["transitions"])
    if job.name == "sensitivity":
        from bstool.experiments import sensitivity

        return sensitivity.measure(job.name, c.states(T), _design(c, p), on_robots).to_json()
    evaluate = mobility.distances_of(run)
    if job.name == "base":
        (res,) = run([c.states(T)])
        return {
            "distance": float(res.distance),
            "path": np.asarray(res.path).tolist(),
            "shape": path_shape(res.path).to_json(),
        }
    if job.name == "faults":
        return mobility.single_failures(c, evaluate, T).to_json()
    if job.name == "extrapolate":
        plain, reinit = run([c.states(T), reinit_states(c, T, int(p["reinit_every"]))])
        return {
            "plain": distance_curve(plain.path).tolist(),
            "reinit": distance_curve(reinit.path).tolist(),
            "reinit_every": int(p["reinit_every"]),
        }
    baseline = evaluate([c.states(T)])[0]
    if job.name == "multi-failures":
        return {"baseline_distance": baseline, "k": _multi(c, evaluate, T, p, baseline)}
    if job.name == "initial-states":
        return {"baseline_distance": baseline, "k": _nudged(c, evaluate, T, p, baseline)}
    raise InputError(f"unknown analysis {job.name!r}")  # pragma: no cover


class _OnRobots:
    """An evolve evaluator as ``(sequences, robots) -> distances`` (``bstool sensitivity``'s
    evaluation: plain or stamp-timed physics on each robot), in chunks for the progress."""

    def __init__(self, evaluator: Any, chunk: int, advance: Callable[[int], None]) -> None:
        self.evaluator, self.chunk, self.advance = evaluator, chunk, advance

    def __call__(self, seqs: list[np.ndarray], robots: list[Any]) -> list[float]:
        out: list[float] = []
        for i in range(0, len(seqs), self.chunk):
            part = self.evaluator(seqs[i : i + self.chunk], robot=robots[i : i + self.chunk])
            out += [float(d) for d in part]
            self.advance(len(part))
        return out

    def close(self) -> None:
        close = getattr(self.evaluator, "close", None)
        if close is not None:
            close()


def _on_robots(
    c: Controller,
    spec: RobotSpec,
    schedule: Any,
    workers: int | None,
    advance: Callable[[int], None],
) -> _OnRobots:
    from bstool.cpus import usable_cpus
    from bstool.evolve.fitness import PhysicsFitness, StampTimedFitness

    threads = workers or usable_cpus()
    factory: Any = (
        PhysicsFitness(c.legs, c.modules, threads, spec)
        if schedule is None
        else StampTimedFitness(schedule, c.legs, c.modules, threads, spec)
    )
    return _OnRobots(factory.build(), max(1, 2 * threads), advance)


def _multi(
    c: Controller, evaluate: mobility.Evaluate, T: int, p: dict[str, Any], baseline: float
) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k in p["k"]:  # seed K, as `bstool faults --k K`
        runs = mobility.random_failures(c, evaluate, T, k, p["samples"], k, baseline)
        out[str(k)] = {
            "summary": mobility.summarize(runs),
            "runs": [
                {
                    "failed": [str(m) for m in r.failed],
                    "distance": r.distance,
                    "mobility": _finite(r.mobility),
                }
                for r in runs
            ],
        }
    return out


def _nudged(
    c: Controller, evaluate: mobility.Evaluate, T: int, p: dict[str, Any], baseline: float
) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k in p["k"]:  # seed k
        runs = initial.nudged_runs(c, evaluate, T, k, p["samples"], baseline, seed=k)
        kept = np.array([r.kept for r in runs], dtype=float)
        kept = kept[np.isfinite(kept)]
        out[str(k)] = {
            "mean_kept": float(np.mean(kept)) if kept.size else None,
            "median_kept": float(np.median(kept)) if kept.size else None,
            "runs": [
                {"changed": r.nudge.to_json(), "distance": r.distance, "kept": _finite(r.kept)}
                for r in runs
            ],
        }
    return out


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


@dataclass
class Progress:
    """What :func:`analyse` tells its caller."""

    total: Callable[[int], None] = lambda n: None  # simulations to come
    advance: Callable[[int], None] = lambda k: None  # k more simulations done
    describe: Callable[[str], None] = lambda text: None


def analyse(
    folder: Path,
    runs: Sequence[tuple[str, Path]],
    plan: cp.CampaignPlan,
    *,
    workers: int | None = None,
    schedule_for: ScheduleFor | None = None,
    progress: Progress | None = None,
) -> dict[str, dict[str, dict[str, Any]]]:
    """Every analysis of every run (name, folder holding best.json): from the cache when its
    digest matches, else computed and cached (each result written as soon as it is done)."""
    from bstool.sim.batch import BatchEvaluator

    say = progress or Progress()
    todo: list[tuple[str, Controller, Job, str, Path]] = []
    results: dict[str, dict[str, dict[str, Any]]] = {}
    for name, run_folder in runs:
        best = run_folder / "best.json"
        data = fileio.read_limited(best, "controller file")
        c = load_controller(best)
        how = evaluation(c)
        results[name] = {}
        for job in jobs(plan, c.max_trans or 30):
            key = digest(job, data, how)
            path = result_path(folder, name, job.name)
            hit = cached(path, key)
            if hit is not None:
                results[name][job.name] = hit
            else:
                todo.append((name, c, job, key, path))
    say.total(sum(simulations(job, c) for _, c, job, _, _ in todo))
    evaluators: dict[RobotSpec, Any] = {}
    schedules: dict[str, Any] = {}
    try:
        for name, c, job, key, path in todo:
            say.describe(f"{name}: {job.name}")
            how = evaluation(c)
            if how["kind"] == "stamp-timed" and name not in schedules:
                if schedule_for is None:
                    raise InputError(
                        f"{name} was evolved stamp-timed: its analyses need the schedule model"
                    )
                schedules[name] = schedule_for(c, how.get("period"))
            spec = robot_of(c).spec
            if spec not in evaluators:  # one MuJoCo model per robot, not per analysis
                evaluators[spec] = BatchEvaluator(spec, workers=workers)
            run = batch_runner(evaluators[spec], schedules.get(name), say.advance)
            on_robots = None
            if job.name == "sensitivity":
                on_robots = _on_robots(c, spec, schedules.get(name), workers, say.advance)
            try:
                result = compute(job, c, run, on_robots)
            finally:
                if on_robots is not None:
                    on_robots.close()
            record = {
                "format": FORMAT,
                "analysis": job.name,
                "inputs": key,
                "params": job.params,
                "evaluation": how,
                "result": result,
            }
            fileio.write_json(path, record)
            results[name][job.name] = result
    finally:
        for ev in evaluators.values():
            ev.close()
    return results
