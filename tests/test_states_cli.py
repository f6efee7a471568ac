"""`bstool states`: the printed JSON sequence and its errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli

from bstool.controllers import make_controller, save_controller


@pytest.fixture
def nn_file(tmp_path: Path) -> Path:
    w = np.zeros((5, 6, 6), dtype=int)
    w[:, 0, 1] = 1
    ctrl = make_controller("nnsin", [0, 3, 6, 9, 15], weights=w, max_trans=5)
    path = tmp_path / "best.json"
    save_controller(ctrl, path)
    return path


def test_prints_frames(nn_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli(["states", str(nn_file)], capsys)
    assert code == 0
    frames = json.loads(out)
    assert len(frames) == 6  # max_trans = 5 from the file
    assert frames[0][0] == [0, 1, 8, 8, 8, 8]
    assert [f[4][0] for f in frames] == [15, 0, 1, 2, 3, 4]
    assert out.splitlines()[1].startswith("[[0,1,8,8,8,8],")  # one frame per line


def test_transitions_and_failures(nn_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli(
        ["states", str(nn_file), "-T", "3", "--fail", "1.0", "--fail", "L2.M1"], capsys
    )
    assert code == 0
    frames = np.array(json.loads(out))
    assert frames.shape == (4, 5, 6)
    assert (frames[:, 1, 0] == 3).all() and (frames[:, 2, 1] == frames[0, 2, 1]).all()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--fail", "7.0"], "leg 7 is not in 0..4"),
        (["--fail", "x"], "bad module address 'x'"),
        (["-T", "-2"], "Invalid value for '-T'"),
    ],
)
def test_bad_arguments(
    nn_file: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    code, _, err = run_cli(["states", str(nn_file), *args], capsys)
    assert code == 2 and message in err and "Traceback" not in err


def test_bad_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "bstool.controller/1", "model": "nnsin"}))
    code, _, err = run_cli(["states", str(bad)], capsys)
    assert code == 2 and "field 'legs': missing" in err and "Hint:" in err
    code, _, err = run_cli(["states", str(tmp_path / "none.json")], capsys)
    assert code == 2 and "controller file not found" in err
