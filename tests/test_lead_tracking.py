"""bench/lead_tracking.py: the leads' travel behind docs/results.md's reading of the NN targets."""

from __future__ import annotations

import dataclasses
import importlib.util
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from bstool.builtin import builtin_controller
from bstool.controllers import load_controller
from bstool.robot import RobotSpec
from bstool.sim.simulator import Simulator

ROOT = Path(__file__).resolve().parent.parent


def _bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location(
        "lead_tracking", ROOT / "bench" / "lead_tracking.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_sampling_the_angles_leaves_the_walk_as_it_was() -> None:
    lt = _bench()
    sim = Simulator()
    states = load_controller(builtin_controller("nnsin")).states(lt.TRANSITIONS)
    t = lt.tracking(sim, states)
    assert t["distance"] == pytest.approx(sim.run(states).distance * 100, abs=1e-9)
    assert 0.5 < t["lead_travel"] <= 1.05
    assert t["lead_err"] > 0 and t["other_err"] > 0


def test_a_lead_held_still_travels_nothing_and_a_weaker_servo_travels_less() -> None:
    lt = _bench()
    states = load_controller(builtin_controller("nnsin")).states(lt.TRANSITIONS)
    still = np.array(states)
    still[:, :, 0] = still[0, :, 0]  # every lead keeps its first state
    t = lt.tracking(Simulator(), still)
    assert np.isnan(t["lead_travel"])  # nothing commanded: no fraction to give
    nominal = RobotSpec()
    weak = dataclasses.replace(nominal, friction=1.0, servo_torque=nominal.servo_torque * 0.7)
    assert (
        lt.tracking(Simulator(weak), states)["lead_travel"]
        < lt.tracking(Simulator(nominal), states)["lead_travel"]
    )
