"""Bad input files: absurd nesting, huge integers, special files, oversized files — each one
clear line (exit 2, InputError), never a traceback or a hang (issue 16, item 6)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from conftest import traced_controller

from bstool import fileio
from bstool.cli import main
from bstool.controllers.controller import _kind
from bstool.errors import InputError

COMMANDS = ["states", "simulate", "compile"]


def _controller() -> dict[str, object]:
    return json.loads(Path(traced_controller("nnsin")).read_text())


def _args(cmd: str, path: Path, tmp_path: Path) -> list[str]:
    return [cmd, str(path), "-o", str(tmp_path / "build")] if cmd == "compile" else [cmd, str(path)]


def _bad_files(tmp_path: Path) -> dict[str, Path]:
    text = json.dumps(_controller())
    files = {
        "nested_file": "[" * 100_000 + "]" * 100_000,
        "nested_field": text[:-1] + ', "seed": ' + "[" * 100_000 + "]" * 100_000 + "}",
        "nested_few_hundred": text[:-1] + ', "seed": ' + "[" * 400 + "]" * 400 + "}",
        "huge_int": text[:-1] + ', "seed": ' + "7" * 5000 + "}",
    }
    out = {}
    for name, body in files.items():
        out[name] = tmp_path / f"{name}.json"
        out[name].write_text(body)
    return out


@pytest.mark.parametrize("cmd", COMMANDS)
@pytest.mark.parametrize("case", ["nested_file", "nested_field", "nested_few_hundred", "huge_int"])
def test_bad_json_is_one_clear_line(
    cmd: str, case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _bad_files(tmp_path)[case]
    assert main(_args(cmd, path, tmp_path)) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and str(path) in err
    assert not (tmp_path / "build").exists()


@pytest.mark.parametrize("cmd", COMMANDS)
def test_special_files_are_refused_without_reading(
    cmd: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)  # opening it for reading would block forever
    for path in (fifo, Path("/dev/zero")):
        assert main(_args(cmd, path, tmp_path)) == 2
        err = capsys.readouterr().err
        assert "not a regular file" in err and "Traceback" not in err


@pytest.mark.parametrize("cmd", COMMANDS)
def test_a_folder_is_refused(cmd: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "dir.json"
    folder.mkdir()
    assert main(_args(cmd, folder, tmp_path)) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_read_json_caps_the_size(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    big = tmp_path / "big.json"
    big.write_text("[" + "0," * 600 + "0]")
    monkeypatch.setattr(fileio, "MAX_JSON_BYTES", 1000)
    with pytest.raises(InputError, match="larger than"):
        fileio.read_limited(big, "states file", limit=1000)
    assert len(fileio.read_json(tmp_path.joinpath("big.json"))) == 601  # default cap: 64 MiB


def test_read_json_messages_name_the_file(tmp_path: Path) -> None:
    p = tmp_path / "x.json"
    p.write_text("[" * 100_000)
    with pytest.raises(InputError, match=r"x\.json: .*nested too deeply"):
        fileio.read_json(p, "controller file")
    p.write_text("1" * 5000)
    with pytest.raises(InputError, match=r"x\.json: cannot read controller file: Exceeds"):
        fileio.read_json(p, "controller file")


def test_huge_integer_field_is_described_not_printed() -> None:
    assert _kind(10**5000) == "an integer of about 5001 digits"
    assert _kind(12) == "the number 12"


def test_states_on_stdin_nested_too_deeply(capsys: pytest.CaptureFixture[str]) -> None:
    from click.testing import CliRunner

    from bstool.cli import cli

    result = CliRunner().invoke(cli, ["simulate", "--states", "-"], input="[" * 100_000)
    assert result.exit_code != 0 and isinstance(result.exception, InputError)
    assert "nested too deeply" in str(result.exception)
