"""`bstool demo`, the README's main job: compile, flash 30 twins over the protocol, run, compare."""

from __future__ import annotations

from pathlib import Path

import pytest

from bstool.cli import main


def test_demo_runs_the_whole_chain(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "build"
    assert main(["demo", "--model", "ca1d", "-T", "4", "-q", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "30/30 twins programmed" in text
    assert "states, 4 transitions" in text and "equal" in text
    assert "all correct" in text
    assert (out / "manifest.json").is_file() and len(list(out.glob("modules/*"))) == 30


def test_demo_with_a_dead_module_matches_the_failed_reference(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["demo", "-T", "3", "-q", "--fail", "1.2"]) == 0
    assert "modules differ" not in capsys.readouterr().out


def test_demo_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--fail", "9.9", "-q"]) == 2
    assert "unknown module 9.9" in capsys.readouterr().err
    assert main(["demo", "--controller", str(tmp_path / "missing.json"), "-q"]) == 2


def test_demo_out_refuses_a_foreign_folder_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    assert main(["demo", "--model", "ca1d", "-T", "2", "--out", str(mine), "-q"]) == 2
    captured = capsys.readouterr()
    assert "--force" in captured.err and "controller" not in captured.out  # nothing ran
    assert (mine / "notes.txt").read_text() == "keep"
