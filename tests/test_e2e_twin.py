"""The proof that what we flash is what evolved (issue 7), for each of the five models:

shipped controller → bstool compile → tokenize → bstool flash (all 30 twins, over the
programming protocol, through the `bstwin://` URLs of a --ports file) → run on the robot twin →
every module's states equal `bstool states` for 60+ transitions; the same with one module dead
from the start equals `bstool states --fail L.M`; the disc path matches the stamp-timed
`bstool simulate --build` (issue 13); the manifest's timing estimates agree with the twin.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import traced_controller

from bstool.builtin import MODELS as BUILTIN
from bstool.cli import main
from bstool.controllers import load_controller
from bstool.moduleid import ModuleId
from hil_mock.fleet import make_fleet
from hil_mock.robot import RobotTwin, load_build

pytestmark = pytest.mark.slow

LONG = 60  # transitions compared exactly
PATH_TRANSITIONS = 10  # transitions over which the path must match the stamp-timed simulator
PATH_TOLERANCE_M = 0.005  # issue 13: at each transition
PERIOD_TOLERANCE = 0.15  # measured mean period against the manifest's estimate (a report)


@pytest.fixture(scope="module", params=BUILTIN)
def flashed(request: pytest.FixtureRequest, traced_build):  # type: ignore[no-untyped-def]
    model = request.param
    source = traced_controller(model)
    build = traced_build(model, fresh=True)  # flash writes its progress file into it
    manifest = load_build(build)
    fleet = make_fleet(manifest.legs, manifest.modules)
    ports = build.parent / "ports.json"
    ports.write_text(json.dumps({str(m): url for m, url in fleet.urls.items()}))
    assert main(["flash", "--all", "--ports", str(ports), str(build), "-q"]) == 0
    yield model, load_controller(source), manifest, fleet
    fleet.close()


def test_flashed_images_are_the_build(flashed) -> None:  # type: ignore[no-untyped-def]
    _, _, build, fleet = flashed
    for mid, eeprom in fleet.eeproms.items():
        for slot, image in build.images(mid).items():
            assert eeprom.slot(slot) == image


def test_states_equal_the_reference(flashed) -> None:  # type: ignore[no-untyped-def]
    _, ctrl, build, fleet = flashed
    result = RobotTwin(build, eeproms=dict(fleet.eeproms), physics=False).run(LONG)
    assert result.stalled == []
    np.testing.assert_array_equal(
        result.state_array(build.legs, build.modules, LONG), ctrl.states(LONG)
    )
    hash8 = build.manifest.controller.hash8
    assert all(a == f"bstool {m.label} {hash8}" for m, a in result.announcements.items())
    mean, _ = result.period_stats()  # the serve loop's period, about the estimate
    estimate = max(m.timing.nominal_transition_s for m in build.manifest.modules)
    assert abs(mean - estimate) <= PERIOD_TOLERANCE * estimate


@pytest.mark.parametrize("dead", [ModuleId(0, 0), ModuleId(2, 3)])
def test_a_dead_module_equals_the_failed_reference(flashed, dead: ModuleId) -> None:  # type: ignore[no-untyped-def]
    _, ctrl, build, fleet = flashed
    twin = RobotTwin(build, eeproms=dict(fleet.eeproms), failed=[dead], physics=False)
    result = twin.run(LONG)
    np.testing.assert_array_equal(
        result.state_array(build.legs, build.modules, LONG), ctrl.states(LONG, failed=[dead])
    )


def test_path_and_timing_agree_with_simulator_and_manifest(flashed) -> None:  # type: ignore[no-untyped-def]
    """Issue 13: the twin walks as the stamp-timed simulator does (the build's own schedule):
    distance within 2 % or 2 mm, the path within 5 mm at each of the first transitions. (The
    plain simulator moves every module at one instant; the serve loop does not.)"""
    from hil_mock.schedule_extract import simulate_build

    _, _, build, fleet = flashed
    result = RobotTwin(build, eeproms=dict(fleet.eeproms)).run(PATH_TRANSITIONS)
    timed, _, _ = simulate_build(build, PATH_TRANSITIONS)
    assert len(result.path) == len(timed.path) == PATH_TRANSITIONS + 1
    assert np.max(np.linalg.norm(result.path - timed.path, axis=1)) < PATH_TOLERANCE_M
    assert abs(result.distance - timed.distance) <= max(0.02 * timed.distance, 0.002)
    for m in build.manifest.modules:  # timing: the servo never starved beyond the estimate
        mid = m.module
        assert result.servo_gaps[mid] <= m.timing.longest_servo_gap_s * 1.1 + 0.001
        if build.manifest.controller.model.startswith("ca"):  # NN: protocol/link.md §6
            assert result.servo_gaps[mid] <= 0.025 + 1e-6


def test_twin_cli_reports_equal(
    flashed, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:  # type: ignore[no-untyped-def]
    model, _, build, _ = flashed
    code = main(["twin", str(build.root), "-T", "6", "--no-physics", "--json", "-q",
                 "--controller", str(traced_controller(model))])  # fmt: skip
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["states_equal"] and out["announcements_ok"]
