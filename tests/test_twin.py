"""The robot twin's scheduler, wiring, servo coupling and faults, on a tiny hand-written pair of
programs (independent of `bstool compile`): module 0.0 counts, module 0.1 copies what it hears.

Module 0.0 (master) each round: PULSOUT its servo, send its state on pin 1, wait up to 20 ms
for 0.1's echo on the same wire; then state = state + 1 mod 16, tn = tn + 1. Module 0.1 waits
for a byte on pin 0 (no timeout), takes it as its state, answers it, pulses its servo.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import CliRun, FakeModule, write_fake_build

from bstool.buildfile import Wire
from bstool.errors import InputError
from bstool.moduleid import ModuleId
from bstool.tokenizer import tokenize_source
from hil_mock.robot import LIMP_AFTER_S, RobotTwin, load_build

BAUD = 33268  # 4800 baud, open drain
MASTER = f"""' {{$STAMP BS2sx}}
' {{$PBASIC 2.5}}
state VAR Nib
tn    VAR Nib
echo  VAR Byte
state = 3
Main:
  PULSOUT 12, 1042 + (state * 111)
  SEROUT 1, {BAUD}, [state]
  SERIN 1, {BAUD}, 50, Late, [echo]
Late:
  PAUSE 20
  state = state + 1 // 16
  tn = tn + 1
  GOTO Main
"""
SLAVE = f"""' {{$STAMP BS2sx}}
' {{$PBASIC 2.5}}
state VAR Nib
tn    VAR Nib
got   VAR Byte
state = 9
PULSOUT 12, 1042 + (state * 111)
Main:
  SERIN 0, {BAUD}, [got]
  state = got
  tn = tn + 1
  SEROUT 0, {BAUD}, [got]
  PULSOUT 12, 1042 + (state * 111)
  GOTO Main
"""


def make_build(tmp_path: Path) -> Path:
    fakes = []
    for j, src in enumerate((MASTER, SLAVE)):
        image = tokenize_source(src, f"m{j}.bsx").slots[0]
        variables = image.variables
        fakes.append(
            FakeModule(
                ModuleId(0, j),
                {0: image.eeprom},
                initial_state=3 if j == 0 else 9,
                ram_map={"state": variables["STATE"], "tn": variables["TN"]},
            )
        )
    wire = Wire(ModuleId(0, 0), 1, ModuleId(0, 1), 0, colour=0, bypass=False)
    return write_fake_build(
        tmp_path / "build", fakes, legs=1, modules_per_leg=2, period=0.03, links=[wire]
    )


def test_bytes_reach_the_listening_neighbour(tmp_path: Path) -> None:
    twin = RobotTwin(load_build(make_build(tmp_path)), physics=False)
    result = twin.run(10)
    assert result.states[ModuleId(0, 0)] == [(3 + t) % 16 for t in range(11)]
    # The master's first byte (3) goes out while the slave is still in its first PULSOUT (a
    # longer pulse): no receive buffer, so it is lost and the master's SERIN times out. From
    # then on the slave copies the master's state of the same round.
    assert result.states[ModuleId(0, 1)] == [9] + [(4 + t) % 16 for t in range(10)]
    assert result.stalled == []
    # after that first round the rounds differ only by the pulse width, 111 units (88.8 us)
    # longer per state
    periods = result.periods[ModuleId(0, 0)][1:]
    steps = [b - a for a, b in itertools.pairwise(periods)]
    assert steps == pytest.approx([88.8e-6] * len(steps), abs=1e-9)
    assert 0.024 < periods[0] < 0.040


def test_a_cut_link_starves_the_listener(tmp_path: Path) -> None:
    twin = RobotTwin(
        load_build(make_build(tmp_path)), physics=False, cut=[(ModuleId(0, 0), ModuleId(0, 1))]
    )
    result = twin.run(5, timeout_s=0.5)
    assert result.states[ModuleId(0, 0)][:6] == [3, 4, 5, 6, 7, 8]  # times out, goes on
    assert result.states[ModuleId(0, 1)] == [9]  # never hears anything
    assert result.stalled == [ModuleId(0, 1)]


def test_a_failed_module_is_silent_and_holds_its_initial_state(tmp_path: Path) -> None:
    twin = RobotTwin(load_build(make_build(tmp_path)), physics=False, failed=["0.1"])
    result = twin.run(4)
    assert result.states[ModuleId(0, 1)] == [9] * 5
    assert result.states[ModuleId(0, 0)] == [3, 4, 5, 6, 7]
    assert twin.servos[ModuleId(0, 1)].pulses == 0


def test_servo_targets_follow_pulses_and_go_limp(tmp_path: Path) -> None:
    pytest.importorskip("mujoco")
    build = load_build(make_build(tmp_path))
    twin = RobotTwin(build, physics=True, cut=[(ModuleId(0, 0), ModuleId(0, 1))])
    twin.run(3, timeout_s=0.3)
    master, slave = twin.servos[ModuleId(0, 0)], twin.servos[ModuleId(0, 1)]
    assert master.pulses >= 3 and not master.limp
    # the last pulse was for the state it holds: 1042 + 111·s units maps back to θ(s)
    s = twin.stamps[ModuleId(0, 0)].memory.nib(build.module(ModuleId(0, 0)).ram_map["state"][1])
    assert master.target == pytest.approx(-math.pi / 3 + s * (2 * math.pi / 3) / 15)
    # the slave pulsed once at start and then waits forever: limp after the threshold
    assert slave.pulses == 1 and slave.limp
    assert twin.t_ns / 1e9 > LIMP_AFTER_S
    assert twin.sim is not None and twin.sim.model.actuator_gainprm[1, 0] == 0.0
    assert twin.sim.model.actuator_gainprm[0, 0] > 0.0


def test_build_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"no manifest\.json"):
        load_build(tmp_path)
    (tmp_path / "manifest.json").write_text("{bad")
    with pytest.raises(InputError, match="malformed JSON"):
        load_build(tmp_path)
    (tmp_path / "manifest.json").write_text('{"format": "other"}')
    with pytest.raises(InputError, match=r"bstool\.build/1"):
        load_build(tmp_path)


def test_twin_cli_video_and_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import subprocess
    import sys

    build = make_build(tmp_path)
    video = tmp_path / "twin.mp4"
    # a subprocess, so the headless GL backend is chosen before mujoco is imported
    proc = subprocess.run(
        [sys.executable, "-m", "bstool", "twin", str(build), "-T", "12", "--video", str(video),
         "-q", "--timeout", "1"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    import imageio.v3 as iio

    frames = iio.imread(video)
    assert frames.shape[0] >= 5 and frames.shape[3] == 3 and frames.std() > 1.0

    from bstool.cli import main

    assert main(["twin", str(build), "--video", str(video), "--no-physics"]) == 2
    assert main(["twin", str(tmp_path / "nope")]) == 2
    assert "no manifest.json" in capsys.readouterr().err
    assert main(["twin", str(build), "--cut", "0.1"]) == 2
    assert "bad --cut" in capsys.readouterr().err
    assert main(["twin", str(build), "--cut", "0.1-0.1", "--no-physics", "-T", "1"]) == 2
    assert "no wire joins" in capsys.readouterr().err
    assert main(["twin", str(build), "--cut", "0.0-0.1@soon", "--no-physics", "-T", "1"]) == 2
    assert "A-B@S" in capsys.readouterr().err
    assert main(["twin", str(build), "--cut", "0.1-0.1@2", "--no-physics", "-T", "1"]) == 2
    assert "no wire joins" in capsys.readouterr().err


def test_twin_refuses_a_build_changed_after_compile(
    tmp_path: Path, cli: Callable[..., CliRun]
) -> None:
    """Like `bstool flash`, the twin runs only images that match the manifest's sha256."""
    build = make_build(tmp_path)
    image = build / "modules" / "L0.M1" / "slot0.eeprom"
    image.write_bytes(b"\x01" + image.read_bytes()[1:])
    run = cli("twin", str(build), "-T", "1", "--no-physics", "-q")
    assert run.code != 0
    assert "differs from the manifest's sha256" in run.err and "bstool compile" in run.err
