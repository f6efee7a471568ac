"""``--robot FILE`` on every command that simulates, evolves or compiles; the robot recorded in
best.json and in a build and used from there; the one-line note when --robot differs."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import traced_controller

from bstool.cli import COMMANDS
from bstool.controllers import load_controller
from bstool.robot import robotfile
from bstool.sim.simulator import Simulator
from tests.conftest import CliRun

T = 3
CTRL = traced_controller("ca1d")
ROBOT_TEXT = "friction = 0.7\nmodule_mass = 0.1\n"


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("robot-option")
    robot = d / "robot.toml"
    robot.write_text(ROBOT_TEXT)
    other = d / "other.toml"
    other.write_text("friction = 0.9\n")
    recorded = d / "recorded.json"  # a controller evolved for the robot of robot.toml
    obj = load_controller(CTRL).to_json()
    obj["robot"] = robotfile.load(robot).to_json()
    recorded.write_text(json.dumps(obj))
    return {"dir": d, "robot": robot, "other": other, "recorded": recorded}


def spec_of(path: Path) -> object:
    return robotfile.load(path).spec


def distance(spec: object, transitions: int = T, period: float | None = None) -> float:
    sim = Simulator(spec, transition_time=period)  # type: ignore[arg-type]
    return sim.run(load_controller(CTRL).states(transitions)).distance


def default_distance(transitions: int = T) -> float:
    return Simulator().run(load_controller(CTRL).states(transitions)).distance


def test_every_command_that_simulates_evolves_or_compiles_takes_robot(
    cli: Callable[..., CliRun],
) -> None:
    wanted = {
        "simulate",
        "evolve",
        "twin",
        "demo",
        "faults",
        "extrapolate",
        "paths",
        "report",
        "sensitivity",
        "compile",
        "rotate",
        "model",
    }
    for name in sorted(wanted):
        assert name in COMMANDS
        run = cli(name, "--help")
        assert run.code == 0 and "--robot FILE" in run.out, name


def test_simulate(files: dict[str, Path], cli: Callable[..., CliRun]) -> None:
    want = distance(spec_of(files["robot"]))
    assert want != pytest.approx(default_distance(), abs=1e-6)
    run = cli("simulate", str(CTRL), "-T", str(T), "--json", "--robot", str(files["robot"]))
    assert run.code == 0 and json.loads(run.out)["distance"] == want
    run = cli("simulate", str(files["recorded"]), "-T", str(T), "--json")  # its recorded robot
    assert json.loads(run.out)["distance"] == want and "note" not in run.err
    run = cli(
        "simulate",
        str(files["recorded"]),
        "-T",
        str(T),
        "--robot",
        str(files["other"]),
        "--plot",
        str(files["dir"] / "p.png"),
    )
    assert run.code == 0 and (files["dir"] / "p.png").exists()
    assert "note: the robot of" in run.err and "differs from the one" in run.err
    assert "friction 0.7 -> 0.9" in run.err


def test_compile_records_the_robot_and_the_twin_uses_it(
    files: dict[str, Path], cli: Callable[..., CliRun]
) -> None:
    build = files["dir"] / "build"
    assert (
        cli("compile", str(CTRL), "-o", str(build), "-q", "--robot", str(files["robot"])).code == 0
    )
    manifest = json.loads((build / "manifest.json").read_text())
    assert manifest["robot_values"]["friction"] == 0.7
    from bstool import buildfile
    from hil_mock.body import robot_spec

    assert robot_spec(buildfile.load(build)) == spec_of(files["robot"])
    recorded = files["dir"] / "build2"  # a controller's recorded robot goes into its build
    assert cli("compile", str(files["recorded"]), "-o", str(recorded), "-q").code == 0
    assert json.loads((recorded / "manifest.json").read_text())["robot_values"]["friction"] == 0.7
    plain = files["dir"] / "build3"  # no robot file anywhere: the manifest is as before
    assert cli("compile", str(CTRL), "-o", str(plain), "-q").code == 0
    assert "robot_values" not in json.loads((plain / "manifest.json").read_text())
    run = cli("twin", str(build), "-T", str(T), "--json", "-q")
    out = json.loads(run.out)
    assert run.code == 0 and out["verdict"] == "equal"
    assert out["sim_distance"] == pytest.approx(
        _reference(build, spec_of(files["robot"])), abs=1e-12
    )
    run = cli("twin", str(build), "-T", str(T), "--json", "-q", "--robot", str(files["other"]))
    assert run.code == 0 and json.loads(run.out)["sim_distance"] == pytest.approx(
        _reference(build, spec_of(files["other"])), abs=1e-12
    )
    run = cli("simulate", "--build", str(build), "-T", str(T), "--json")
    assert run.code == 0
    stamp = json.loads(run.out)["distance"]
    run = cli(
        "simulate", "--build", str(build), "-T", str(T), "--json", "--robot", str(files["other"])
    )
    assert json.loads(run.out)["distance"] != stamp


def _reference(build: Path, spec: object) -> float:
    """The twin's reference simulator for ``build`` on ``spec``."""
    from bstool import buildfile
    from hil_mock.check import settle_seconds

    b = buildfile.load(build)
    sim = Simulator(spec, transition_time=b.period, settle_time=settle_seconds(b))  # type: ignore[arg-type]
    return sim.run(load_controller(CTRL).states(T)).distance


def test_stamp_timed_simulate_takes_the_robot(
    files: dict[str, Path], cli: Callable[..., CliRun]
) -> None:
    a = cli("simulate", str(CTRL), "-T", str(T), "--stamp-timed", "--json")
    b = cli(
        "simulate",
        str(CTRL),
        "-T",
        str(T),
        "--stamp-timed",
        "--json",
        "--robot",
        str(files["robot"]),
    )
    assert a.code == b.code == 0
    assert json.loads(a.out)["distance"] != json.loads(b.out)["distance"]


def test_the_experiment_commands(files: dict[str, Path], cli: Callable[..., CliRun]) -> None:
    r = str(files["robot"])
    want = distance(spec_of(files["robot"]))
    run = cli("extrapolate", str(CTRL), "-T", str(T), "--no-reinit", "--json", "--robot", r)
    assert json.loads(run.out)["curves"]["plain"][-1] == pytest.approx(want, abs=1e-12)
    run = cli("paths", str(CTRL), "-T", str(T), "--json", "--robot", r)
    assert json.loads(run.out)["ca1d"]["distance"] == pytest.approx(want, abs=1e-12)
    run = cli(
        "faults",
        str(CTRL),
        "-T",
        str(T),
        "--k",
        "1",
        "--samples",
        "1",
        "--json",
        "-q",
        "--robot",
        r,
    )
    assert run.code == 0 and json.loads(run.out)["baseline_distance"] == pytest.approx(want)
    run = cli(
        "rotate",
        str(CTRL),
        "--legs",
        "1",
        "-T",
        str(T),
        "--json",
        "--robot",
        r,
        "-o",
        str(files["dir"] / "rot.json"),
    )
    assert run.code == 0
    run = cli("model", "--robot", r, "--xml", "-")
    assert run.code == 0 and 'friction="0.7 ' in run.out
    run = cli(
        "report",
        str(files["recorded"]),
        "-T",
        str(T),
        "--extrapolate",
        "3",
        "-o",
        str(files["dir"] / "report"),
        "--robot",
        str(files["other"]),
    )
    assert run.code == 0 and "differs from the one" in run.err


def test_sensitivity_runs_every_controller_on_the_same_robots(
    files: dict[str, Path], cli: Callable[..., CliRun]
) -> None:
    other = traced_controller("nnsin")
    run = cli(
        "sensitivity",
        str(CTRL),
        str(other),
        "-T",
        str(T),
        "--points",
        "2",
        "--samples",
        "3",
        "--json",
        "-q",
        "--robot",
        str(files["robot"]),
    )
    assert run.code == 0
    out = json.loads(run.out)
    first, second = out["controllers"]
    assert first["nominal"] == pytest.approx(distance(spec_of(files["robot"])), abs=1e-12)
    from bstool.experiments.sensitivity import design

    plan = design(robotfile.load(files["robot"]), points=2, samples=3, seed=0)
    period = plan.robot.spec.transition_time  # a sample's servo speed keeps the period
    want = [distance(r, period=period) for r in plan.joint]
    assert np.allclose(first["joint"], want, atol=1e-12)
    assert len(second["joint"]) == 3 and second["joint"] != first["joint"]
    assert set(first["sweeps"]) == set(robotfile.load(files["robot"]).box.names)
    for key, points in first["sweeps"].items():
        assert len(points) == 2 and first["hurts_most"][key]["distance"] == min(
            p[1] for p in points
        )


@pytest.mark.slow
def test_demo_takes_the_robot(files: dict[str, Path], cli: Callable[..., CliRun]) -> None:
    run = cli("demo", "-T", "2", "-q", "--robot", str(files["robot"]), "--controller", str(CTRL))
    assert run.code == 0 and "differs from the default robot" in run.err
