"""`bstool evolve --robust`: fitness over the n leg rotations, on a cheap toy fitness."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli

from bstool.controllers import load_controller
from bstool.evolve.checkpoint import load_checkpoint, save_outputs
from bstool.evolve.engine import GAParams, evolve_step, new_run, run
from bstool.evolve.fitness import ToyEvaluator, sequence_key
from bstool.evolve.problem import Problem
from bstool.evolve.scoring import combine, rotations
from bstool.experiments.rotation import rotate_controller, rotate_states

TOY = ["--fitness", "toy", "--quiet", "--transitions", "6"]


class Lopsided:
    """The toy fitness plus a bonus for leg 0's activity, so rotations differ (the plain toy
    fitness is rotation invariant). Records batch sizes."""

    def __init__(self) -> None:
        self.batches: list[int] = []

    def __call__(self, seqs: Sequence[np.ndarray]) -> list[float]:
        self.batches.append(len(seqs))
        base = ToyEvaluator()(seqs)
        leg0 = [float(np.abs(np.diff(np.asarray(s, float)[:, 0], axis=0)).sum()) for s in seqs]
        return [b + x / 1000 for b, x in zip(base, leg0, strict=True)]


def test_rotation_layout_and_combine() -> None:
    rng = np.random.default_rng(0)
    seqs = rng.integers(0, 16, (3, 4, 5, 6), dtype=np.uint8)
    rot = rotations(seqs, 5)
    assert rot.shape == (15, 4, 5, 6)
    for p in range(3):
        for r in range(5):
            np.testing.assert_array_equal(rot[p * 5 + r], rotate_states(seqs[p], r))
    d = np.array([[1.0, 2.0, 3.0], [np.nan, 4.0, 5.0], [-1.0, 2.0, 2.0]])
    np.testing.assert_allclose(combine(d, "mean"), [2.0, 3.0, 4 / 3])  # blow-ups count as 0
    np.testing.assert_allclose(combine(d, "worst"), [1.0, 0.0, 0.0])


@pytest.mark.parametrize("mode", ["mean", "worst"])
@pytest.mark.parametrize("model", ["nnsin", "ca1d", "ca2ddiff"])
def test_best_fitness_is_over_rotations(model: str, mode: str) -> None:
    params = GAParams(pop=6, gens=2, pm=0.01, transitions=6, coevol_gens=1, seed=3, robust=mode)
    ev = Lopsided()
    state = run(new_run(Problem(model, transitions=6), params), ev)
    assert all(b <= 6 * 5 for b in ev.batches) and len(ev.batches) == state.step  # one call a step
    best = state.best_controller()
    assert best is not None and best.ga is not None and best.ga["robust"] == mode
    per_rotation = Lopsided()([rotate_controller(best, r).states(6) for r in range(5)])
    expected = np.mean(per_rotation) if mode == "mean" else np.min(per_rotation)
    assert best.fitness == pytest.approx(expected, rel=1e-12)
    assert len(set(per_rotation)) > 1  # the test fitness does tell rotations apart


def test_cache_holds_raw_distances_per_rotation() -> None:
    """A candidate's rotation 0 is its plain sequence: the cache shares it with plain scoring,
    and the elite costs nothing in the next generation."""
    params = GAParams(pop=5, gens=2, pm=0.02, transitions=5, seed=1, robust="mean")
    problem = Problem("nnsig", transitions=5)
    state = new_run(problem, params)
    first = state.populations["main"].copy()
    evolve_step(state, Lopsided())
    assert state.history[0].evaluations == len(state.cache.table) <= 25
    plain = problem.sequences("main", first)
    assert all(sequence_key(s) in state.cache.table for s in plain)
    evolve_step(state, Lopsided())
    assert state.history[1].evaluations <= 4 * 5  # the elite's 5 rotations are cached
    _, known, paid = state.cache.evaluate(plain, Lopsided())
    assert paid == 0 and known.all()


def test_plain_run_unchanged_by_the_new_options() -> None:
    plain = GAParams(pop=5, gens=2, transitions=5, seed=2)
    assert "robust" not in plain.to_json() and "parasites" not in plain.to_json()
    a = run(new_run(Problem("ca1d", transitions=5), plain), ToyEvaluator())
    b = run(new_run(Problem("ca1d", transitions=5), GAParams(**plain.to_json())), ToyEvaluator())
    assert [vars(r) for r in a.history] == [vars(r) for r in b.history]


def test_checkpoint_resume_equals_uninterrupted(tmp_path: Path) -> None:
    params = GAParams(pop=5, gens=4, transitions=5, pm=0.02, seed=9, robust="worst")
    problem = Problem("nnsin", transitions=5)
    straight = run(new_run(problem, params), Lopsided())
    state = new_run(problem, params)
    for _ in range(2):
        evolve_step(state, Lopsided())
    save_outputs(state, tmp_path, {"fitness": "toy"})
    resumed, _ = load_checkpoint(tmp_path)
    assert resumed.params == params
    run(resumed, Lopsided())
    assert [vars(r) for r in resumed.history] == [vars(r) for r in straight.history]
    assert sorted(resumed.cache.table.items()) == sorted(straight.cache.table.items())
    best_a, best_b = resumed.best_controller(), straight.best_controller()
    assert best_a is not None and best_b is not None
    assert best_a.to_json() == best_b.to_json()


def evolve(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    run = run_cli(["evolve", *args], capsys)
    return run.code, run.err


def test_cli_records_mode_and_resumes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    full, part = tmp_path / "full", tmp_path / "part"
    common = ["--pop", "5", "--seed", "4", "--robust", "worst", *TOY]
    assert evolve(["nnsig", "--gens", "3", "--out", str(full), *common], capsys)[0] == 0
    assert evolve(["nnsig", "--gens", "1", "--out", str(part), *common], capsys)[0] == 0
    code, err = evolve(["--resume", str(part), "--gens", "3", "-q"], capsys)
    assert code == 0, err
    for name in ("best.json", "history.csv"):
        assert (part / name).read_text() == (full / name).read_text()
    best = load_controller(full / "best.json")
    assert best.ga is not None and best.ga["robust"] == "worst"
    # a bare --robust means "mean"
    assert evolve(["ca1d", "--gens", "1", "--out", str(tmp_path / "m"), "--pop", "4",
                   "--robust", *TOY], capsys)[0] == 0  # fmt: skip
    assert load_controller(tmp_path / "m" / "best.json").ga["robust"] == "mean"  # type: ignore[index]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["nnsin", "--out", "x", "--robust", "best"], "Invalid value for '--robust'"),
        (["nnsin", "--out", "x", "--robust", "--coevolve-faults"], "do not combine"),
        (["--resume", "plain", "--robust"], "was started without --robust"),
        (["--resume", "rob", "--robust", "worst"], "--robust is 'worst' but the run"),
    ],
)
def test_cli_errors(
    args: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    monkeypatch.chdir(tmp_path)
    base = ["--pop", "4", "--gens", "1", "--seed", "1", *TOY]
    assert evolve(["ca1d", "--out", "plain", *base], capsys)[0] == 0
    assert evolve(["ca1d", "--out", "rob", "--robust", *base], capsys)[0] == 0
    code, err = evolve(args, capsys)
    assert code == 2 and message in err and "Traceback" not in err
