"""``bstool simulate --build``: the stamp-timed run (the twin's schedule, MuJoCo's physics).

Kept apart from :mod:`bstool.commands.simulate` so that a plain ``bstool simulate`` never
imports the twin.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bstool import buildfile
from bstool.controllers import controller_hash, load_controller
from bstool.errors import InputError
from bstool.moduleid import ModuleId
from bstool.sim.simulator import SimResult


def load_matching(build_dir: str, controller: str | None) -> tuple[buildfile.Build, str]:
    """The build, and the controller file to take the states from (the build's own
    controller.json without CONTROLLER; else CONTROLLER, which must be the build's)."""
    build = buildfile.load(build_dir)
    own = build.controller_file
    if controller is None:
        if not own.is_file():
            raise InputError(
                f"{build_dir}: the build has no controller.json",
                hint="give the CONTROLLER it was compiled from",
            )
        return build, str(own)
    chash = controller_hash(load_controller(controller))
    if chash != build.controller_hash:
        raise InputError(
            f"{controller} is not the controller {build_dir} was compiled from "
            f"({chash[:8]} vs {build.controller_hash[:8]})",
            hint=f"compile it (`bstool compile {controller} -o DIR`) and give --build DIR",
        )
    return build, controller


def run_build(
    build: buildfile.Build,
    states: np.ndarray,
    failed: list[ModuleId],
    *,
    quiet: bool,
    timing_file: str | None = None,
) -> tuple[SimResult, dict[str, Any]]:
    """Play ``build``'s schedule for ``len(states) - 1`` transitions; the result and what to
    add to the output. ``timing_file``: the stamps' measured timing (bstool probe)."""
    from hil_mock import measured
    from hil_mock.schedule_extract import simulate_build

    transitions = len(states) - 1
    if transitions < 1:
        raise InputError("--build needs at least one transition", hint="give -T 1 or more")
    timing = measured.load(timing_file)
    result, schedule, twin = simulate_build(build, transitions, failed=failed, timing=timing)
    seen = twin.state_array(build.legs, build.modules, transitions)
    period = np.diff(schedule.samples)
    return result, {
        "timing": f"the stamps of {Path(build.root).name} (mean period {period.mean():.3f} s)"
        if len(period)
        else f"the stamps of {Path(build.root).name}",
        "build": str(build.root),
        "stamp_timed": True,
        "schedule": "build",
        "first_transition_s": float(schedule.samples[0]),
        "period_mean": float(period.mean()) if len(period) else None,
        "states_equal": bool(np.array_equal(seen, states)),
    }
