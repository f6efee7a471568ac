"""`bstool evolve`'s settings (defaults in one place, library checks), its run folder (refusing
folders it did not make, --force, paths under a file), killed-write temporaries, units."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bstool import cpus
from bstool.cli import main
from bstool.errors import InputError
from bstool.evolve import driver, fitness
from bstool.evolve import options as opt
from bstool.evolve.checkpoint import is_run, load_checkpoint
from bstool.evolve.engine import GAParams, default_gens, default_pm

TOY = ["--fitness", "toy", "--quiet", "--transitions", "6", "--pop", "4", "--seed", "5"]
ROOT = Path(__file__).resolve().parents[1]


def evolve(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(["evolve", *args])
    out = capsys.readouterr()
    return code, out.out, out.err


def files(d: Path) -> tuple[str, str]:
    return (d / "best.json").read_text(), (d / "history.csv").read_text()


# -- A: defaults and checks in one place --------------------------------------------------------
def test_help_shows_the_defaults_of_gaparams(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["evolve", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for name, value in [(f.name, f.default) for f in dataclasses.fields(GAParams)]:
        if name in ("pop", "pc", "transitions", "coevol_gens"):
            assert f"[default: {value};" in text, name
    assert f"{default_gens('ca1d')}; ca2ddiff: {default_gens('ca2ddiff')}" in text
    assert f"{default_pm('ca1d')} CA, {default_pm('nnsin')} NN" in text
    assert f"[default: {opt.DEFAULT_PARASITES};" in text and "[default: 1..2]" in text


def test_ga_params_defaults_are_gaparams() -> None:
    p = opt.ga_params("ca1d", seed=3)
    assert p == GAParams(seed=3, gens=default_gens("ca1d"), pm=default_pm("ca1d"))
    assert opt.ga_params("nnsin", seed=3).pm == default_pm("nnsin")
    assert opt.ga_params("ca2ddiff", seed=3).gens == default_gens("ca2ddiff")
    faults = opt.ga_params("ca1d", seed=3, coevolve_faults=True, parasite_k="2")
    assert faults.parasites == opt.DEFAULT_PARASITES and faults.parasite_k == (2, 2)
    assert 0 <= opt.ga_params("ca1d").seed < 2**32


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"pop": 1}, "--pop must be an integer of at least 2"),
        ({"pc": 1.5}, "--pc must be a probability"),
        ({"gens": 0}, "--gens must be"),
        ({"robust": "median"}, "unknown --robust mode"),
        ({"parasites": 3}, "--parasites only applies with --coevolve-faults"),
        ({"coevolve_faults": True, "robust": "mean"}, "do not combine"),
        ({"coevolve_faults": True, "parasite_k": "0..40"}, "must lie within 1..30"),
    ],
)
def test_ga_params_raise_input_errors(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(InputError, match=message):
        opt.ga_params("ca1d", **kwargs)
    with pytest.raises(InputError, match="unknown MODEL"):
        opt.ga_params("ca3d")


def test_resume_checks_are_library_functions(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    assert evolve(["ca1d", "--gens", "2", "--out", str(run), *TOY], capsys)[0] == 0
    state, extra = load_checkpoint(run)
    with pytest.raises(InputError, match=r"--pc is 0\.5 but the run"):
        opt.check_resume(state, extra, run, {"pc": 0.5})
    with pytest.raises(InputError, match="started without --coevolve-faults"):
        opt.check_resume(state, extra, run, {"coevolve_faults": True})
    opt.check_resume(state, extra, run, {"gens": 4, "pop": 4, "fitness": "toy"})
    assert state.params.gens == 4


def test_one_cpu_count_helper(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setattr(os, "sched_getaffinity", lambda _pid: {0, 3, 5}, raising=False)
    assert cpus.usable_cpus() == 3
    seen: list[int] = []
    real = driver.factory_for

    def spy(kind: str, problem: Any, workers: int, *more: Any) -> Any:
        seen.append(workers)
        return real(kind, problem, workers, *more)

    monkeypatch.setattr(driver, "factory_for", spy)
    plan = driver.plan_new("ca1d", opt.ga_params("ca1d", pop=4, gens=1, transitions=4),
                           fitness="toy")  # fmt: skip
    driver.execute(plan)
    assert seen == [3]


# -- B: the run folder --------------------------------------------------------------------------
def test_refuses_a_folder_it_did_not_make(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "best.json").write_text("my precious controller\n")
    code, _, err = evolve(["ca1d", "--gens", "1", "--out", str(mine), *TOY], capsys)
    assert code == 2 and "not empty and was not made by this command" in err
    assert "--force" in err and "Traceback" not in err
    assert (mine / "best.json").read_text() == "my precious controller\n"
    assert sorted(p.name for p in mine.iterdir()) == ["best.json"]
    # a stray checkpoint.npz of something else is no run either
    (mine / "checkpoint.npz").write_bytes(b"PK not ours")
    assert not is_run(mine)
    assert evolve(["ca1d", "--out", str(mine), *TOY], capsys)[0] == 2


def test_an_existing_run_hints_resume_and_force_replaces_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run, fresh = tmp_path / "run", tmp_path / "fresh"
    assert evolve(["nnsig", "--gens", "1", "--out", str(run), *TOY], capsys)[0] == 0
    assert is_run(run)
    code, _, err = evolve(["nnsig", "--gens", "2", "--out", str(run), *TOY], capsys)
    assert code == 2 and "already holds a run" in err
    assert f"--resume {run}" in err and "--force" in err
    (run / "notes.txt").write_text("old\n")
    args = ["nnsig", "--gens", "2", "--seed", "9", *TOY]
    assert evolve([*args, "--out", str(run), "--force"], capsys)[0] == 0
    assert evolve([*args, "--out", str(fresh)], capsys)[0] == 0
    assert files(run) == files(fresh) and not (run / "notes.txt").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_force_never_replaces_the_current_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "data.csv").write_text("1\n")
    monkeypatch.chdir(tmp_path)
    for out in (".", ".."):
        code, _, err = evolve(["ca1d", "--out", out, "--force", *TOY], capsys)
        assert code == 2 and "current folder" in err
    assert (tmp_path / "data.csv").exists()


def test_out_under_a_file_is_one_line_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "file").write_text("")

    def no_work(self: Any, seqs: Any) -> Any:
        raise AssertionError("evaluated before checking the output")

    monkeypatch.setattr(fitness.ToyEvaluator, "__call__", no_work)
    code, _, err = evolve(["ca1d", "--out", str(tmp_path / "file" / "run"), *TOY], capsys)
    assert code == 2 and "Traceback" not in err
    assert "is a file, not a folder" in err and len(err.strip().splitlines()) <= 2


_KILLER = """
import os, signal, sys
import numpy as np
from bstool.cli import main

real, calls = np.savez, [0]

def savez(fh, **arrays):
    calls[0] += 1
    if calls[0] == int(os.environ["KILL_AT"]):
        fh.write(b"half a checkpoint")
        fh.flush()
        os.kill(os.getpid(), signal.SIGKILL)
    return real(fh, **arrays)

np.savez = savez
sys.exit(main(["evolve", *sys.argv[1:]]))
"""


def test_resume_removes_a_killed_writers_temporaries(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    full, cut = tmp_path / "full", tmp_path / "cut"
    args = ["nnsin", "--gens", "4", *TOY]
    assert evolve([*args, "--out", str(full)], capsys)[0] == 0
    env = {**os.environ, "PYTHONPATH": str(ROOT), "KILL_AT": "3"}  # generation 2's checkpoint
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(_KILLER), *args, "--out",
                           str(cut)], env=env, capture_output=True, text=True)  # fmt: skip
    assert proc.returncode == -9, proc.stderr
    left = [p.name for p in cut.iterdir() if p.name.endswith(".tmp")]
    assert len(left) == 1 and left[0].startswith(".checkpoint.npz.")
    real = fitness.ToyEvaluator.__call__

    def checked(self: Any, seqs: Any) -> Any:
        assert not [p for p in cut.iterdir() if p.name.endswith(".tmp")], "not cleaned first"
        return real(self, seqs)

    monkeypatch.setattr(fitness.ToyEvaluator, "__call__", checked)
    code, _, err = evolve(["--resume", str(cut), "--quiet"], capsys)
    assert code == 0, err
    assert files(cut) == files(full)
    assert sorted(p.name for p in cut.iterdir()) == ["best.json", "checkpoint.npz", "history.csv"]


# -- B: the unit of the fitness -----------------------------------------------------------------
def test_summary_prints_the_unit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from bstool.commands.evolve import summary

    code, out, _ = evolve(["ca1d", "--gens", "1", "--out", str(tmp_path / "t"),
                           *[a for a in TOY if a != "--quiet"]], capsys)  # fmt: skip
    assert code == 0 and "(toy units) (not a distance)" in out
    plan = driver.plan_new("ca1d", opt.ga_params("ca1d", pop=2, gens=1, transitions=2))
    result = dataclasses.replace(driver.result_of(plan), fitness=0.246213)
    line = summary(result).splitlines()[0]
    assert line.startswith("best fitness 24.62 cm (eq. 6 distance after 2 transitions)")
    assert driver.fitness_text(float(np.float64(0.5)), "physics") == "50.00 cm"
