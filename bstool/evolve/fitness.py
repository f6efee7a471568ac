"""Fitness evaluation: the evaluator protocol, the state-sequence cache, and the evaluators.

An *evaluator* is any callable taking a list of state sequences ((T+1, n, m) arrays) and
returning one fitness per sequence, in order. Physics is the whole cost, and the controllers
are open loop, so fitness is a function of the state sequence alone: :class:`FitnessCache`
keys it by a hash of the sequence and never pays twice for the same one (elites, clones, and
CA offspring whose mutations only touched rule entries their run never reads).

Evaluators are built from small frozen *factories* (picklable, hashable), so a cluster worker
can build each one once and reuse it.
"""

from __future__ import annotations

import hashlib
import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

Sequences = npt.NDArray[np.uint8]
Evaluator = Callable[[Sequence[np.ndarray]], Sequence[float]]


class EvaluatorFactory(Protocol):
    def build(self) -> Evaluator: ...


def sequence_key(seq: np.ndarray) -> bytes:
    """128-bit digest of a state sequence (shape and values)."""
    arr = np.ascontiguousarray(seq, dtype=np.uint8)
    h = hashlib.blake2b(digest_size=16)
    h.update(repr(arr.shape).encode())
    h.update(arr.tobytes())
    return h.digest()


class FitnessCache:
    """Fitness by state-sequence hash; counts the evaluations it actually paid for."""

    def __init__(self) -> None:
        self.table: dict[bytes, float] = {}
        self.evaluations = 0
        self.hits = 0

    def evaluate(
        self, sequences: Sequences, evaluator: Evaluator
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_], int]:
        """Fitness of every row; (fitness, row was already known, evaluations paid)."""
        keys = [sequence_key(s) for s in sequences]
        known = np.array([k in self.table for k in keys], dtype=bool)
        todo: dict[bytes, int] = {}
        for row, key in enumerate(keys):
            if key not in self.table and key not in todo:
                todo[key] = row
        if todo:
            values = list(evaluator([sequences[row] for row in todo.values()]))
            if len(values) != len(todo):
                raise RuntimeError(f"evaluator returned {len(values)} values for {len(todo)}")
            for key, value in zip(todo, values, strict=True):
                self.table[key] = float(value)
        self.evaluations += len(todo)
        self.hits += len(keys) - len(todo)
        fitness = np.array([self.table[k] for k in keys], dtype=np.float64)
        repeated = ~known
        repeated[list(todo.values())] = False  # first occurrences were paid for
        return fitness, known | repeated, len(todo)

    def to_arrays(self) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.float64]]:
        keys = np.frombuffer(b"".join(self.table), dtype=np.uint8).reshape(-1, 16)
        return keys, np.array(list(self.table.values()), dtype=np.float64)

    @classmethod
    def from_arrays(cls, keys: np.ndarray, values: np.ndarray, evaluations: int, hits: int) -> Any:
        cache = cls()
        cache.table = {bytes(k): float(v) for k, v in zip(keys, values, strict=True)}
        cache.evaluations, cache.hits = evaluations, hits
        return cache


class ToyEvaluator:
    """A cheap deterministic stand-in for physics (tests, demos): not a robot.

    Each leg i pushes along its direction (cos 2πi/n, sin 2πi/n) by the alternating sum of its
    modules' state changes; fitness is the length of the summed push, in "state" units / 100.
    """

    def __call__(self, sequences: Sequence[np.ndarray]) -> list[float]:
        out = []
        for seq in sequences:
            s = np.asarray(seq, dtype=np.float64)
            n, m = s.shape[1], s.shape[2]
            sign = np.where(np.arange(m) % 2 == 0, 1.0, -1.0)
            push = (np.diff(s, axis=0) * sign).sum(axis=(0, 2))  # per leg
            ang = 2 * math.pi * np.arange(n) / n
            out.append(float(math.hypot(push @ np.cos(ang), push @ np.sin(ang)) / 100))
        return out


@dataclass(frozen=True)
class ToyFitness:
    """Factory of :class:`ToyEvaluator`."""

    def build(self) -> Evaluator:
        return ToyEvaluator()


@dataclass(frozen=True)
class PhysicsFitness:
    """Factory of the MuJoCo evaluator: fitness = distance of eq. 6 after the run.

    Built on ``bstool.sim.batch.BatchEvaluator`` (one model, one MjData per thread).
    """

    legs: int = 5
    modules: int = 6
    workers: int = 1

    def build(self) -> Evaluator:
        from bstool.robot import RobotSpec
        from bstool.sim import batch  # mujoco: imported only when physics is used

        spec = RobotSpec(legs=self.legs, modules=self.modules)
        return PhysicsEvaluator(batch.BatchEvaluator(spec, workers=self.workers))


@dataclass(frozen=True, eq=False)
class StampTimedFitness:
    """Factory of the stamp-timed MuJoCo evaluator (``bstool evolve --stamp-timed``): each
    candidate's state sequence becomes the schedule a build of it would follow
    (``schedule_model``: a :class:`bstool.sim.timed.ScheduleModel`, or a
    :class:`~bstool.sim.timed.ScheduleEnsemble` of several builds' schedules), played with
    ``BatchEvaluator.evaluate_schedules``; fitness = distance of eq. 6 between the path's
    first and last samples (an ensemble: its mean over the builds)."""

    schedule_model: Any
    legs: int = 5
    modules: int = 6
    workers: int = 1

    def build(self) -> Evaluator:
        from bstool.robot import RobotSpec
        from bstool.sim import batch

        spec = RobotSpec(legs=self.legs, modules=self.modules)
        return StampTimedEvaluator(batch.BatchEvaluator(spec, workers=self.workers),
                                   self.schedule_model)  # fmt: skip


class _Stop(Exception):
    """Raised in a worker thread's progress callback to end its batch early."""


class PhysicsEvaluator:
    """Distances from a ``BatchEvaluator``; Ctrl-C stops the worker threads after their
    current run instead of letting them finish the whole batch."""

    def __init__(self, runner: Any) -> None:
        self.runner = runner
        self._stop = threading.Event()

    def _progress(self, _count: int) -> None:
        if self._stop.is_set():
            raise _Stop

    def __call__(self, sequences: Sequence[np.ndarray]) -> list[float]:
        self._stop.clear()
        try:
            results = self.runner.evaluate(list(sequences), progress=self._progress)
        except KeyboardInterrupt:
            self._stop.set()
            raise
        return [float(r.distance) for r in results]

    def close(self) -> None:
        self.runner.close()


class StampTimedEvaluator(PhysicsEvaluator):
    """Distances of the stamp-timed runs of the sequences (see :class:`StampTimedFitness`)."""

    def __init__(self, runner: Any, schedule_model: Any) -> None:
        super().__init__(runner)
        self.schedule_model = schedule_model

    def __call__(self, sequences: Sequence[np.ndarray]) -> list[float]:
        from bstool.sim.timed import mean_distance, schedules_of

        self._stop.clear()
        groups = [schedules_of(self.schedule_model, s) for s in sequences]
        flat = [s for group in groups for s in group]
        try:
            results = self.runner.evaluate_schedules(flat, progress=self._progress)
        except KeyboardInterrupt:
            self._stop.set()
            raise
        out, start = [], 0
        for group in groups:
            out.append(
                mean_distance([float(r.distance) for r in results[start : start + len(group)]])
            )
            start += len(group)
        return out
