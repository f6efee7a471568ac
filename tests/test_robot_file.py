"""The robot file (bstool.robot/1): the default file, round trips, every error, the uncertain
ranges and their draws, and which robot a command resolves to."""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bstool.errors import InputError
from bstool.robot import RobotSpec
from bstool.robot import robotfile as rf
from bstool.robot.apply import PHYSICS_FIELDS
from bstool.robot.uncertain import DEFAULT_BOX, ParamRange, Uncertainty


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "robot.toml"
    p.write_text(text)
    return p


def test_the_default_file_is_the_default_robot_and_box(tmp_path: Path) -> None:
    text = rf.default_text()
    robot = rf.load(_write(tmp_path, text))
    assert robot.spec == RobotSpec() and robot.box == DEFAULT_BOX
    for f in dataclasses.fields(RobotSpec):  # every key is there, with a comment
        line = next(x for x in text.splitlines() if x.startswith(f"{f.name} = "))
        assert "#" in line and len(line.split("#", 1)[1].strip()) > 10


def test_a_missing_key_keeps_its_default(tmp_path: Path) -> None:
    robot = rf.load(_write(tmp_path, "friction = 0.7\nmodule_mass = 0.1\n"))
    assert robot.spec == dataclasses.replace(RobotSpec(), friction=0.7, module_mass=0.1)
    assert robot.uncertain is None and robot.box == DEFAULT_BOX


@settings(max_examples=40, deadline=None)
@given(
    friction=st.floats(0.05, 2.0),
    torque=st.floats(0.05, 2.0),
    low=st.floats(0.5, 1.0),
    span=st.floats(0.0, 1.0),
    log=st.booleans(),
)
def test_round_trip_through_the_record(
    friction: float, torque: float, low: float, span: float, log: bool
) -> None:
    """What a run records (to_json) reads back as the same robot, ranges included."""
    law = "log-uniform" if log else "uniform"
    spec = dataclasses.replace(RobotSpec(), friction=friction, servo_torque=torque)
    box = Uncertainty((ParamRange("friction", low, low + span, relative=True, distribution=law),))
    robot = rf.Robot(spec, box)
    again = rf.from_record(robot.to_json(), "test")
    assert again.spec == spec and again.box == box and again.digest() == robot.digest()


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("frction = 0.3\n", r"unknown key 'frction'.*"),
        ("friction = true\n", "friction must be a float"),
        ("friction = 'high'\n", "friction must be a number"),
        ("friction = -0.2\n", "friction must be a positive finite number"),
        ("friction = 0\n", "friction must be a positive finite number"),
        ("friction = nan\n", "friction must be a positive finite number"),
        ("friction = inf\n", "friction must be a positive finite number"),
        ("legs = 4\n", "legs = 4: bstool evolves"),
        ("states = 8.0\n", "states must be an integer"),
        ("lead_axis = 'diagonal'\n", "lead_axis must be"),
        ("format = 'bstool.robot/9'\n", "format must be"),
        ("friction = [\n", "malformed TOML"),
        ("[uncertain]\nfriction = { range = [1.0, 0.3] }\n", "low end 1 is above the high end"),
        ("[uncertain]\nfriction = { range = [0.0, 0.3] }\n", "must stay positive"),
        ("[uncertain]\nservo_torque = { scale = [-1, 1] }\n", "leaves servo_torque at -0.4"),
        ("[uncertain]\nfriction = { range = [0.3, 1], scale = [1, 2] }\n", "exactly one of"),
        ("[uncertain]\nfriction = {}\n", "exactly one of"),
        ("[uncertain]\nfriction = { range = [0.3] }\n", r"range must be \[low, high\]"),
        ("[uncertain]\nfriction = { range = [0.3, 'x'] }\n", r"range must be \[low, high\]"),
        ("[uncertain]\nfriction = { range = [0.3, inf] }\n", "must be finite"),
        ("[uncertain]\nfriction = { range = [0.3, 1], law = 'x' }\n", "unknown key"),
        ("[uncertain]\nfriction = { range = [0.3, 1], distribution = 'x' }\n", "distribution"),
        ("[uncertain]\nfriction = 0.5\n", "must be a table"),
        ("[uncertain]\nmodule_pitch = { scale = [0.9, 1.1] }\n", "cannot be uncertain"),
        ("[uncertain]\nfrictoin = { scale = [0.9, 1.1] }\n", "unknown parameter"),
        ("uncertain = 3\n", "must be a table"),
    ],
)
def test_every_mistake_names_the_file_and_the_key(tmp_path: Path, text: str, match: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(InputError, match=match) as err:
        rf.load(path)
    assert str(path) in err.value.message


def test_did_you_mean(tmp_path: Path) -> None:
    with pytest.raises(InputError) as err:
        rf.load(_write(tmp_path, "servo_torqe = 0.3\n"))
    assert err.value.hint == "did you mean servo_torque?"
    with pytest.raises(InputError) as err2:
        rf.load(_write(tmp_path, "[uncertain]\nfrictoin = { scale = [0.9, 1.1] }\n"))
    assert err2.value.hint == "did you mean friction?"


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="robot file not found") as err:
        rf.load(tmp_path / "nope.toml")
    assert "bstool robot" in (err.value.hint or "")


def test_ranges_absolute_and_relative_uniform_and_log() -> None:
    nominal = RobotSpec()
    absolute = ParamRange("friction", 0.3, 1.0, distribution="log-uniform")
    relative = ParamRange("servo_torque", 0.7, 1.15, relative=True)
    assert absolute.bounds(nominal) == (0.3, 1.0)
    assert relative.bounds(nominal) == pytest.approx((0.28, 0.46))
    assert absolute.draw(nominal, 0.5) == pytest.approx(math.sqrt(0.3))  # the geometric mean
    assert relative.draw(nominal, 0.5) == pytest.approx(0.37)
    assert absolute.points(nominal, 3) == pytest.approx([0.3, math.sqrt(0.3), 1.0])


def test_draws_are_seeded_within_their_ranges_and_change_only_the_box() -> None:
    nominal = RobotSpec()
    a = DEFAULT_BOX.samples(nominal, 200, seed=[1, 2])
    assert a == DEFAULT_BOX.samples(nominal, 200, seed=[1, 2])
    assert a != DEFAULT_BOX.samples(nominal, 200, seed=[1, 3])
    for r in DEFAULT_BOX.ranges:
        lo, hi = r.bounds(nominal)
        values = np.array([getattr(x, r.name) for x in a])
        assert values.min() >= lo and values.max() <= hi
        assert values.max() - values.min() > 0.5 * (hi - lo)
    untouched = [f.name for f in dataclasses.fields(RobotSpec) if f.name not in DEFAULT_BOX.names]
    assert all(getattr(x, n) == getattr(nominal, n) for x in a for n in untouched)
    assert set(DEFAULT_BOX.names) <= set(PHYSICS_FIELDS)


def test_resolve_prefers_the_option_then_the_record(tmp_path: Path) -> None:
    mine = _write(tmp_path, "friction = 0.7\n")
    recorded = rf.Robot(dataclasses.replace(RobotSpec(), friction=0.5)).to_json()
    assert rf.resolve(None, None) == (rf.Robot(), None)
    robot, note = rf.resolve(None, recorded, what="best.json")
    assert robot.spec.friction == 0.5 and note is None
    robot, note = rf.resolve(mine, recorded, what="best.json")
    assert robot.spec.friction == 0.7
    assert note is not None and "the one best.json was evolved on" in note
    assert "friction 0.5 -> 0.7" in note
    same = _write(tmp_path, "friction = 0.5\n")
    assert rf.resolve(same, recorded, what="best.json")[1] is None


def test_bstool_robot_prints_the_file_and_checks_one(
    tmp_path: Path, cli: object, capsys: pytest.CaptureFixture[str]
) -> None:
    from bstool.cli import main

    assert main(["robot"]) == 0
    out = capsys.readouterr().out
    assert tomllib.loads(out)["format"] == rf.FORMAT
    target = tmp_path / "mine.toml"
    assert main(["robot", "-o", str(target)]) == 0
    assert target.read_text() == out
    target.write_text(out.replace("friction = 0.4 ", "friction = 0.6 "))
    capsys.readouterr()
    assert main(["robot", str(target)]) == 0
    assert "friction 0.4 -> 0.6" in capsys.readouterr().out
    (tmp_path / "bad.toml").write_text("frction = 1\n")
    assert main(["robot", str(tmp_path / "bad.toml")]) == 2
    err = capsys.readouterr().err
    assert "unknown key 'frction'" in err and "did you mean friction" in err
