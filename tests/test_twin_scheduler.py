"""The twin's scheduler (hil_mock/schedule.py) runs a stamp ahead of the robot up to the horizon
of the stamps wired to it. That must not change a single record: the same runs under the
global scheduler it replaced (always the stamp furthest behind, never past the second-furthest)
give the same pulse times, states, WELCOMEs and noise hits, with perturbations, resets, noise,
dead and dying modules and cut wires."""

from __future__ import annotations

from typing import Any

import pytest

from bstool import buildfile
from bstool.moduleid import ModuleId
from hil_mock.perturb import Perturbation, Reset
from hil_mock.robot import GlobalSchedulerTwin, RobotTwin


def _record(twin: RobotTwin) -> dict[str, Any]:
    return {
        "times": {m: list(r.times_ns) for m, r in twin.records.items()},
        "states": {m: list(r.states) for m, r in twin.records.items()},
        "welcomes": sorted(twin.welcomes),
        "noise": dict(twin.noise_events),
        "died": dict(twin.died),
    }


CASES = {
    "plain": {},
    "perturbed": {
        "perturb": Perturbation(
            timing_spread=0.2,
            clock_spread=0.02,
            start_spread=1.0,
            resets=(Reset("1.0", 1.5, 0.4),),
            seed=4,
        ),
        "noise": 0.02,
        "seed": 5,
    },
    "faults": {
        "failed": [ModuleId(2, 3)],
        "die": {ModuleId(4, 0): 2},
        "cut": [(ModuleId(0, 1), ModuleId(0, 2))],
        "noise": 0.03,
        "seed": 1,
    },
}


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("model", ["ca2dsing", "nnsin"])
def test_the_local_scheduler_changes_nothing(model: str, case: str, traced_build) -> None:
    build = buildfile.load(traced_build(model))
    runs = []
    for cls in (RobotTwin, GlobalSchedulerTwin):
        twin = cls(build, physics=False, **CASES[case])
        twin.run(4)
        runs.append(_record(twin))
    assert sum(len(t) >= 5 for t in runs[0]["times"].values()) >= 28  # the robot ran
    if case != "plain":
        assert sum(runs[0]["noise"].values()) > 0  # the noise hit the links
    assert runs[0] == runs[1]
