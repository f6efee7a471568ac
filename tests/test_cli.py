"""The command group itself: help, version, and errors without tracebacks."""

from __future__ import annotations

import json

import pytest

from bstool import __version__, fileio
from bstool.cli import main
from bstool.errors import InputError
from bstool.moduleid import ModuleId, all_modules, parse_module


def test_help_lists_commands(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--help"]) == 0
    assert "Usage: bstool" in capsys.readouterr().out


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--version"]) == 0
    assert __version__ in capsys.readouterr().out


def test_unknown_command_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["no-such-command"]) == 2
    assert "No such command" in capsys.readouterr().err


def test_parse_module() -> None:
    assert parse_module("2.3") == ModuleId(2, 3)
    assert parse_module("L4.M0") == ModuleId(4, 0)
    assert str(ModuleId(1, 5)) == "1.5" and ModuleId(1, 5).label == "L1.M5"
    for bad in ("2", "a.b", "1.2.3", ""):
        with pytest.raises(InputError, match="bad module address"):
            parse_module(bad)
    with pytest.raises(InputError, match="leg 5"):
        parse_module("5.0", legs=5, modules=6)
    with pytest.raises(InputError, match="module 6"):
        parse_module("0.6", legs=5, modules=6)
    assert len(all_modules(5, 6)) == 30 and all_modules(5, 6)[7] == ModuleId(1, 1)


def test_read_json_errors(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(InputError, match="not found"):
        fileio.read_json(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text('{"a": 1,\n "b": }')
    with pytest.raises(InputError, match=r"bad.json:2:7: malformed JSON"):
        fileio.read_json(bad)


def test_atomic_write_keeps_old_file_on_failure(tmp_path) -> None:  # type: ignore[no-untyped-def]
    target = tmp_path / "out.json"
    fileio.write_json(target, {"x": 1})
    with pytest.raises(RuntimeError), fileio.atomic_open(target) as fh:
        fh.write("partial")
        raise RuntimeError("killed")
    assert json.loads(target.read_text()) == {"x": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]


def test_atomic_write_uses_normal_permissions(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import os

    target = tmp_path / "out.txt"
    fileio.write_text(target, "x")
    mask = os.umask(0)
    os.umask(mask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~mask
