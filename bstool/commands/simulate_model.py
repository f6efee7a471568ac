"""``bstool simulate --stamp-timed``: a controller on the schedule model evolution uses.

``bstool evolve --stamp-timed`` scores each candidate on the schedule a build of it would
follow, derived from the model (``hil_mock.schedule_model``) rather than compiled; this plays
the same schedule for one controller, so a stamp-timed run's fitness is replayed to the bit.
Kept apart from :mod:`bstool.commands.simulate` so that a plain ``bstool simulate`` never
imports the twin.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bstool.controllers import Controller
from bstool.errors import InputError
from bstool.sim.simulator import SimResult


def evolved_period(ctrl: Controller) -> float | None:
    """The period a stamp-timed run evolved ``ctrl`` at (None: compile's default)."""
    ga = ctrl.ga if isinstance(ctrl.ga, dict) else {}
    period = ga.get("period") if ga.get("stamp_timed") else None
    return float(period) if isinstance(period, int | float) and period > 0 else None


def run_model(
    ctrl: Controller,
    states: np.ndarray,
    *,
    period: float | None,
    timing_file: str | None = None,
) -> tuple[SimResult, dict[str, Any]]:
    """Play ``states`` (``ctrl``'s) on the schedule model of ``ctrl.model`` at ``period``
    (None: the period ``ctrl`` was evolved at, else compile's); the result and what to add
    to the output."""
    from bstool import timingfile
    from bstool.robot import RobotSpec
    from bstool.sim.simulator import Simulator
    from hil_mock.schedule_model import schedule_model

    if len(states) < 2:
        raise InputError("--stamp-timed needs at least one transition", hint="give -T 1 or more")
    if period is None:
        period = evolved_period(ctrl)
    timing = None if timing_file is None else timingfile.load(timing_file)
    fitted = schedule_model(
        ctrl.model, period=period, legs=ctrl.legs, modules=ctrl.modules, timing=timing
    )
    schedule = fitted.schedule(states)
    sim = Simulator(RobotSpec(legs=ctrl.legs, modules=ctrl.modules, states=ctrl.k))
    result = sim.run_schedule(schedule)
    gaps = np.diff(schedule.samples)
    label = "compile's default period" if period is None else f"period {period:g} s"
    return result, {
        "timing": f"the schedule model of {ctrl.model} ({label}, mean period {gaps.mean():.3f} s)",
        "stamp_timed": "model",
        "period": period,
        "first_transition_s": float(schedule.samples[0]),
        "period_mean": float(gaps.mean()),
    }
