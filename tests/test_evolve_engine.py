"""The evolution loop: fitness cache, skipped CA offspring, co-evolution, checkpoints."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bstool.controllers import chromosome as ch
from bstool.controllers.sequences import ca_sequences
from bstool.evolve.checkpoint import load_checkpoint, save_outputs
from bstool.evolve.engine import GAParams, RunState, evolve_step, new_run, run
from bstool.evolve.fitness import FitnessCache, ToyEvaluator, sequence_key
from bstool.evolve.problem import Problem


class Counting:
    """The toy evaluator, recording every batch it is asked for."""

    def __init__(self) -> None:
        self.batches: list[int] = []
        self.seen: list[bytes] = []

    def __call__(self, seqs: Sequence[np.ndarray]) -> list[float]:
        self.batches.append(len(seqs))
        self.seen += [sequence_key(s) for s in seqs]
        return ToyEvaluator()(seqs)


def test_cache_never_pays_twice() -> None:
    rng = np.random.default_rng(0)
    seqs = rng.integers(0, 16, (5, 4, 2, 3), dtype=np.uint8)
    batch = np.concatenate([seqs, seqs[[0, 2]], seqs[[0]]])
    cache, ev = FitnessCache(), Counting()
    fit, known, paid = cache.evaluate(batch, ev)
    assert paid == 5 and ev.batches == [5]
    assert known.tolist() == [False] * 5 + [True] * 3  # repeats inside one batch are free
    np.testing.assert_array_equal(fit[5:], fit[[0, 2, 0]])
    fit2, known2, paid2 = cache.evaluate(seqs, ev)
    assert paid2 == 0 and known2.all() and ev.batches == [5]
    np.testing.assert_array_equal(fit2, fit[:5])
    assert cache.evaluations == 5 and cache.hits == 8


def test_unvisited_rule_mutation_is_skipped() -> None:
    rng = np.random.default_rng(1)
    bits = rng.integers(0, 2, (1, ch.ca_length(5, 6)), dtype=np.uint8)
    init, rule = ch.decode_ca(bits, 5, 6)
    seq = ca_sequences("ca1d", init, rule, 30)[0].astype(int)
    visited = set()
    for t in range(30):
        s = seq[t]
        visited |= set((256 * np.roll(s, 1, 1) + 16 * s + np.roll(s, -1, 1)).ravel().tolist())
    assert len(visited) <= 900
    unvisited = next(i for i in range(4096) if i not in visited)
    child = bits.copy()
    child[0, 120 + 4 * unvisited + 2] ^= 1  # a rule entry the run never reads
    problem = Problem("ca1d")
    cache, ev = FitnessCache(), Counting()
    cache.evaluate(problem.sequences("main", bits), ev)
    _, known, paid = cache.evaluate(problem.sequences("main", child), ev)
    assert known.all() and paid == 0


@pytest.mark.parametrize("model", ["ca1d", "ca2dsing", "ca2ddiff", "nnsig", "nnsin"])
def test_best_controller_reproduces_its_fitness(model: str) -> None:
    params = GAParams(pop=6, gens=3, pm=0.01, transitions=8, coevol_gens=2, seed=4)
    state = run(new_run(Problem(model, transitions=8), params), ToyEvaluator())
    best = state.best_controller()
    assert best is not None and best.model == model
    assert best.fitness == state.best_fitness == max(r.best for r in state.history)
    assert ToyEvaluator()([best.states(8)])[0] == state.best_fitness
    assert best.ga == params.to_json() and best.seed == 4 and best.max_trans == 8


def test_coevolution_schedule() -> None:
    params = GAParams(pop=4, gens=2, transitions=5, coevol_gens=2, seed=2)
    state = new_run(Problem("ca2ddiff", transitions=5), params)
    assert state.total_steps == 8
    first_control = state.best_of["control"].copy()
    assert any((first_control == row).all() for row in state.populations["control"])
    order = []
    while not state.done:
        name = state.schedule(state.step)
        if name == "control" and state.step % 4 == 2:
            leg_best = state.best_of["leg"].copy()  # the best leg rule of the last leg step
        row = evolve_step(state, ToyEvaluator())
        order.append((row.population, row.generation))
        if name == "control":
            assert (state.best_of["leg"] == leg_best).all()  # fixed through the control phase
    assert order == [
        ("leg", 0), ("leg", 1), ("control", 0), ("control", 1),
        ("leg", 2), ("leg", 3), ("control", 2), ("control", 3),
    ]  # fmt: skip


def test_same_seed_same_run_and_elite_is_free() -> None:
    params = GAParams(pop=8, gens=4, transitions=6, pm=0.002, seed=11)
    a = run(new_run(Problem("nnsin", transitions=6), params), Counting())
    b = run(new_run(Problem("nnsin", transitions=6), params), Counting())
    assert [vars(r) for r in a.history] == [vars(r) for r in b.history]
    assert all(r.evaluations <= 7 for r in a.history[1:])  # the elite is never re-simulated
    assert a.stats()["offspring"] == 3 * 7
    c = run(new_run(Problem("nnsin", transitions=6), GAParams(**{**params.to_json(), "seed": 12})),
            ToyEvaluator())  # fmt: skip
    assert [r.mean for r in c.history] != [r.mean for r in a.history]


def snapshot(state: RunState) -> tuple:
    return (
        state.step,
        {k: v.tobytes() for k, v in state.populations.items()},
        {k: v.tobytes() for k, v in state.best_of.items()},
        [vars(r) for r in state.history],
        state.rng.bit_generator.state,
        state.best_fitness,
        state.stats(),
        sorted(state.cache.table.items()),
    )


@pytest.mark.parametrize(("model", "gens"), [("ca2ddiff", 2), ("nnsig", 6), ("ca1d", 5)])
def test_checkpoint_resume_equals_uninterrupted(model: str, gens: int, tmp_path: Path) -> None:
    params = GAParams(pop=5, gens=gens, transitions=6, coevol_gens=2, seed=3)
    problem = Problem(model, transitions=6)
    straight = run(new_run(problem, params), ToyEvaluator())
    state = new_run(problem, params)
    for _ in range(3):
        evolve_step(state, ToyEvaluator())
    save_outputs(state, tmp_path, {"fitness": "toy"})
    resumed, extra = load_checkpoint(tmp_path)
    assert extra == {"fitness": "toy"}
    assert snapshot(resumed) == snapshot(state)
    run(resumed, ToyEvaluator())
    assert snapshot(resumed) == snapshot(straight)
    best_a, best_b = resumed.best_controller(), straight.best_controller()
    assert best_a is not None and best_b is not None
    assert best_a.to_json() == best_b.to_json()


def test_physics_evaluator_stops_worker_threads_on_ctrl_c() -> None:
    from bstool.evolve.fitness import PhysicsEvaluator, _Stop

    class Runner:
        progress: Any = None

        def evaluate(self, seqs: list[np.ndarray], progress: Any) -> list[Any]:
            Runner.progress = progress
            progress(1)  # a worker finished one run: carries on
            raise KeyboardInterrupt  # Ctrl-C arrives while the main thread waits

    ev = PhysicsEvaluator(Runner())
    with pytest.raises(KeyboardInterrupt):
        ev([np.zeros((2, 5, 6), dtype=np.uint8)])
    with pytest.raises(_Stop):  # the next worker callback ends that worker thread
        Runner.progress(1)
