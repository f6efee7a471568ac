"""Fitness evaluation: the evaluator protocol, the state-sequence cache, and the evaluators.

An *evaluator* is any callable taking a list of state sequences ((T+1, n, m) arrays) and
returning one fitness per sequence, in order; ``robot=`` (a :class:`~bstool.robot.RobotSpec`)
runs them on another robot's physics (``--randomize``). Physics is the whole cost, and the
controllers are open loop, so fitness is a function of the state sequence and the robot alone:
:class:`FitnessCache` keys it by a hash of both and never pays twice for the same one (elites,
clones, and CA offspring whose mutations only touched rule entries their run never reads).

Evaluators are built from small frozen *factories* (picklable, hashable), so a cluster worker
can build each one once and reuse it.
"""

from __future__ import annotations

import hashlib
import json
import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

Sequences = npt.NDArray[np.uint8]
#: ``evaluator(sequences, robot=None)``: one fitness per sequence (``robot``: a RobotSpec)
Evaluator = Callable[..., Sequence[float]]


class EvaluatorFactory(Protocol):
    def build(self) -> Evaluator: ...


def sequence_key(seq: np.ndarray, robot: bytes = b"") -> bytes:
    """128-bit digest of a state sequence (shape and values), and of the robot it runs on
    (``robot_key``; empty for the run's nominal robot, so a plain run's keys never change)."""
    arr = np.ascontiguousarray(seq, dtype=np.uint8)
    h = hashlib.blake2b(digest_size=16)
    h.update(repr(arr.shape).encode())
    h.update(arr.tobytes())
    if robot:
        h.update(b"robot:" + robot)
    return h.digest()


def _per_row(robot: Any, count: int) -> list[Any]:
    if robot is None or not isinstance(robot, list | tuple):
        return [robot] * count
    if len(robot) != count:
        raise ValueError(f"{len(robot)} robots for {count} sequences")
    return list(robot)


def robot_key(robot: Any) -> bytes:
    """A digest of a robot's values (a RobotSpec); empty for None (the nominal robot)."""
    if robot is None:
        return b""
    text = json.dumps(robot.to_dict(), sort_keys=True)
    return hashlib.blake2b(text.encode(), digest_size=16).digest()


class FitnessCache:
    """Fitness by state-sequence hash; counts the evaluations it actually paid for."""

    def __init__(self) -> None:
        self.table: dict[bytes, float] = {}
        self.evaluations = 0
        self.hits = 0

    def evaluate(
        self, sequences: Sequences, evaluator: Evaluator, robot: Any = None
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_], int]:
        """Fitness of every row on ``robot`` (None: the nominal one; a sequence: one robot per
        row); (fitness, row was already known, evaluations paid)."""
        robots = _per_row(robot, len(sequences))
        keys = [sequence_key(s, robot_key(r)) for s, r in zip(sequences, robots, strict=True)]
        known = np.array([k in self.table for k in keys], dtype=bool)
        todo: dict[bytes, int] = {}
        for row, key in enumerate(keys):
            if key not in self.table and key not in todo:
                todo[key] = row
        if todo:
            rows = [sequences[row] for row in todo.values()]
            on = [robots[row] for row in todo.values()]
            if all(r is None for r in on):
                values = list(evaluator(rows))
            elif all(r is on[0] for r in on):
                values = list(evaluator(rows, robot=on[0]))
            else:
                values = list(evaluator(rows, robot=on))
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
    On another ``robot`` it is scaled by (friction / 0.4)^½ · (0.09 / module_mass) ·
    (servo_torque / 0.4), so randomized runs can be tested cheaply.
    """

    def __call__(self, sequences: Sequence[np.ndarray], robot: Any = None) -> list[float]:
        out = []
        for seq, on in zip(sequences, _per_row(robot, len(sequences)), strict=True):
            scale = 1.0
            if on is not None:
                scale = (
                    math.sqrt(on.friction / 0.4) * (0.09 / on.module_mass) * (on.servo_torque / 0.4)
                )
            s = np.asarray(seq, dtype=np.float64)
            n, m = s.shape[1], s.shape[2]
            sign = np.where(np.arange(m) % 2 == 0, 1.0, -1.0)
            push = (np.diff(s, axis=0) * sign).sum(axis=(0, 2))  # per leg
            ang = 2 * math.pi * np.arange(n) / n
            out.append(float(math.hypot(push @ np.cos(ang), push @ np.sin(ang)) / 100) * scale)
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
    spec: Any = None  # the nominal RobotSpec (None: the default robot of legs × modules)

    def build(self) -> Evaluator:
        from bstool.sim import batch  # mujoco: imported only when physics is used

        return PhysicsEvaluator(batch.BatchEvaluator(_spec(self), workers=self.workers))


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
    spec: Any = None  # the nominal RobotSpec (None: the default robot of legs × modules)

    def build(self) -> Evaluator:
        from bstool.sim import batch

        return StampTimedEvaluator(batch.BatchEvaluator(_spec(self), workers=self.workers),
                                   self.schedule_model)  # fmt: skip


def _spec(factory: Any) -> Any:
    from bstool.robot import RobotSpec

    if factory.spec is not None:
        return factory.spec
    return RobotSpec(legs=factory.legs, modules=factory.modules)


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

    def __call__(self, sequences: Sequence[np.ndarray], robot: Any = None) -> list[float]:
        self._stop.clear()
        try:
            more = {} if robot is None else {"robot": robot}
            results = self.runner.evaluate(list(sequences), progress=self._progress, **more)
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

    def __call__(self, sequences: Sequence[np.ndarray], robot: Any = None) -> list[float]:
        from bstool.robot import RobotSpec
        from bstool.sim.timed import mean_distance, schedules_of

        self._stop.clear()
        groups = [schedules_of(self.schedule_model, s) for s in sequences]
        flat = [s for group in groups for s in group]
        if robot is not None and not isinstance(robot, RobotSpec):
            robot = _per_schedule(list(robot), groups)
        try:
            more = {} if robot is None else {"robot": robot}
            results = self.runner.evaluate_schedules(flat, progress=self._progress, **more)
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


def _per_schedule(robots: list[Any], groups: list[list[Any]]) -> list[Any]:
    """One robot per sequence, repeated for each schedule (build) the sequence is played on."""
    from bstool.errors import InputError

    if len(robots) != len(groups):
        raise InputError(
            f"{len(robots)} robots given for {len(groups)} sequences: give one per sequence"
        )
    return [r for r, group in zip(robots, groups, strict=True) for _ in group]
