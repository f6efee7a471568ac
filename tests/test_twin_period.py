"""`bstool twin` compares with a simulation at the build's period (`compile --period P`), not
at the simulator's default transition time."""

from __future__ import annotations

import json
from collections.abc import Callable

import pytest
from conftest import CliRun, TracedBuild, traced_controller

from bstool import buildfile
from bstool.controllers import load_controller
from bstool.robot import RobotSpec
from bstool.sim.simulator import Simulator
from hil_mock.check import reference_simulator, settle_seconds

PERIOD = 0.6  # the default is RobotSpec().transition_time (0.475 s)


def test_twin_after_compile_period_compares_with_that_period(
    traced_build: TracedBuild, cli: Callable[..., CliRun]
) -> None:
    assert RobotSpec().transition_time != PERIOD
    root = traced_build("ca1d", period=PERIOD)
    build = buildfile.load(root)
    assert build.period == PERIOD
    assert reference_simulator(build).transition_time == PERIOD
    run = cli("twin", str(root), "-T", "2", "--json", "-q")
    assert run.code == 0, run.err
    out = json.loads(run.out)
    states = load_controller(traced_controller("ca1d")).states(2)
    settle = settle_seconds(build)
    at_period = Simulator(RobotSpec(), transition_time=PERIOD, settle_time=settle).run(states)
    at_default = Simulator(RobotSpec(), settle_time=settle).run(states)
    assert at_period.distance != pytest.approx(at_default.distance, abs=1e-4)
    assert out["sim_distance"] == pytest.approx(at_period.distance, abs=1e-12)
    assert out["period_nominal"] == PERIOD
