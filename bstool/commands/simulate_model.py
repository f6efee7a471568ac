"""``bstool simulate --stamp-timed``: a controller on the schedule model evolution uses.

``bstool evolve --stamp-timed`` scores each candidate on the schedule a build of it would
follow, derived from the model (``hil_mock.schedule_model``) rather than compiled; this plays
the same schedule for one controller, so a stamp-timed run's fitness is replayed to the bit
(same period, same timing file, a plain-distance fitness).
Kept apart from :mod:`bstool.commands.simulate` so that a plain ``bstool simulate`` never
imports the twin.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bstool.controllers import Controller
from bstool.errors import InputError
from bstool.sim.simulator import SimResult
from bstool.sim.timed import ScheduleEnsemble, ScheduleSource, mean_distance, schedules_of


def _evolved(ctrl: Controller) -> dict[str, Any]:
    """The stamp-timed settings of the run that evolved ``ctrl`` ({} if it was not one)."""
    ga = ctrl.ga if isinstance(ctrl.ga, dict) else {}
    return ga if ga.get("stamp_timed") is True else {}


def evolved_period(ctrl: Controller) -> float | None:
    """The period a stamp-timed run evolved ``ctrl`` at (None: compile's default)."""
    period = _evolved(ctrl).get("period")
    if isinstance(period, bool) or not isinstance(period, int | float) or not period > 0:
        return None
    return float(period)


def evolved_builds(ctrl: Controller, where: str = "the controller") -> int:
    """The builds a stamp-timed run scored its candidates on (``--schedule-builds``; 0: one
    model, the mean of two builds' instants, as without it)."""
    from bstool.evolve.options import MAX_BUILDS

    count = _evolved(ctrl).get("schedule_builds", 0)
    if isinstance(count, bool) or not isinstance(count, int) or not 0 <= count <= MAX_BUILDS:
        raise InputError(
            f"{where}: ga.schedule_builds must be a whole number in 1..{MAX_BUILDS}, got {count!r}",
            hint="it is what `bstool evolve --schedule-builds` recorded: restore it, or remove it"
            " to replay on the one averaged model",
        )
    return count


def evolved_timing(ctrl: Controller, where: str) -> str | None:
    """The timing file a stamp-timed run evolved ``ctrl`` with, if it recorded one: that file,
    checked against the sha256 it recorded (None: the run used the estimate)."""
    from bstool.evolve.options import timing_record

    saved = _evolved(ctrl).get("timing")
    if not isinstance(saved, dict) or not isinstance(saved.get("file"), str):
        return None
    hint = "give the file with --timing F (or another timing model on purpose)"
    if not Path(saved["file"]).is_file():
        raise InputError(
            f"{where} was evolved with the timing file {saved['file']}, which is not there",
            hint=hint,
        )
    if timing_record(saved["file"])["sha256"] != saved.get("sha256"):
        raise InputError(
            f"{saved['file']} has changed since {where} was evolved with it (sha256 differs)",
            hint=hint,
        )
    return str(saved["file"])


def run_model(
    ctrl: Controller,
    states: np.ndarray,
    where: str,
    *,
    period: float | None,
    timing_file: str | None = None,
    other_builds: int = 0,
    spec: Any = None,
) -> tuple[SimResult, dict[str, Any]]:
    """Play ``states`` (``ctrl``'s, from the file ``where``) on the schedule model of
    ``ctrl.model``; the result and what to add to the output. ``period`` None: the one
    ``ctrl`` was evolved at, else compile's; ``timing_file`` None: the one it was evolved
    with, else the estimate. ``other_builds`` N: also each distance on N builds it was not
    scored on (random controllers after the ones its run used), and their mean. ``spec``:
    the robot (a RobotSpec; None: the default)."""
    from bstool import timingfile
    from bstool.compile.build import default_period
    from bstool.robot import RobotSpec
    from bstool.sim.simulator import Simulator
    from hil_mock.schedule_model import REPRESENTATIVES, schedule_model

    if len(states) < 2:
        raise InputError("--stamp-timed needs at least one transition", hint="give -T 1 or more")
    if period is None:
        period = evolved_period(ctrl)
    if timing_file is None:
        timing_file = evolved_timing(ctrl, where)
    timing = None if timing_file is None else timingfile.load(timing_file)
    builds = evolved_builds(ctrl, where)

    def fitted_on(count: int) -> ScheduleSource:
        return schedule_model(ctrl.model, period=period, legs=ctrl.legs, modules=ctrl.modules,
                              timing=timing, builds=count, spec=spec)  # fmt: skip

    fitted = fitted_on(builds)
    schedules = schedules_of(fitted, states)
    robot = spec if spec is not None else RobotSpec(legs=ctrl.legs, modules=ctrl.modules)
    sim = Simulator(robot)
    runs = [sim.run_schedule(s) for s in schedules]
    result, schedule = runs[0], schedules[0]  # the path shown: the first build's
    distances = [float(r.distance) for r in runs]
    used = default_period(ctrl.legs, ctrl.modules, robot) if period is None else period
    gaps = np.diff(schedule.samples)
    out: dict[str, Any] = {
        "timing": f"the schedule model of {ctrl.model} (builds at period {used:g} s, mean "
        f"period {gaps.mean():.3f} s)",
        "stamp_timed": True,
        "schedule": "model",
        "period": used,
        "timing_file": timing_file,
        "first_transition_s": float(schedule.samples[0]),
        "period_mean": float(gaps.mean()),
        "schedule_builds": builds,
        "fitness": mean_distance(distances),  # what a stamp-timed run scores it
    }
    if other_builds:
        first = builds or REPRESENTATIVES  # the builds it was scored on come first
        others = fitted_on(first + other_builds)
        assert isinstance(others, ScheduleEnsemble)
        new = [
            float(sim.run_schedule(m.schedule(states)).distance) for m in others.variants[first:]
        ]
        out["other_build_distances"] = new
        new_cm = np.array(new) * 100
        out["other_text"] = (
            f"mean {new_cm.mean():.2f} cm on {other_builds} build{'s' * (other_builds > 1)} "
            "it was not scored on "
            f"({new_cm.min():.2f} to {new_cm.max():.2f} cm): the spread of builds' timing"
        )
    ga = ctrl.ga if isinstance(ctrl.ga, dict) else {}
    if builds:
        out["build_distances"] = distances
        each = ", ".join(f"{100 * d:.2f}" for d in distances)
        out["builds_text"] = (
            f"{each} cm on the {builds} builds' patterns, mean {100 * out['fitness']:.2f} cm "
            "(the stamp-timed fitness; path and distance above: the first build's)"
        )
    if ga.get("randomize"):
        out["nominal_fitness"] = out["fitness"]
        out["fitness"], count = validation_mean(ctrl, states, fitted, robot)
        out["note"] = (
            f"fitness: the mean over the run's {count} validation robots (--randomize; "
            "the distance above is the nominal robot's)"
        )
    if ga.get("robust") or ga.get("coevolve_faults"):
        out["note"] = (
            "this run's fitness was not a plain distance (--robust or --coevolve-faults), "
            "so it is not replayed here"
        )
    return result, out


def validation_mean(ctrl: Controller, states: np.ndarray, fitted: ScheduleSource,
                    spec: Any) -> tuple[float, int]:  # fmt: skip
    """A randomized run's fitness, replayed: ``ctrl``'s mean distance over the run's
    validation robots (its seed, its settings), as the run's validator measured it."""
    from bstool.evolve.fitness import StampTimedFitness
    from bstool.evolve.ga import clean_fitness
    from bstool.evolve.randomize import Randomize, validation_robots
    from bstool.robot.robotfile import Robot, from_record

    ga = ctrl.ga if isinstance(ctrl.ga, dict) else {}
    settings = Randomize.from_json(ga["randomize"])
    robot = Robot() if ctrl.robot is None else from_record(ctrl.robot, "the controller")
    if ctrl.seed is None:
        raise InputError(
            "this randomized run's controller file records no seed, so its validation robots "
            "cannot be drawn again",
            hint='replay it with the seed it was evolved with in the file\'s "seed"',
        )
    robots = validation_robots(robot, settings, int(ctrl.seed))
    ev = StampTimedFitness(fitted, ctrl.legs, ctrl.modules, 2, spec).build()
    try:
        raw = ev([states] * len(robots), robot=robots)
    finally:
        close = getattr(ev, "close", None)
        if close is not None:
            close()
    return float(np.mean(clean_fitness(raw))), len(robots)
