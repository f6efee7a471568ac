"""Evolution wired to the MuJoCo batch evaluator: fitness is the simulator's distance (eq. 6)."""

from __future__ import annotations

from pathlib import Path

import pytest

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


def test_robust_physics_smoke(tmp_path: Path) -> None:
    """--robust on physics: best.json's fitness is the mean distance over its 5 rotations."""
    from bstool.experiments.rotation import rotate_controller

    out = tmp_path / "rob"
    args = ["evolve", "nnsin", "--pop", "4", "--gens", "1", "--transitions", "2", "--seed", "2"]
    assert main([*args, "--robust", "--workers", "2", "--out", str(out), "-q"]) == 0
    best = load_controller(out / "best.json")
    assert best.ga is not None and best.ga["robust"] == "mean"
    sim = Simulator(RobotSpec())
    distances = [sim.run(rotate_controller(best, r).states(2)).distance for r in range(5)]
    assert best.fitness == pytest.approx(sum(distances) / 5, rel=1e-12)


def test_coevolve_faults_physics_smoke(tmp_path: Path) -> None:
    """--coevolve-faults on physics: hosts and parasites alternate in history.csv."""
    out = tmp_path / "cf"
    args = ["evolve", "ca1d", "--pop", "4", "--gens", "2", "--transitions", "2", "--seed", "2"]
    assert main([*args, "--coevolve-faults", "--parasites", "2", "--out", str(out), "-q"]) == 0
    rows = (out / "history.csv").read_text().splitlines()[1:]
    assert [r.split(",")[3] for r in rows] == ["host", "parasite", "host", "parasite"]
    best = load_controller(out / "best.json")
    assert best.fitness is not None and best.fitness > 0
    assert best.ga is not None and best.ga["parasites"] == 2
