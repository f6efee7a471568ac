"""A robot's physics written into a compiled model walks the path of a model built from the
spec (issue 29 §4: to 1e-9 m), in one run and in batches, and leaves the nominal model as it
was."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import traced_controller

from bstool.controllers import load_controller
from bstool.errors import InputError
from bstool.robot import RobotSpec, build_model
from bstool.robot.apply import PHYSICS_FIELDS, apply_physics, check_applicable
from bstool.sim.batch import BatchEvaluator
from bstool.sim.simulator import Simulator

NOMINAL = RobotSpec()
T = 30
#: each physics parameter moved well inside or past the default box
CHANGES = {
    "friction": 0.73,
    "servo_torque": 0.31,
    "servo_speed": 0.226,
    "servo_band": 0.117,
    "servo_armature": 0.0027,
    "module_mass": 0.1043,
    "disc_mass": 0.461,
}


@pytest.fixture(scope="module")
def states() -> np.ndarray:
    return load_controller(traced_controller("nnsin")).states(T)


def test_every_physics_field_is_covered() -> None:
    assert set(CHANGES) == set(PHYSICS_FIELDS)


@pytest.mark.parametrize("name", sorted(CHANGES))
def test_one_parameter_applied_equals_a_model_built_from_the_spec(
    name: str, states: np.ndarray
) -> None:
    robot = dataclasses.replace(NOMINAL, **{name: CHANGES[name]})
    built = Simulator(robot, transition_time=NOMINAL.transition_time).run(states)
    sim = Simulator(NOMINAL)
    apply_physics(sim.model, robot, base=NOMINAL, base_model=build_model(NOMINAL))
    applied = sim.run(states)
    assert np.max(np.abs(applied.path - built.path)) <= 1e-9
    assert abs(applied.distance - built.distance) <= 1e-9
    assert built.distance != pytest.approx(Simulator(NOMINAL).run(states).distance, abs=1e-4)


def test_all_at_once_and_back(states: np.ndarray) -> None:
    robot = dataclasses.replace(NOMINAL, **CHANGES)
    base = build_model(NOMINAL)
    sim = Simulator(NOMINAL)
    apply_physics(sim.model, robot, base=NOMINAL, base_model=base)
    built = Simulator(robot, transition_time=NOMINAL.transition_time).run(states)
    assert abs(sim.run(states).distance - built.distance) <= 1e-9
    apply_physics(sim.model, NOMINAL, base=NOMINAL, base_model=base)  # restores to the bit
    assert np.array_equal(sim.run(states).path, Simulator(NOMINAL).run(states).path)


def test_a_batch_on_other_robots_and_the_nominal_model_untouched(states: np.ndarray) -> None:
    robots = [dataclasses.replace(NOMINAL, friction=f, module_mass=m)
              for f, m in ((0.3, 0.08), (0.9, 0.1), (0.55, 0.09))]  # fmt: skip
    nominal = Simulator(NOMINAL).run(states).path
    with BatchEvaluator(NOMINAL, workers=2) as ev:
        before = ev.evaluate([states])[0].path
        varied = ev.evaluate([states] * 4, robot=[*robots, None])
        after = ev.evaluate([states])[0].path
        one = ev.evaluate([states, states], robot=robots[1])
    assert np.array_equal(before, nominal) and np.array_equal(after, nominal)
    assert np.array_equal(varied[3].path, nominal)
    for got, robot in zip(varied[:3], robots, strict=True):
        want = Simulator(robot, transition_time=NOMINAL.transition_time).run(states)
        assert abs(got.distance - want.distance) <= 1e-9
    assert one[0].distance == one[1].distance == varied[1].distance


def test_a_servo_speed_never_changes_the_period(states: np.ndarray) -> None:
    """The period belongs to the controller (the evaluator's robot), not to the sample."""
    slow = dataclasses.replace(NOMINAL, servo_speed=0.25)
    with BatchEvaluator(NOMINAL, workers=1) as ev:
        assert ev.sim.steps_per_transition == round(NOMINAL.transition_time / NOMINAL.timestep)
        got = ev.evaluate([states], robot=slow)[0]
    want = Simulator(slow, transition_time=NOMINAL.transition_time).run(states)
    assert abs(got.distance - want.distance) <= 1e-9


def test_geometry_cannot_vary_between_samples() -> None:
    for change in ({"module_pitch": 0.08}, {"timestep": 0.004}, {"disc_radius": 0.09}):
        with pytest.raises(InputError, match="cannot vary between samples"):
            check_applicable(NOMINAL, dataclasses.replace(NOMINAL, **change))
    with BatchEvaluator(NOMINAL, workers=1) as ev, pytest.raises(InputError):
        ev.evaluate([np.zeros((2, 5, 6), dtype=int)], robot=dataclasses.replace(NOMINAL, legs=4))


def test_worker_models_are_made_before_the_workers_start(
    states: np.ndarray, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two workers that each found no model copies made a list of their own: one worker's
    physics went into the list that the other then replaced, and a later job on that robot
    ran on the nominal model. Slowed copies and applies make that interleaving certain."""
    import time

    from bstool.sim import batch

    def slow(func):  # type: ignore[no-untyped-def]
        def wrapped(*args, **kwargs):  # type: ignore[no-untyped-def]
            time.sleep(0.05)
            return func(*args, **kwargs)

        return wrapped

    monkeypatch.setattr(batch, "model_copy", slow(batch.model_copy))
    monkeypatch.setattr(batch, "apply_physics", slow(batch.apply_physics))
    robot = dataclasses.replace(NOMINAL, friction=0.9, module_mass=0.1)
    want = Simulator(robot, transition_time=NOMINAL.transition_time).run(states).distance
    with BatchEvaluator(NOMINAL, workers=2) as ev:
        first = ev.evaluate([states, states], robot=robot)
        again = ev.evaluate([states, states], robot=robot)
    for got in (*first, *again):
        assert abs(got.distance - want) <= 1e-9
