"""`bstool evolve` and `bstool plot-history` end to end on the toy fitness (no physics)."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import run_cli

from bstool.cli import main
from bstool.controllers import load_controller
from bstool.evolve import fitness

TOY = ["--fitness", "toy", "--quiet", "--transitions", "8"]


def evolve(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    return run_cli(["evolve", *args], capsys)


def files(d: Path) -> tuple[str, str]:
    return (d / "best.json").read_text(), (d / "history.csv").read_text()


def test_run_directory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    code, _, err = evolve(
        ["ca2dsing", "--pop", "6", "--gens", "3", "--seed", "1", "--out", str(out), *TOY], capsys
    )
    assert code == 0, err
    best = load_controller(out / "best.json")
    assert best.model == "ca2dsing" and best.max_trans == 8 and best.seed == 1
    assert best.ga == {"pop": 6, "gens": 3, "pc": 0.8, "pm": 0.0002, "transitions": 8,
                       "coevol_gens": 20, "seed": 1}  # fmt: skip
    rows = list(csv.DictReader((out / "history.csv").open()))
    assert list(rows[0]) == ["generation", "best", "mean", "population", "evaluations"]
    assert [r["generation"] for r in rows] == ["0", "1", "2"]
    assert float(rows[-1]["best"]) == best.fitness
    assert (out / "checkpoint.npz").exists()
    assert main(["states", str(out / "best.json")]) == 0
    assert len(json.loads(capsys.readouterr().out)) == 9


def test_summary_and_default_seed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = evolve(["nnsin", "--pop", "4", "--gens", "2", "--out", str(tmp_path / "r"),
                           "--fitness", "toy", "--transitions", "4"], capsys)  # fmt: skip
    assert code == 0 and "best fitness" in out and "offspring skipped" in out
    assert isinstance(load_controller(tmp_path / "r" / "best.json").seed, int)


@pytest.mark.parametrize("model", ["ca1d", "ca2ddiff", "nnsig"])
def test_resume_reaches_the_same_result(
    model: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    common = ["--pop", "5", "--seed", "7", "--coevol-gens", "2", *TOY]
    full, part = tmp_path / "full", tmp_path / "part"
    gens = "2" if model == "ca2ddiff" else "4"
    assert evolve([model, "--gens", gens, "--out", str(full), *common], capsys)[0] == 0
    assert evolve([model, "--gens", "1", "--out", str(part), *common], capsys)[0] == 0
    assert files(part) != files(full)
    code, _, err = evolve(["--resume", str(part), "--gens", gens, "--quiet"], capsys)
    assert code == 0, err
    assert files(part) == files(full)


def test_ctrl_c_saves_and_resumes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    common = ["--pop", "6", "--gens", "5", "--seed", "3", *TOY]
    full, cut = tmp_path / "full", tmp_path / "cut"
    assert evolve(["nnsig", "--out", str(full), *common], capsys)[0] == 0
    real = fitness.ToyEvaluator.__call__
    calls = {"n": 0}

    def interrupted(self: Any, seqs: Any) -> Any:
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return real(self, seqs)

    monkeypatch.setattr(fitness.ToyEvaluator, "__call__", interrupted)
    code, _, err = evolve(["nnsig", "--out", str(cut), *common], capsys)
    assert code == 130
    assert "Interrupted after 2 of 5 generations" in err and f"--resume {cut}" in err
    assert "Traceback" not in err
    assert len((cut / "history.csv").read_text().splitlines()) == 3  # header + 2 generations
    assert load_controller(cut / "best.json").model == "nnsig"
    monkeypatch.setattr(fitness.ToyEvaluator, "__call__", real)
    assert evolve(["--resume", str(cut)], capsys)[0] == 0
    assert files(cut) == files(full)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--out", "x"], "missing MODEL"),
        (["nnsin"], "missing --out DIR"),
        (["nnsix", "--out", "x"], "Invalid value for 'MODEL'"),
        (["nnsin", "--out", "x", "--pc", "1.5"], "Invalid value for '--pc'"),
        (["nnsin", "--out", "x", "--pop", "1"], "Invalid value for '--pop'"),
        (["--resume", "nowhere"], "no checkpoint in nowhere"),
        (["nnsin", "--out", "afile"], "Directory 'afile' is a file"),
        (["nnsin", "--out", "x", "--resume", "y"], "give either --out DIR"),
    ],
)
def test_bad_arguments(
    args: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("")
    code, _, err = evolve(args, capsys)
    assert code == 2 and message in err and "Traceback" not in err


def test_resume_conflicts(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    assert (
        evolve(
            ["ca1d", "--pop", "4", "--gens", "2", "--seed", "1", "--out", str(run), *TOY], capsys
        )[0]
        == 0
    )
    code, _, err = evolve(["ca1d", "--out", str(run), *TOY], capsys)
    assert code == 2 and "already holds a run" in err and "--resume" in err
    code, _, err = evolve(["--resume", str(run), "--pop", "9"], capsys)
    assert code == 2 and "--pop is 9 but the run" in err
    code, _, err = evolve(["nnsin", "--resume", str(run)], capsys)
    assert code == 2 and "MODEL is 'nnsin'" in err
    code, _, err = evolve(["--resume", str(run), "--gens", "1"], capsys)
    assert code == 2 and "less than the 2 generations" in err
    (run / "checkpoint.npz").write_bytes(b"garbage")
    code, _, err = evolve(["--resume", str(run)], capsys)
    assert code == 2 and "cannot read checkpoint" in err


def test_plot_history(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    assert (
        evolve(
            ["nnsin", "--pop", "4", "--gens", "3", "--seed", "1", "--out", str(a), *TOY], capsys
        )[0]
        == 0
    )
    assert evolve(["ca2ddiff", "--pop", "4", "--gens", "1", "--coevol-gens", "2", "--seed", "1",
                   "--out", str(b), *TOY], capsys)[0] == 0  # fmt: skip
    png = tmp_path / "h.png"
    assert main(["plot-history", str(a), str(b), "-o", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["plot-history", str(a), "-o", str(tmp_path / "h.txt")]) == 2
    assert "name the output .png" in capsys.readouterr().err
    assert main(["plot-history", str(tmp_path), "-o", str(png)]) == 2
    assert "no history file" in capsys.readouterr().err
    (a / "history.csv").write_text("generation,best,mean,population,evaluations\n0,x,1,main,3\n")
    assert main(["plot-history", str(a), "-o", str(png)]) == 2
    assert "history.csv:2: malformed history row" in capsys.readouterr().err


def test_history_matches_state_sequences(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "r"
    assert (
        evolve(
            ["ca1d", "--pop", "4", "--gens", "2", "--seed", "5", "--out", str(run), *TOY], capsys
        )[0]
        == 0
    )
    best = load_controller(run / "best.json")
    assert fitness.ToyEvaluator()([np.asarray(best.states(8), dtype=np.uint8)])[0] == best.fitness
