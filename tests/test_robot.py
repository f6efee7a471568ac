"""The robot description, the state→angle map and the generated MJCF."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bstool.cli import main
from bstool.errors import InputError
from bstool.robot import ANGLE_MAX, ANGLE_MIN, RobotSpec, build_model, state_to_angle, to_mjcf


def test_state_to_angle_endpoints_and_step() -> None:
    assert state_to_angle(0, 16) == pytest.approx(-math.pi / 3, abs=1e-15)
    assert state_to_angle(15, 16) == pytest.approx(math.pi / 3, abs=1e-15)
    assert state_to_angle(7, 16) < 0 < state_to_angle(8, 16)
    steps = np.diff(state_to_angle(np.arange(16), 16))
    np.testing.assert_allclose(steps, (2 * math.pi / 3) / 15, rtol=1e-12)


@given(st.integers(2, 64), st.data())
def test_state_to_angle_is_the_papers_linear_map(k: int, data: st.DataObject) -> None:
    s = data.draw(st.integers(0, k - 1))
    theta = state_to_angle(s, k)
    assert theta == pytest.approx(-math.pi / 3 + s * (2 * math.pi / 3) / (k - 1), abs=1e-15)
    assert ANGLE_MIN - 1e-12 <= theta <= ANGLE_MAX + 1e-12
    assert state_to_angle(np.array([s]), k)[0] == theta  # arrays and scalars agree


def test_spec_defaults_and_axes() -> None:
    spec = RobotSpec()
    assert (spec.legs, spec.modules, spec.states) == (5, 6, 16)
    assert [spec.axis_of(j) for j in range(4)] == ["vertical", "horizontal"] * 2
    flipped = RobotSpec(lead_axis="horizontal")
    assert flipped.axis_of(0) == "horizontal" and flipped.axis_of(1) == "vertical"
    # a hobby servo: 0.15-0.25 s per 60° unloaded, transition long enough for the full range
    assert 0.15 <= spec.servo_speed <= 0.25
    assert spec.transition_time >= (2 * math.pi / 3) / spec.servo_no_load_speed
    with pytest.raises(InputError, match="legs must be >= 1"):
        RobotSpec(legs=0)
    with pytest.raises(InputError, match="servo_torque"):
        RobotSpec(servo_torque=-1.0)


def test_mjcf_structure() -> None:
    spec = RobotSpec()
    root = ET.fromstring(to_mjcf(spec))
    assert root.find("option").get("cone") == "elliptic"  # type: ignore[union-attr]
    assert not root.findall(".//geom[@type='cylinder']")  # the disc is n identical parts
    disc = root.find(".//body[@name='disc']")
    assert disc is not None and len(disc.findall("geom")) == spec.legs
    actuators = root.findall("./actuator/position")
    assert [a.get("name") for a in actuators[:7]] == [f"L0M{j}" for j in range(6)] + ["L1M0"]
    model = build_model(spec)
    assert (model.nu, model.njnt, model.nbody) == (30, 31, 32)
    np.testing.assert_allclose(model.actuator_ctrlrange, [[-math.pi / 3, math.pi / 3]] * 30)
    np.testing.assert_allclose(model.actuator_forcerange[:, 1], spec.servo_torque)
    assert model.body_subtreemass[1] == pytest.approx(spec.disc_mass + 30 * spec.module_mass)
    axes = model.jnt_axis[1:7]
    np.testing.assert_array_equal(axes[0::2], [[0, 0, 1]] * 3)  # lead: vertical
    np.testing.assert_array_equal(axes[1::2], [[0, 1, 0]] * 3)


def test_model_is_n_fold_symmetric() -> None:
    """Every body and geom of leg i+1 is leg i's rotated by 360°/n (at the zero pose)."""
    spec = RobotSpec()
    model = build_model(spec)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    a = 2 * math.pi / spec.legs
    rot = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    for i in range(spec.legs):
        for j in range(spec.modules):
            here = data.geom(f"L{i}M{j}").xpos
            there = data.geom(f"L{(i + 1) % spec.legs}M{j}").xpos
            np.testing.assert_allclose(rot @ here, there, atol=1e-14)
        np.testing.assert_allclose(
            rot @ data.geom(f"disc{i}").xpos, data.geom(f"disc{(i + 1) % 5}").xpos, atol=1e-14
        )


def test_servo_speed_is_a_hobby_servos() -> None:
    """The outermost module (lightest load) crosses the full range within one default
    transition, lifting itself against gravity, and never turns faster than the no-load
    speed (0.19 s per 60°) by more than the parent module's recoil."""
    spec = RobotSpec()
    model = build_model(spec)
    data = mujoco.MjData(model)
    data.ctrl[:] = 0.0
    data.ctrl[5] = ANGLE_MAX  # tip down
    mujoco.mj_step(model, data, nstep=round(spec.transition_time / spec.timestep))
    data.ctrl[5] = ANGLE_MIN  # tip up
    qadr = model.jnt_qposadr[model.joint("L0M5").id]
    dadr = model.jnt_dofadr[model.joint("L0M5").id]
    start, peak, half_time = data.qpos[qadr], 0.0, None
    steps = round(spec.transition_time / spec.timestep)
    for k in range(steps):
        mujoco.mj_step(model, data)
        peak = max(peak, abs(data.qvel[dadr]))
        if half_time is None and data.qpos[qadr] <= 0:
            half_time = (k + 1) * spec.timestep
    assert start > ANGLE_MAX - 0.05
    assert abs(data.qpos[qadr] - ANGLE_MIN) < math.radians(3)
    assert peak <= spec.servo_no_load_speed * 1.15  # relative speed: the parent recoils
    assert half_time is not None and half_time >= spec.servo_speed  # 60° takes ≥ 0.19 s


def test_model_command_writes_loadable_xml(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "robot.xml"
    assert main(["model", "--xml", str(out)]) == 0
    model = mujoco.MjModel.from_xml_path(str(out))
    assert model.nu == 30
    assert main(["model", "--xml"]) == 0
    assert capsys.readouterr().out.startswith('<mujoco model="brittle_star_5x6">')
    assert main(["model", "--legs", "4", "--modules", "3"]) == 0
    assert "4 legs × 3 modules" in capsys.readouterr().out
