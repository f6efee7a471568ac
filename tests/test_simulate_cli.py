"""``bstool simulate``: outputs (text, JSON, PNG, MP4) and clear errors for bad input."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli

from bstool.builtin import MODELS
from bstool.errors import InputError
from bstool.moduleid import ModuleId
from bstool.sim import Simulator, hold_failed


def _states(seed: int = 0, transitions: int = 2) -> list:  # type: ignore[type-arg]
    rng = np.random.default_rng(seed)
    return rng.integers(0, 16, (transitions + 1, 5, 6)).tolist()  # type: ignore[no-any-return]


def _write(tmp_path: Path, obj: object, name: str = "states.json") -> Path:
    p = tmp_path / name
    p.write_text(json.dumps(obj))
    return p


def test_json_output_matches_the_simulator(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    states = _states()
    code, out, _ = run_cli(
        ["simulate", "--states", str(_write(tmp_path, states)), "--json"], capsys
    )
    assert code == 0
    obj = json.loads(out)
    expected = Simulator().run(np.array(states))
    assert obj["path"] == expected.path.tolist()  # JSON floats round-trip exactly
    assert obj["displacement"] == list(expected.displacement)
    assert obj["distance"] == expected.distance
    assert obj["transitions"] == 2 and obj["units"] == "m" and obj["failed"] == []


def test_states_file_as_argument_with_T_and_fail(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    states = _states(1, 3)
    path = _write(tmp_path, states)
    code, out, _ = run_cli(["simulate", str(path), "-T", "2", "--fail", "1.2", "--json"], capsys)
    assert code == 0
    obj = json.loads(out)
    held = hold_failed(np.array(states)[:3], [ModuleId(1, 2)])
    assert obj["path"] == Simulator().run(held).path.tolist()
    assert obj["failed"] == ["1.2"] and len(obj["path"]) == 3


def test_builtin_example_text_output(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli(["simulate", "--example", "-T", "2"], capsys)
    assert code == 0
    assert "built-in example" in out and "distance:" in out and "displacement:" in out


@pytest.mark.parametrize("model", MODELS)
def test_builtin_evolved_controllers_replay_their_fitness(
    model: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """The shipped controllers were evolved stamp-timed: `--stamp-timed` plays the same
    schedule model, so the run's fitness comes back to the bit."""
    from bstool.builtin import builtin_controller

    data = json.loads(builtin_controller(model).read_text())
    assert data["ga"]["stamp_timed"] is True
    code, out, _ = run_cli(["simulate", "--model", model, "--stamp-timed", "--json", "-q"], capsys)
    result = json.loads(out)
    assert code == 0
    assert result["fitness"] == data["fitness"], (
        "the schedule model moved (templates or timing model changed?): re-evolve or "
        "re-measure the shipped controllers, docs/DEVELOPING.md"
    )
    assert result["stamp_timed"] is True and result["schedule"] == "model"
    assert result["transitions"] == data["max_trans"] and result["timing_file"] is None
    code, out, _ = run_cli(["simulate", "--model", model, "--json", "-q"], capsys)
    assert code == 0 and json.loads(out)["distance"] != data["fitness"]  # plain is another robot


def test_stamp_timed_period_comes_from_the_run_unless_given(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from conftest import traced_controller

    from bstool.compile.build import default_period

    data = json.loads(traced_controller("ca1d").read_text())
    data["ga"]["period"] = 0.5
    ctrl = tmp_path / "c.json"
    ctrl.write_text(json.dumps(data))
    runs = {}
    for extra in ([], ["--period", "0.45"]):
        code, out, err = run_cli(["simulate", str(ctrl), "--stamp-timed", "-T", "3", "--json",
                                  "-q", *extra], capsys)  # fmt: skip
        assert code == 0, err
        runs[tuple(extra)] = json.loads(out)
    assert runs[()]["period"] == 0.5 and runs[("--period", "0.45")]["period"] == 0.45
    assert runs[()]["path"] != runs[("--period", "0.45")]["path"]
    data["ga"]["stamp_timed"] = False  # a plain run's period is not a build's
    ctrl.write_text(json.dumps(data))
    code, out, _ = run_cli(["simulate", str(ctrl), "--stamp-timed", "-T", "1", "--json", "-q"],
                           capsys)  # fmt: skip
    assert code == 0 and json.loads(out)["period"] == default_period(5, 6)


def test_stamp_timed_needs_the_runs_timing_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run evolved with --timing F replays with F; a missing or changed F is a clear error."""
    from dataclasses import replace

    from conftest import traced_controller

    from bstool import timingfile
    from bstool.evolve.options import timing_record

    timing = tmp_path / "t.json"
    timingfile.dump(timingfile.DEFAULT, timing)
    data = json.loads(traced_controller("ca1d").read_text())
    data["ga"]["timing"] = timing_record(timing)
    ctrl = tmp_path / "c.json"
    ctrl.write_text(json.dumps(data))
    code, out, err = run_cli(["simulate", str(ctrl), "--stamp-timed", "-T", "1", "--json", "-q"],
                             capsys)  # fmt: skip
    assert code == 0 and json.loads(out)["timing_file"] == str(timing), err
    timingfile.dump(replace(timingfile.DEFAULT, source="another stamp"), timing)  # same name
    code, _, err = run_cli(["simulate", str(ctrl), "--stamp-timed", "-T", "1", "-q"], capsys)
    assert code == 2 and "has changed since" in err and "--timing F" in err
    timing.unlink()
    code, _, err = run_cli(["simulate", str(ctrl), "--stamp-timed", "-T", "1", "-q"], capsys)
    assert code == 2 and "which is not there" in err and "Traceback" not in err


def test_stamp_timed_refuses_a_states_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from conftest import traced_controller

    from bstool.controllers import load_controller

    states = load_controller(traced_controller("ca1d")).states(2)
    path = tmp_path / "s.json"
    path.write_text(json.dumps(np.asarray(states).tolist()))
    code, _, err = run_cli(["simulate", str(path), "--stamp-timed", "-q"], capsys)
    assert code == 2 and "needs a controller file" in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--period", "0.5"], "--period only applies with --stamp-timed"),
        (["--stamp-timed", "--example"], "--stamp-timed does not combine with --example"),
        (["--stamp-timed", "--fail", "0.1"], "--stamp-timed does not combine with --fail"),
        (["--stamp-timed", "--build", "nowhere"], "--stamp-timed does not combine with --build"),
        (["--timing", "t.json"], "--timing needs --build or --stamp-timed"),
        (["--other-builds", "2"], "--other-builds only applies with --stamp-timed"),
    ],
)
def test_stamp_timed_misuse_is_a_clear_error(
    args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = run_cli(["simulate", *args], capsys)
    assert code == 2 and message in err and "Traceback" not in err


def test_other_builds_are_the_ones_after_those_it_was_scored_on(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """--other-builds N: the controller on N more builds, each alone; a run scored on one
    model of builds 0 and 1 (the shipped ones) gets builds 2.. (none it was scored on)."""
    from conftest import traced_controller

    from bstool.controllers import load_controller
    from bstool.robot import RobotSpec
    from hil_mock.schedule_model import schedule_model

    args = ["simulate", str(traced_controller("ca1d")), "--stamp-timed", "-T", "2", "-q"]
    code, out, err = run_cli([*args, "--other-builds", "1", "--json"], capsys)
    assert code == 0, err
    got = json.loads(out)
    ctrl = load_controller(traced_controller("ca1d"))
    third = schedule_model("ca1d", builds=3).variants[2]
    want = Simulator(RobotSpec()).run_schedule(third.schedule(ctrl.states(2))).distance
    assert got["other_build_distances"] == [want]
    assert got["fitness"] == got["distance"] != want  # one model: the fitness is its distance
    code, out, _ = run_cli([*args, "--other-builds", "1"], capsys)
    assert code == 0 and "on 1 build it was not scored on" in out


@pytest.mark.parametrize("bad", ["3", True, -1, 65])
def test_a_bad_recorded_build_count_is_a_clear_error(
    bad: object, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from conftest import traced_controller

    from hil_mock.schedule_model import schedule_model

    data = json.loads(traced_controller("ca1d").read_text())
    data["ga"]["schedule_builds"] = bad
    ctrl = tmp_path / "c.json"
    ctrl.write_text(json.dumps(data))
    code, _, err = run_cli(["simulate", str(ctrl), "--stamp-timed", "-T", "1", "-q"], capsys)
    assert code == 2 and "ga.schedule_builds" in err and "Traceback" not in err
    if bad != 65:  # 65 builds is a lot but a valid request of the library
        with pytest.raises(InputError, match="builds must be"):
            schedule_model("ca1d", builds=bad)  # type: ignore[arg-type]


def test_stamp_timed_period_defaults_to_the_evolved_one() -> None:
    from dataclasses import replace

    from conftest import traced_controller

    from bstool.commands.simulate_model import evolved_period
    from bstool.controllers import load_controller

    ctrl = load_controller(traced_controller("ca1d"))
    assert evolved_period(ctrl) is None  # shipped: compile's default period
    ga = dict(ctrl.ga or {})
    assert evolved_period(replace(ctrl, ga={**ga, "period": 0.5})) == 0.5
    assert evolved_period(replace(ctrl, ga={**ga, "period": 0.5, "stamp_timed": False})) is None


def test_plot_is_a_png(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import matplotlib.image

    png = tmp_path / "path.png"
    code, _, _ = run_cli(["simulate", "-T", "2", "--plot", str(png)], capsys)
    assert code == 0
    image = matplotlib.image.imread(png)
    assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100


@pytest.mark.slow
def test_video_is_an_mp4(tmp_path: Path) -> None:
    """Runs in a subprocess: MUJOCO_GL must be chosen before mujoco is imported, and this
    test process has imported it already."""
    import imageio.v3 as iio

    mp4 = tmp_path / "run.mp4"
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("DISPLAY", "WAYLAND_DISPLAY", "MUJOCO_GL", "PYOPENGL_PLATFORM")
    }
    proc = subprocess.run(
        [sys.executable, "-m", "bstool", "simulate", "-T", "1", "--video", str(mp4), "-q"],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr and "ctypes" not in proc.stderr
    frames = iio.imread(mp4)
    # a frame every 20 steps (25 frames/s at 2 ms) over settle + 1 transition
    assert frames.shape == (Simulator().steps_for(1) // 20, 272, 480, 3)
    assert frames.std() > 10  # not a blank picture


def test_view_without_display_is_a_clear_error(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    code, _, err = run_cli(["simulate", "-T", "1", "--view"], capsys)
    assert code != 0 and "needs a display" in err and "--video" in err
    monkeypatch.setenv("DISPLAY", ":987")  # configured, but no such X server
    code, out, err = run_cli(["simulate", "-T", "1", "--view"], capsys)
    assert code != 0 and "cannot open the display ':987'" in err and "Traceback" not in err
    assert out == ""  # checked before simulating


@pytest.mark.parametrize(
    ("content", "args", "message"),
    [
        (None, [], "states file not found"),
        ("[[[0, 1]", [], "malformed JSON"),
        ([[[0] * 6] * 4] * 2, [], "wrong robot shape"),
        ([[[0] * 5] * 5] * 2, [], "wrong robot shape"),
        ([[[0] * 6] * 4 + [[0] * 5 + [16]]] * 2, [], "state 16 at frame 0, leg 4, module 5"),
        ([[[0] * 6] * 5] * 2, ["--fail", "5.0"], "unknown module 5.0"),
        ([[[0] * 6] * 5] * 2, ["--fail", "0.6"], "unknown module 0.6"),
        ([[[0] * 6] * 5] * 2, ["--fail", "x"], "bad module address"),
        ([[[0] * 6] * 5] * 2, ["-T", "5"], "cannot run 5 transitions"),
        ({"format": "nonsense"}, [], ""),
    ],
)
def test_bad_input_is_a_clear_error(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    content: object,
    args: list[str],
    message: str,
) -> None:
    path = tmp_path / "in.json"
    if isinstance(content, str):
        path.write_text(content)
    elif content is not None:
        path.write_text(json.dumps(content))
    flag = ["--states"] if not isinstance(content, dict) else []
    code, out, err = run_cli(["simulate", *flag, str(path), *args], capsys)
    assert code != 0
    assert err.startswith("Error: ") and message in err
    assert "Traceback" not in err + out


def test_controller_and_states_together_is_an_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write(tmp_path, _states())
    code, _, err = run_cli(["simulate", str(path), "--states", str(path)], capsys)
    assert code != 0 and "not both" in err


def test_controller_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A bstool.controller/1 file runs through controllers.load_controller(...).states()."""
    from bstool import controllers

    rng = np.random.default_rng(2)
    ctrl = controllers.make_controller(
        "ca1d", rng.integers(0, 16, (5, 6)), rule=rng.integers(0, 16, 4096), max_trans=2
    )
    path = tmp_path / "best.json"
    controllers.save_controller(ctrl, path)
    code, out, err = run_cli(["simulate", str(path), "--fail", "0.0", "--json"], capsys)
    assert code == 0, err
    obj = json.loads(out)
    states = controllers.load_controller(path).states(2, ["0.0"])
    assert obj["path"] == Simulator().run(states).path.tolist()


def test_states_from_stdin(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import io

    states = _states(3, 1)
    monkeypatch.setattr("sys.stdin", io.StringIO(json.dumps(states)))
    code, out, _ = run_cli(["simulate", "--states", "-", "--json"], capsys)
    assert code == 0
    assert json.loads(out)["path"] == Simulator().run(np.array(states)).path.tolist()
