"""`bstool sensitivity`'s reading of the joint sample: which parameters the losses go with."""

from __future__ import annotations

import numpy as np
import pytest

from bstool.experiments import sensitivity as sens
from bstool.robot import RobotSpec
from bstool.robot.robotfile import Robot


def _plan(samples: int) -> sens.Design:
    return sens.design(Robot(RobotSpec()), points=2, samples=samples, seed=0)


def test_drivers_rank_the_parameters_the_distance_goes_with() -> None:
    plan = _plan(16)
    friction = np.array([r.friction for r in plan.joint])
    torque = np.array([r.servo_torque for r in plan.joint])
    # a gait that walks less on a grippier floor and does not care about anything else
    got = sens.drivers(plan, list(1.0 - friction))
    assert got["friction"] == pytest.approx(-1.0)
    assert set(got) == set(plan.sweeps)
    assert got["servo_torque"] == pytest.approx(
        -float(np.corrcoef(np.argsort(np.argsort(torque)), np.argsort(np.argsort(friction)))[0, 1])
    )
    assert sens.drivers(plan, [0.2] * len(plan.joint)) == dict.fromkeys(plan.sweeps)  # never moves
    assert set(sens.drivers(_plan(2), [0.1, 0.2]).values()) == {None}  # too few robots
    holed = list(1.0 - friction)
    holed[3] = float("nan")  # a run that failed: left out, the rest still ranks
    assert sens.drivers(plan, holed)["friction"] == pytest.approx(-1.0)
    assert set(sens.drivers(plan, [float("nan")] * len(plan.joint)).values()) == {None}


def test_the_table_names_what_to_measure_first() -> None:
    plan = _plan(8)
    distances = [0.3 - 0.2 * r.friction for r in plan.joint]
    t = sens.Transfer("gait", 0.25, {k: [(0.0, 0.2)] for k in plan.sweeps}, distances,
                      drivers=sens.drivers(plan, distances))  # fmt: skip
    text = sens.table([t], plan)
    assert "all at once: Spearman rho" in text
    assert "  friction: gait: -1.00" in text
    assert t.to_json()["drivers"]["friction"] == pytest.approx(-1.0)
