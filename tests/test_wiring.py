"""WIRING.md is enough to build, calibrate and flash the robot: what it tells a person is true
for the model compiled, and the program, file and commands it gives work as written."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from bstool.cli import cli
from bstool.compile.calibration import parse_calibration
from bstool.flash.flasher import read_ports_file
from bstool.moduleid import parse_module
from bstool.tokenizer import tokenize_source

GOLDEN = Path(__file__).parent / "golden" / "compile"


def _wiring(model: str) -> str:
    return (GOLDEN / model / "WIRING.md").read_text(encoding="utf-8")


def _block(text: str, language: str) -> str:
    found = re.findall(rf"```{language}\n(.*?)```", text, flags=re.S)
    assert len(found) == 1, f"one {language} block expected"
    return found[0]


@pytest.mark.parametrize("model", ["ca1d", "nnsin"])
def test_the_calibration_program_tokenizes(model: str) -> None:
    project = tokenize_source(_block(_wiring(model), "pbasic"), "calibrate.bsx")
    assert project.slots[0].program_bytes > 0


@pytest.mark.parametrize("model", ["ca1d", "nnsin"])
def test_the_calibration_file_example_loads(model: str) -> None:
    import json

    data = json.loads(_block(_wiring(model), "json"))
    calib = parse_calibration(data, "servos.json", 5, 6)
    assert calib.servo(parse_module("0.0")).centre_us == 1530


def test_the_commands_it_gives_exist_with_those_options() -> None:
    text = _wiring("nnsin")
    commands = re.findall(r"^ {4}(bstool .+)$", text, flags=re.M)
    commands += re.findall(r"`(bstool (?:flash|compile) [^`]+)`", text)
    assert len(commands) >= 4
    for line in commands:
        argv = shlex.split(line)[1:]
        command = cli.get_command(None, argv[0])  # type: ignore[arg-type]
        assert command is not None, line
        ctx = command.make_context(argv[0], argv[1:], resilient_parsing=True)
        assert not ctx.args or all(not a.startswith("-") for a in ctx.args), line


def test_the_ports_file_example_is_the_format_flash_reads(tmp_path: Path) -> None:
    example = re.search(r'`(\{"L0\.M0":\s*"/dev/ttyUSB0", \.\.\.\})`', _wiring("nnsin"))
    assert example
    (tmp_path / "ports.json").write_text(example.group(1).replace(", ...", ""))
    assert read_ports_file(tmp_path / "ports.json") == {parse_module("0.0"): "/dev/ttyUSB0"}


def test_ring_wording_only_where_legs_are_rings() -> None:
    assert "the lead's P0 goes to the tip" in _wiring("ca1d")
    assert "the lead's P0 goes to the tip" in _wiring("ca2dsing")
    for nn in ("nnsin", "nnsig"):
        assert "(the leg is a ring)" not in _wiring(nn) and "goes to the tip" not in _wiring(nn)


@pytest.mark.parametrize("model", ["ca1d", "nnsin"])
def test_it_names_orientation_axes_power_and_pull_ups(model: str) -> None:
    text = _wiring(model)
    assert "anticlockwise" in text and "72°" in text
    assert "| M0 | vertical |" in text and "| M1 | horizontal |" in text
    assert "Common ground" in text and "One switch" in text
    assert "pull-up from the wire to the shared +5 V" in text
