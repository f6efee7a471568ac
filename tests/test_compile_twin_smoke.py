"""Compiled programs on hil_mock's robot twin (:class:`hil_mock.robot.RobotTwin`, no physics)
reproduce the reference exactly, with and without a module dead from power-up, and keep the
timing the manifest promises (servo gaps, the period).

Small robots cut from the golden controllers run every model family quickly; the shipped NN
controller (5 × 6) checks dead modules in the middle of a leg, which the bypass wires cover
(protocol/link.md §2).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bstool.buildfile import Build
from bstool.compile.build import compile_loaded
from bstool.controllers import Controller, from_json, load_controller
from bstool.moduleid import ModuleId
from hil_mock import robot

GOLDEN = Path(__file__).parent / "golden" / "compile"
SHIPPED = Path(__file__).parent.parent / "bstool" / "data" / "controllers"
PERIOD_TOLERANCE = 0.15  # of the manifest's estimated period (a report, docs/compile.md)


def _cut(model: str, legs: int, modules: int) -> Controller:
    """The golden controller of ``model`` cut down to ``legs`` × ``modules``."""
    from bstool.controllers.reference import nn_initial_reference

    obj = load_controller(GOLDEN / f"{model}.json").to_json()
    obj["legs"], obj["modules"] = legs, modules
    obj["initial_states"] = [row[:modules] for row in obj["initial_states"][:legs]]
    if "weights" in obj:
        obj["weights"] = [[r[:modules] for r in w[:modules]] for w in obj["weights"][:legs]]
        leads = [row[0] for row in obj["initial_states"]]
        obj["initial_states"] = nn_initial_reference(model, leads, obj["weights"])
    return from_json(obj)


def _run(
    ctrl: Controller, out: Path, transitions: int, dead: list[ModuleId], period: float | None
) -> tuple[Build, robot.TwinResult]:
    res = compile_loaded(ctrl, out, period=period)
    assert res.tokenized
    build = robot.load_build(out)
    result = robot.RobotTwin(build, failed=dead, physics=False).run(transitions)
    assert result.stalled == []
    np.testing.assert_array_equal(
        result.state_array(ctrl.legs, ctrl.modules, transitions),
        ctrl.states(transitions, [(d.leg, d.module) for d in dead]),
    )
    hash8 = res.controller_hash[:8]
    assert all(a == f"bstool {m.label} {hash8}" for m, a in result.announcements.items())
    return build, result


@pytest.mark.slow
@pytest.mark.parametrize(
    ("model", "legs", "modules", "dead"),
    [
        ("ca1d", 1, 6, []),
        ("ca2dsing", 3, 4, [ModuleId(1, 0)]),
        ("nnsin", 2, 6, [ModuleId(0, 0)]),  # module 1 paces on the dead lead's R^0
        ("nnsig", 2, 6, [ModuleId(1, 3)]),
    ],
)
def test_compiled_robot_follows_reference(
    model: str, legs: int, modules: int, dead: list[ModuleId], tmp_path: Path
) -> None:
    build, result = _run(_cut(model, legs, modules), tmp_path / "build", 20, dead, 0.5)
    for m in build.manifest.modules:
        mid = m.module
        if mid in dead:
            continue
        gap = result.servo_gaps[mid]
        if model.startswith("ca"):  # NN: asserted healthy in test_link_serve.py
            assert gap < 0.025, f"{mid.label}: servo gap {gap * 1000:.1f} ms"
        assert gap <= m.timing.longest_servo_gap_s + 0.002, "manifest estimate too low"
    nominal = build.manifest.modules[0].timing.nominal_transition_s
    mean, _ = result.period_stats()
    if model.startswith("nn") and not mean > nominal * (1 - PERIOD_TOLERANCE):
        pytest.xfail(  # the states and gaps above passed; the estimate is a report
            f"NN period {mean:.3f} s under the estimate {nominal:.3f} s: a leg fed by a bypass or "
            "paced by module 1 runs faster than the lead's hold, and plan.period_ms has no term "
            "for it (docs/link-redesign.md §6)"
        )
    if dead:  # a dead neighbour's wire is still polled (every 4th round, unanswered tries)
        assert nominal * (1 - PERIOD_TOLERANCE) < mean < 1.35 * nominal, (mean, nominal)
    else:
        assert abs(mean - nominal) < PERIOD_TOLERANCE * nominal, (mean, nominal)


@pytest.mark.slow
@pytest.mark.parametrize(
    "dead",
    ["0.0", "1.1", "2.3", "3.4", "4.5"],
)
def test_nn_dead_module_anywhere_equals_failed_reference(dead: str, tmp_path: Path) -> None:
    """Issue: a dead NN module in the middle of a leg used to hide the modules before it from
    those after it; the bypass wire j-1 -> j+1 carries their states past it."""
    ctrl = load_controller(SHIPPED / "nnsin.json")
    mid = ModuleId(*map(int, dead.split(".")))
    _run(ctrl, tmp_path / "build", 20, [mid], None)
