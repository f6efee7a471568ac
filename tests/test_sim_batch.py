"""Batches: threads, rollout and sequential runs agree to the bit; evaluators are reusable."""

from __future__ import annotations

import numpy as np
import pytest

from bstool.errors import InputError
from bstool.robot import RobotSpec
from bstool.sim import BatchEvaluator, Simulator, evaluate_batch


def _population() -> list[np.ndarray]:
    rng = np.random.default_rng(11)
    return [rng.integers(0, 16, (t + 1, 5, 6)) for t in (2, 1, 2)]


def test_methods_are_bit_identical_to_sequential() -> None:
    pop = _population()
    sim = Simulator(transition_time=0.1, settle_time=0.1)
    expected = [sim.run(s).path for s in pop]
    for method in ("threads", "rollout", "sequential"):
        results = evaluate_batch(
            RobotSpec(), pop, workers=2, method=method, transition_time=0.1, settle_time=0.1
        )
        assert [r.path.tobytes() for r in results] == [p.tobytes() for p in expected], method


def test_evaluator_is_reusable() -> None:
    pop = _population()
    with BatchEvaluator(workers=2, transition_time=0.1, settle_time=0.1) as ev:
        first = ev.evaluate(pop)
        done: list[int] = []
        second = ev.evaluate(pop[::-1], progress=done.append)
        assert ev.evaluate([]) == []
    assert sum(done) == len(pop)
    assert [r.path.tobytes() for r in first] == [r.path.tobytes() for r in second[::-1]]


def test_bad_arguments() -> None:
    with pytest.raises(InputError, match="unknown batch method"):
        BatchEvaluator(method="processes")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="workers"):
        BatchEvaluator(workers=0)
    with (
        BatchEvaluator(workers=1) as ev,
        pytest.raises(InputError, match=r"states\[1\]: wrong robot shape"),
    ):
        ev.evaluate([np.zeros((2, 5, 6), int), np.zeros((2, 5, 5), int)])


def test_an_exception_in_progress_stops_every_worker() -> None:
    """evolve stops a batch on Ctrl-C by raising from the progress callback."""

    class Stop(Exception):
        pass

    calls: list[int] = []

    def progress(k: int) -> None:
        calls.append(k)
        raise Stop

    pop = [np.zeros((2, 5, 6), int)] * 6
    with BatchEvaluator(workers=2, transition_time=0.05, settle_time=0.05) as ev:
        with pytest.raises(Stop):
            ev.evaluate(pop, progress=progress)
        assert len(calls) <= 2  # each worker stopped after its first run
        assert len(ev.evaluate(pop[:2])) == 2  # and the evaluator still works
