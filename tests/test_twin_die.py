"""A module dying mid-run on the twin (``RobotTwin(die=...)``, ``bstool twin --die L.M@T``).

The dying module stops once it has shown S^T and its neighbours have had S^T; its neighbours
wait for it until the dead-limit (keeping S^T, an NN bypass taking over), then go on without
it (protocol/link.md §4.5). The states equal ``controller.states(T, failed_at={module: T})``
from the first transition on.
Figures for every module of every model: ``python bench/twin_die_sweep.py``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import TracedBuild

from bstool.cli import main
from bstool.compile import emulate
from bstool.compile.calibration import DEFAULT
from bstool.compile.plan import build_plans
from bstool.controllers import load_controller
from bstool.moduleid import ModuleId
from bstool.robot import state_to_angle
from hil_mock.robot import RobotTwin, load_build

TRANSITIONS = 32
SWITCH_OVER = 12  # transitions after the death until the dead-limit (>= 1.5 s; 2-4 s nominal)


@pytest.fixture(scope="module", params=["ca2ddiff", "nnsin"])
def build(request: pytest.FixtureRequest, traced_build: TracedBuild) -> Path:
    return traced_build(request.param)


@pytest.mark.slow
@pytest.mark.parametrize(("dying", "at"), [(ModuleId(0, 0), 5), (ModuleId(2, 3), 7)])
def test_a_module_dying_mid_run_equals_the_failed_at_reference(
    build: Path, dying: ModuleId, at: int
) -> None:
    b = load_build(build)
    ctrl = load_controller(build / "controller.json")
    twin = RobotTwin(b, die={dying: at}, physics=False)
    result = twin.run(TRANSITIONS)
    assert result.stalled == []
    assert list(twin.died) == [dying]
    got = result.state_array(b.legs, b.modules, TRANSITIONS)
    np.testing.assert_array_equal(got, ctrl.states(TRANSITIONS, failed_at={dying: at}))
    # its servo holds S^T (the last target it was given)
    held = int(got[at, dying.leg, dying.module])
    assert twin.servos[dying].target == pytest.approx(state_to_angle(held, b.manifest.robot.states))
    assert len(twin.records[dying].states) == at + 1
    # after the dead-limit the robot runs on at about the estimated period (timing model)
    after = [p for m, ps in result.periods.items() if m != dying for p in ps[at + SWITCH_OVER :]]
    estimate = max(m.timing.nominal_transition_s for m in b.manifest.modules)
    assert np.mean(after) <= 1.25 * estimate
    gap = max(m.timing.longest_servo_gap_s for m in b.manifest.modules)
    assert max(result.servo_gaps.values()) <= 1.5 * gap


def test_dying_at_0_and_limp(build: Path) -> None:
    """``@0``: the module dies at its first pulse (after the join, before S^1), so its
    neighbours hold R^0 of it: the states are the reference's ``failed``; ``limp_failed`` makes
    its servo limp."""
    b = load_build(build)
    ctrl = load_controller(build / "controller.json")
    dying = ModuleId(1, 2)
    twin = RobotTwin(b, die={dying: 0}, limp_failed=True, physics=False)
    result = twin.run(6)
    np.testing.assert_array_equal(
        result.state_array(b.legs, b.modules, 6), ctrl.states(6, failed=[dying])
    )
    assert twin.servos[dying].limp and list(twin.died) == [dying]


@pytest.fixture(scope="module")
def nnsin_build(traced_build: TracedBuild) -> Path:
    return traced_build("nnsin")


@pytest.mark.parametrize(
    "die", [{ModuleId(4, 2): 4, ModuleId(4, 3): 10}, {ModuleId(4, 3): 4, ModuleId(4, 2): 10}]
)
def test_two_neighbours_dying_leave_the_module_before_them_alone(
    nnsin_build: Path, die: dict[ModuleId, int]
) -> None:
    """Issue 16: 4.2 and 4.3 dying one after the other (either order). Everything before and
    at the pair must equal the reference; the modules after it are the documented limit: no
    frame reaches them, 4.4 paces on the states it holds (PaceTicks) and 4.5 follows it, so
    they run on (no stall) showing what ``emulate.run`` gives them (a constant state)."""
    b = load_build(nnsin_build)
    ctrl = load_controller(nnsin_build / "controller.json")
    T = 14
    result = RobotTwin(b, die=die, physics=False).run(T)
    assert result.stalled == []
    got = result.state_array(b.legs, b.modules, T)
    want = ctrl.states(T, failed_at=die)
    np.testing.assert_array_equal(got[:, :, :4], want[:, :, :4])  # 4.1 is before the pair
    np.testing.assert_array_equal(got[:, :4], want[:, :4])  # the other legs
    limit = emulate.run(build_plans(ctrl, DEFAULT, b.period, "0" * 8), T, die=die)
    np.testing.assert_array_equal(got, limit)


def test_twin_cli_die(build: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = ["twin", str(build), "-T", "8", "--no-physics", "-q"]
    assert main([*args, "--die", "0.1@3"]) == 0
    assert "EQUAL to" in capsys.readouterr().out
    for bad, said in [
        ("0.1", "bad --die '0.1': expected L.M@T"),
        ("0.1@x", "expected L.M@T"),
        ("0.1@-1", "expected L.M@T"),
        ("7.1@2", "unknown module 7.1"),
    ]:
        assert main([*args, "--die", bad]) == 2
        err = capsys.readouterr().err
        assert said in err and "Traceback" not in err
    assert main([*args, "--die", "0.1@2", "--fail", "0.1"]) == 2
    assert "both failed from power-up and dying" in capsys.readouterr().err


def test_twin_cli_names_the_documented_limit(
    nnsin_build: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 16's command: exit 0, every module before and at the pair equal to `bstool states
    --fail-at`, the two after it compared with the compiled programs' emulation, and said so."""
    args = ["twin", str(nnsin_build), "-T", "14", "--no-physics", "-q"]
    assert main([*args, "--die", "4.2@4", "--die", "4.3@10"]) == 0
    out = capsys.readouterr().out
    assert "EQUAL to" in out and "(L4.M4, L4.M5)" in out and "documented limit" in out
    assert main([*args, "--die", "4.2@4"]) == 0  # one death: no limit, no note
    assert "note:" not in capsys.readouterr().out


def test_after_dead_pairs() -> None:
    from hil_mock.session import after_dead_pairs

    m = ModuleId
    assert after_dead_pairs(5, 6, [m(4, 2), m(4, 3)], nn=True) == [m(4, 4), m(4, 5)]
    assert after_dead_pairs(5, 6, [m(4, 2), m(4, 3)], nn=False) == []
    assert after_dead_pairs(5, 6, [m(4, 2), m(4, 4)], nn=True) == []  # not neighbours
    assert after_dead_pairs(5, 6, [m(1, 4), m(1, 5)], nn=True) == []  # at the tip
