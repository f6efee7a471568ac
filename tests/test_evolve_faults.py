"""`bstool evolve --coevolve-faults`: hosts against parasites (sets of failed modules), §6."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli

from bstool.controllers import load_controller
from bstool.errors import InputError
from bstool.evolve.checkpoint import load_checkpoint, save_outputs
from bstool.evolve.engine import GAParams, evolve_step, new_run, run
from bstool.evolve.fitness import ToyEvaluator
from bstool.evolve.problem import Problem
from bstool.evolve.scoring import (
    mutate_parasite,
    new_parasites,
    next_parasites,
    parasite_cells,
    parse_k,
)
from bstool.moduleid import ModuleId

TOY = ["--fitness", "toy", "--quiet", "--transitions", "6"]


def valid(row: np.ndarray, k: tuple[int, int], cells: int) -> bool:
    members = [int(c) for c in row if c >= 0]
    padded = all(c < 0 for c in row[len(members) :])
    return (
        padded
        and k[0] <= len(members) <= k[1]
        and members == sorted(set(members))
        and all(0 <= c < cells for c in members)
    )


def test_parse_k() -> None:
    assert parse_k("1", 30) == (1, 1)
    assert parse_k("1..3", 30) == (1, 3)
    for bad in ("0", "3..2", "31", "x", "1..", "1..y"):
        with pytest.raises(InputError):
            parse_k(bad, 30)


@pytest.mark.parametrize("k", [(1, 1), (2, 2), (1, 2), (1, 4), (29, 30)])
def test_parasites_stay_valid(k: tuple[int, int]) -> None:
    rng = np.random.default_rng(5)
    pop = new_parasites(6, k, 30, rng)
    assert pop.shape == (6, k[1]) and all(valid(r, k, 30) for r in pop)
    sizes = set()
    for _ in range(300):
        child = mutate_parasite(pop[0], k, 30, rng)
        assert valid(child, k, 30)
        assert not np.array_equal(child, pop[0])  # every child differs from its parent
        sizes.add(int((child >= 0).sum()))
        pop[0] = child
    assert sizes == set(range(k[0], k[1] + 1)) or k[1] - k[0] > 2


def test_next_parasites_keeps_the_most_harmful() -> None:
    rng = np.random.default_rng(1)
    pop = new_parasites(5, (1, 2), 30, rng)
    nxt = next_parasites(pop, [0.1, 0.5, 0.2, 0.0, 0.5], (1, 2), 30, rng)
    assert nxt.shape == pop.shape and np.array_equal(nxt[0], pop[1])
    assert parasite_cells(np.array([7, 12, -1]), 6) == [(1, 1), (2, 0)]


@pytest.mark.parametrize("model", ["ca1d", "ca2dsing", "nnsig", "nnsin", "ca2ddiff"])
def test_fitness_formulas(model: str) -> None:
    """Host = mean of healthy + one run per parasite, with failures applied exactly as the
    controllers apply them; parasite = mean fraction of healthy distance lost."""
    params = GAParams(pop=4, gens=1, transitions=6, coevol_gens=1, seed=2, parasites=3)
    state = new_run(Problem(model, transitions=6), params)
    assert state.parasites is not None
    parasites = state.parasites.copy()
    name = state.schedule(0)
    partner_name = state.problem.partner_of(name)
    partner = state.best_of[partner_name].copy() if partner_name else None
    bits = state.populations[name].copy()
    evolve_step(state, ToyEvaluator())
    host_row, parasite_row = state.history
    toy = ToyEvaluator()
    host, lost = [], np.zeros((3, 4))
    for h in range(4):
        c = state.problem.controller(name, bits[h], partner)
        healthy = toy([c.states(6)])[0]
        faulty = [
            toy([c.states(6, failed=[ModuleId(i, j) for i, j in parasite_cells(q, 6)])])[0]
            for q in parasites
        ]
        host.append(np.mean([healthy, *faulty]))
        lost[:, h] = [max(0.0, 1 - f / healthy) if healthy > 0 else 0.0 for f in faulty]
    assert host_row.population == ("host" if model != "ca2ddiff" else name)
    assert host_row.best == pytest.approx(max(host), rel=1e-12)
    assert host_row.mean == pytest.approx(np.mean(host), rel=1e-12)
    assert parasite_row.population == "parasite" and parasite_row.evaluations == 0
    assert parasite_row.best == pytest.approx(lost.mean(axis=1).max(), rel=1e-12)
    assert state.best_fitness == host_row.best
    best = state.best_controller()
    assert best is not None and best.ga is not None
    assert best.ga["parasites"] == 3 and best.ga["parasite_k"] == [1, 2]


def test_best_is_the_latest_generation_best_and_one_call_per_step() -> None:
    calls: list[int] = []

    def ev(seqs: Sequence[np.ndarray]) -> list[float]:
        calls.append(len(seqs))
        return ToyEvaluator()(seqs)

    params = GAParams(pop=5, gens=4, transitions=6, pm=0.02, seed=8, parasites=3)
    state = run(new_run(Problem("nnsin", transitions=6), params), ev)
    hosts = [r for r in state.history if r.population == "host"]
    parasites = [r for r in state.history if r.population == "parasite"]
    assert [r.generation for r in hosts] == [r.generation for r in parasites] == [0, 1, 2, 3]
    assert [r.population for r in state.history[:4]] == ["host", "parasite"] * 2
    assert len(calls) == 4 and all(c <= 5 * 4 for c in calls)
    assert state.best_fitness == hosts[-1].best


@pytest.mark.parametrize(("model", "gens"), [("nnsig", 5), ("ca2ddiff", 2)])
def test_checkpoint_resume_equals_uninterrupted(model: str, gens: int, tmp_path: Path) -> None:
    params = GAParams(pop=5, gens=gens, transitions=5, coevol_gens=2, seed=6, parasites=4,
                      parasite_k=(1, 3))  # fmt: skip
    problem = Problem(model, transitions=5)
    straight = run(new_run(problem, params), ToyEvaluator())
    state = new_run(problem, params)
    for _ in range(3):
        evolve_step(state, ToyEvaluator())
    save_outputs(state, tmp_path, {"fitness": "toy"})
    resumed, _ = load_checkpoint(tmp_path)
    assert resumed.params == params and resumed.parasites is not None
    assert state.parasites is not None and np.array_equal(resumed.parasites, state.parasites)
    run(resumed, ToyEvaluator())
    assert [vars(r) for r in resumed.history] == [vars(r) for r in straight.history]
    assert resumed.parasites is not None and straight.parasites is not None
    assert np.array_equal(resumed.parasites, straight.parasites)
    best_a, best_b = resumed.best_controller(), straight.best_controller()
    assert best_a is not None and best_b is not None
    assert best_a.to_json() == best_b.to_json()


def evolve(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    run = run_cli(["evolve", *args], capsys)
    return run.code, run.err


@pytest.mark.parametrize("model", ["ca2dsing", "ca2ddiff"])
def test_cli_run_and_resume(model: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    full, part = tmp_path / "full", tmp_path / "part"
    gens = ["1", "2"] if model == "ca2ddiff" else ["2", "4"]
    common = ["--pop", "4", "--seed", "3", "--coevolve-faults", "--parasites", "3",
              "--parasite-k", "2", "--coevol-gens", "2", *TOY]  # fmt: skip
    assert evolve([model, "--gens", gens[1], "--out", str(full), *common], capsys)[0] == 0
    assert evolve([model, "--gens", gens[0], "--out", str(part), *common], capsys)[0] == 0
    code, err = evolve(["--resume", str(part), "--gens", gens[1], "-q"], capsys)
    assert code == 0, err
    for name in ("best.json", "history.csv"):
        assert (part / name).read_text() == (full / name).read_text()
    rows = list(csv.DictReader((full / "history.csv").open()))
    pops = {r["population"] for r in rows}
    assert pops == ({"leg", "control", "parasite"} if model == "ca2ddiff" else {"host", "parasite"})
    best = load_controller(full / "best.json")
    assert best.ga is not None and best.ga["parasite_k"] == [2, 2] and best.ga["parasites"] == 3


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["nnsin", "--out", "x", "--parasites", "3"], "--parasites only applies with"),
        (["nnsin", "--out", "x", "--parasite-k", "2"], "--parasite-k only applies with"),
        (["nnsin", "--out", "x", "--coevolve-faults", "--parasites", "1"], "'--parasites'"),
        (["nnsin", "--out", "x", "--coevolve-faults", "--parasite-k", "0"], "within 1..30"),
        (["nnsin", "--out", "x", "--coevolve-faults", "--parasite-k", "a"], "not a number"),
        (["--resume", "plain", "--coevolve-faults"], "started without --coevolve-faults"),
        (["--resume", "cf", "--parasites", "5"], "--parasites is 5 but the run"),
        (["--resume", "cf", "--parasite-k", "1"], "--parasite-k is [1, 1] but the run"),
    ],
)
def test_cli_errors(
    args: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    monkeypatch.chdir(tmp_path)
    base = ["--pop", "4", "--gens", "1", "--seed", "1", *TOY]
    assert evolve(["nnsig", "--out", "plain", *base], capsys)[0] == 0
    assert evolve(["nnsig", "--out", "cf", "--coevolve-faults", *base], capsys)[0] == 0
    assert evolve(["--resume", "cf", "--coevolve-faults", "--parasites", "4"], capsys)[0] == 0
    code, err = evolve(args, capsys)
    assert code == 2 and message in err and "Traceback" not in err
