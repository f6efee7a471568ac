"""`bstool sensitivity`'s reading of the joint sample: which parameters the losses go with."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from bstool.experiments import sensitivity as sens
from bstool.robot import RobotSpec
from bstool.robot.robotfile import Robot
from tests.conftest import CliRun


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


def test_the_mean_and_10th_percentile_come_with_how_sure_they_are() -> None:
    plan = _plan(40)
    distances = [0.1 + 0.005 * i for i in range(40)]  # 10 to 29.5 cm, evenly
    t = sens.Transfer("gait", 0.25, {k: [(0.0, 0.2)] for k in plan.sweeps}, distances)
    iv = t.intervals()
    assert iv is not None
    for key, value in (("mean", t.mean), ("p10", t.p10)):
        low, high = iv[key]
        assert low < value < high  # a real spread, around the figure itself
    assert iv["p10"][0] >= min(distances) and iv["p10"][1] <= np.percentile(distances, 40)
    assert iv == t.intervals()  # seeded: the same table every time
    text = sens.table([t], plan)
    low, high = iv["p10"]
    assert f"p10 {t.p10 * 100:.1f} [{low * 100:.1f}, {high * 100:.1f}]" in text
    assert f"= {t.p10 / 0.25:.0%} [{low / 0.25:.0%}, {high / 0.25:.0%}] of nominal" in text
    assert t.to_json()["intervals"]["p10"] == pytest.approx(list(iv["p10"]))
    # too few robots for a 10th percentile to mean anything: no intervals, no block
    few = sens.Transfer("gait", 0.25, t.sweeps, distances[:8])
    assert few.intervals() is None and few.to_json()["intervals"] is None
    assert "how sure" not in sens.table([few], _plan(8))


def test_a_build_plays_its_own_programs_timing_on_every_robot(
    traced_build: Callable[..., Path], cli: Callable[..., CliRun], tmp_path: Path
) -> None:
    """`bstool sensitivity BUILD`: the nominal robot walks what `simulate --build` walks (the
    build's own schedule, not the schedule model), and the sample's robots differ from it."""
    build = traced_build("nnsin")
    sim = cli("simulate", "--build", str(build), "-T", "3", "--json")
    assert sim.code == 0, sim.err
    run = cli(
        "sensitivity", str(build), "-T", "3", "--points", "2", "--samples", "2", "--json", "-q"
    )
    assert run.code == 0, run.err
    out = json.loads(run.out)
    (result,) = out["controllers"]
    assert result["nominal"] == pytest.approx(json.loads(sim.out)["distance"], abs=1e-12)
    assert "build's own programs" in out["timing"]["build"]
    assert len(result["joint"]) == 2 and result["joint"] != [result["nominal"]] * 2
    model = cli(
        "sensitivity", str(build / "controller.json"), "-T", "3", "--points", "2",
        "--samples", "2", "--stamp-timed", "--json", "-q",
    )  # fmt: skip
    assert "schedule model" in json.loads(model.out)["timing"]["controller"]
    bad = cli("sensitivity", str(tmp_path), "-T", "3")
    assert bad.code == 2 and "not a build (no manifest.json)" in bad.err


def test_a_build_schedule_plays_only_its_own_states() -> None:
    from bstool.errors import InputError
    from bstool.sim.timed import BuildSchedule, StampSchedule, schedules_of

    schedule = StampSchedule.from_events([(0.1, 0, 0.0)], samples=[0.0, 0.5], actuator_count=1)
    states = np.zeros((2, 1, 1), dtype=np.int64)
    source = BuildSchedule(schedule, states)
    assert schedules_of(source, states) == [schedule]
    with pytest.raises(InputError, match="only the states it was compiled from"):
        schedules_of(source, states + 1)
