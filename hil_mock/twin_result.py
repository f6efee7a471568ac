"""What the robot twin observed: per-module state records and the run's result."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np

from bstool.errors import InputError
from bstool.moduleid import ModuleId
from hil_mock.stamp import Stamp

NS = 1_000_000_000
OFF_STATE = -2  # a transition a reset module skipped while it was off (no state shown)


@dataclass
class ModuleRecord:
    """What one module did: its states and when it made its transitions. A transition is seen
    at the first servo pulse after the module's transition counter moved: the moment its servo
    gets the new target (every program pulses its servo at least every 25 ms)."""

    states: list[int] = field(default_factory=list)
    times_ns: list[int] = field(default_factory=list)
    last_tn: int | None = None
    rejoining: bool = False  # booted again (--reset): re-aligned at its next servo pulse
    rejoined: list[int] = field(default_factory=list)  # the transitions it rejoined at
    before: list[list[int]] = field(default_factory=list)  # its states before each rejoin


@dataclass
class TwinResult:
    states: dict[ModuleId, list[int]]  # observed R^0..R^T per module
    path: np.ndarray  # (T+1, 2): disc xy when the reference module started transitions 1..T+1
    periods: dict[ModuleId, list[float]]  # seconds between a module's transitions
    servo_gaps: dict[ModuleId, float]  # longest time between two servo pulses while running, s
    stalled: list[ModuleId]
    announcements: dict[ModuleId, str]
    virtual_seconds: float
    instructions: int
    # when every running module had made its first transition (s; nan if one never did): the
    # start-up, which a neighbour silent from power-up lengthens by the power-up window, ends
    moving_s: float = math.nan
    # each module's periods that began once the whole robot was moving (the running period)
    running_periods: dict[ModuleId, list[float]] = field(default_factory=dict)
    # modules that lost power (--reset): the longest time without pulses across a power-off
    # (its last pulse before to its first after), kept out of servo_gaps
    servo_outages: dict[ModuleId, float] = field(default_factory=dict)

    @property
    def displacement(self) -> tuple[float, float]:
        if len(self.path) < 2:  # run without physics: no path
            return (0.0, 0.0)
        d = self.path[-1] - self.path[0]
        return float(d[0]), float(d[1])

    @property
    def distance(self) -> float:
        return math.hypot(*self.displacement)

    def state_array(self, legs: int, modules: int, transitions: int) -> np.ndarray:
        """(T+1, n, m) like ``bstool states`` (modules that stalled are padded with -1)."""
        out = -np.ones((transitions + 1, legs, modules), dtype=np.int64)
        for mid, seq in self.states.items():
            k = min(len(seq), transitions + 1)
            out[:k, mid.leg, mid.module] = seq[:k]
        return out

    def period_stats(self) -> tuple[float, float]:
        """Mean and standard deviation of every module's transition period (seconds)."""
        return _stats(self.periods)

    def running_period_stats(self) -> tuple[float, float]:
        """The same over the periods that began once the whole robot was moving
        (:attr:`running_periods`): a robot that waited at power-up for a silent neighbour (a
        cut wire, a failed module: the power-up window) runs at this period afterwards; all
        periods when there are none such."""
        mean, std = _stats(self.running_periods)
        return (mean, std) if math.isfinite(mean) else self.period_stats()


def _stats(periods: dict[ModuleId, list[float]]) -> tuple[float, float]:
    allp = [p for ps in periods.values() for p in ps]
    if not allp:
        return math.nan, math.nan
    return float(np.mean(allp)), float(np.std(allp))


def running_periods(
    times_ns: dict[ModuleId, list[int]], transitions: int
) -> tuple[float, dict[ModuleId, list[float]]]:
    """(moving_s, periods): the instant every module with a first transition had made it, and
    each module's periods (of transitions 1..T) that began at or after it."""
    firsts = [t[1] for t in times_ns.values() if len(t) > 1 and t[1] >= 0]
    if len(firsts) < len(times_ns) or not firsts:
        return math.nan, {}
    moving = max(firsts)
    out = {
        mid: [(b - a) / NS for a, b in pairwise(t[1 : transitions + 1]) if a >= moving and b >= 0]
        for mid, t in times_ns.items()
    }
    return moving / NS, out


def ram_reader(spec: Any) -> Callable[[Stamp], int]:
    """A reader of one RAM variable given as ["nib"|"byte"|"word"|"bit", index]."""
    kind, index = spec
    index = int(index)
    if kind == "nib":
        return lambda s: s.memory.nib(index)
    if kind == "byte":
        return lambda s: s.memory.byte(index)
    if kind == "word":
        return lambda s: s.memory.word(index)
    if kind == "bit":
        return lambda s: s.memory.bit(index)
    raise InputError(f"unknown RAM variable kind {kind!r} in the build's ram_map")
