"""Evolution wired to the MuJoCo batch evaluator: fitness is the simulator's distance (eq. 6)."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("bstool.sim.batch")

from bstool.cli import main
from bstool.controllers import load_controller
from bstool.robot import RobotSpec
from bstool.sim import Simulator


def test_evolve_physics_best_replays(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    args = ["evolve", "nnsin", "--pop", "4", "--gens", "2", "--transitions", "2", "--seed", "1"]
    assert main([*args, "--workers", "2", "--out", str(out), "-q"]) == 0
    best = load_controller(out / "best.json")
    assert best.fitness is not None and best.fitness > 0
    replay = Simulator(RobotSpec()).run(best.states(2))
    assert replay.distance == best.fitness  # bit-identical, threads or not
    again = tmp_path / "again"
    assert main([*args, "--workers", "1", "--out", str(again), "-q"]) == 0
    assert (again / "best.json").read_text() == (out / "best.json").read_text()
