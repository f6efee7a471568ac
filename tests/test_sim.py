"""The simulator: symmetry under leg rotation, determinism, standing still, state validation."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from bstool.errors import InputError
from bstool.moduleid import ModuleId
from bstool.robot import RobotSpec
from bstool.sim import Simulator, hold_failed, states_from_json, validate_states


@pytest.fixture(scope="module")
def sim() -> Simulator:
    return Simulator()


def _random_states(seed: int, transitions: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 16, (transitions + 1, 5, 6))


def _rotation(angle: float) -> np.ndarray:
    return np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])


@pytest.mark.parametrize("seed", [1, 2])
def test_rotating_legs_rotates_the_path(sim: Simulator, seed: int) -> None:
    """Leg i+1 running leg i's states rotates the whole path by 360°/n (first 3 transitions,
    to 1e-4 of the distance: the model is n-fold symmetric, contacts and friction included)."""
    states = _random_states(seed, 3)
    base = sim.run(states)
    shifted = sim.run(np.roll(states, 1, axis=1))
    expected = base.path @ _rotation(2 * math.pi / 5).T
    assert base.distance > 0.005  # the gait does move: the comparison means something
    assert np.abs(shifted.path - expected).max() <= 1e-4 * base.distance
    assert shifted.distance == pytest.approx(base.distance, rel=1e-4)


def test_deterministic_to_the_bit(sim: Simulator) -> None:
    states = _random_states(3, 3)
    first = sim.run(states).path
    sim.run(_random_states(4, 2))  # an unrelated run in between must leave no trace
    again = sim.run(states).path
    fresh = Simulator().run(states).path
    assert first.tobytes() == again.tobytes() == fresh.tobytes()


@pytest.mark.parametrize("state", [0, 7, 15])
def test_constant_states_stand_still(sim: Simulator, state: int) -> None:
    result = sim.run(np.full((5, 5, 6), state))
    assert result.path.shape == (5, 2)
    assert result.distance < 1e-4  # metres, over 4 transitions


def test_result_shape_and_distance(sim: Simulator) -> None:
    result = sim.run(_random_states(5, 2))
    assert result.path.shape == (3, 2) and result.transitions == 2
    dx, dy = result.displacement
    assert result.distance == math.hypot(dx, dy)
    assert sim.run(_random_states(5, 0)).distance == 0.0  # R^0 only: no transition
    out = result.to_json()
    assert set(out) == {"displacement", "distance", "path"} and len(out["path"]) == 3


def test_transition_time_sets_steps() -> None:
    spec = RobotSpec()
    sim = Simulator(spec, transition_time=0.1, settle_time=0.2)
    assert (sim.steps_per_transition, sim.settle_steps) == (50, 100)
    assert Simulator(spec).steps_per_transition == round(spec.transition_time / spec.timestep)
    with pytest.raises(InputError, match="transition time"):
        Simulator(spec, transition_time=0.0)


def test_validate_states_errors() -> None:
    spec = RobotSpec()
    ok = validate_states(np.zeros((2, 5, 6), dtype=np.uint8), spec)
    assert ok.dtype == np.int64
    with pytest.raises(InputError, match="wrong robot shape: frames are 4 legs × 6 modules"):
        validate_states(np.zeros((2, 4, 6)), spec)
    with pytest.raises(InputError, match=r"state 16 at frame 1, leg 2, module 3 is out of range"):
        bad = np.zeros((2, 5, 6), dtype=int)
        bad[1, 2, 3] = 16
        validate_states(bad, spec)
    with pytest.raises(InputError, match="out of range"):
        validate_states(-np.ones((1, 5, 6), dtype=int), spec)
    with pytest.raises(InputError, match="integers"):
        validate_states(np.full((1, 5, 6), 0.5), spec)
    with pytest.raises(InputError, match="expected frames"):
        validate_states(np.zeros((5, 6)), spec)


def test_states_from_json_errors() -> None:
    spec = RobotSpec()
    frame = [[0] * 6 for _ in range(5)]
    assert states_from_json([frame, frame], spec).shape == (2, 5, 6)
    with pytest.raises(InputError, match="non-empty JSON list"):
        states_from_json({"a": 1}, spec)
    with pytest.raises(InputError, match="wrong robot shape at frame 1"):
        states_from_json([frame, frame[:4]], spec)
    with pytest.raises(InputError, match="leg 0 has 5 modules"):
        states_from_json([[[0] * 5] * 5], spec)
    with pytest.raises(InputError, match="not an integer"):
        states_from_json([[[0] * 5 + ["3"], *frame[1:]]], spec)
    with pytest.raises(InputError, match="frame 0 is not a list"):
        states_from_json([3], spec)


def test_hold_failed_keeps_r0() -> None:
    states = _random_states(6, 4)
    held = hold_failed(states, [ModuleId(2, 3), ModuleId(0, 0)])
    assert (held[:, 2, 3] == states[0, 2, 3]).all() and (held[:, 0, 0] == states[0, 0, 0]).all()
    mask = np.ones((5, 6), bool)
    mask[2, 3] = mask[0, 0] = False
    assert (held[:, mask] == states[:, mask]).all()


def _no_library(name: str) -> None:
    raise OSError(f"{name}: cannot open shared object file")


def test_headless_gl_choice(monkeypatch: pytest.MonkeyPatch) -> None:
    from bstool.sim.gl import configure_headless_gl

    for var in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY", "WAYLAND_DISPLAY"):
        monkeypatch.setenv(var, "x")  # records the original value, restored after the test
        monkeypatch.delenv(var)
    import ctypes
    import ctypes.util

    find = ctypes.util.find_library
    monkeypatch.setattr(ctypes.util, "find_library", lambda name: "libOSMesa.so.8")
    assert configure_headless_gl() == "osmesa"  # no display, nothing configured: OSMesa
    monkeypatch.delenv("MUJOCO_GL")
    monkeypatch.setattr(ctypes.util, "find_library", lambda name: None)
    monkeypatch.setattr(ctypes, "CDLL", _no_library)
    with pytest.raises(InputError, match="OSMesa") as missing:  # no traceback from ctypes
        configure_headless_gl()
    assert "libosmesa6" in (missing.value.hint or "") and "MUJOCO_GL" not in os.environ
    monkeypatch.setattr(ctypes.util, "find_library", find)
    monkeypatch.setenv("MUJOCO_GL", "egl")
    assert configure_headless_gl() == "egl"  # an explicit choice is kept
    monkeypatch.delenv("MUJOCO_GL")
    monkeypatch.setenv("DISPLAY", ":0")
    assert configure_headless_gl() == "glfw"  # a display: MuJoCo's default
