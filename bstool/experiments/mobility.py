"""Degree of mobility under module failures (paper §5.1, eq. 15).

M_D = distance with the failed modules / distance without failures × 100 %. A failed module
keeps its R^0 state (the controllers produce that); every run here is the same number of
transitions as the baseline, on the same simulator.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bstool.controllers import Controller
from bstool.errors import InputError
from bstool.moduleid import ModuleId, all_modules

# M_D within this of 100 % counts as "keeps 100 %" (exactly identical runs give exactly 100).
FULL_MOBILITY_TOLERANCE = 1e-9

Evaluate = Callable[[Sequence[np.ndarray]], list[float]]
"""Distances for a list of state sequences (a BatchEvaluator wrapped by `distances_with`)."""


def distances_with(evaluator: object, progress: Callable[[int], None] | None = None) -> Evaluate:
    """Adapt a :class:`bstool.sim.BatchEvaluator` (or a Simulator) to :data:`Evaluate`;
    ``progress(k)`` hears of every k finished runs."""

    def evaluate(states: Sequence[np.ndarray]) -> list[float]:
        if hasattr(evaluator, "evaluate"):
            results = evaluator.evaluate(list(states), progress=progress)
            return [r.distance for r in results]
        out = []
        for s in states:
            out.append(evaluator.run(s).distance)  # type: ignore[attr-defined]
            if progress:
                progress(1)
        return out

    return evaluate


def distances_of(run: Callable[[Sequence[np.ndarray]], Sequence[Any]]) -> Evaluate:
    """:data:`Evaluate` from a function giving one result with a ``distance`` per sequence
    (a plain or a stamp-timed batch run)."""
    return lambda states: [float(r.distance) for r in run(states)]


def mobility(distance: float, baseline: float) -> float:
    """Eq. 15 in percent; NaN when the healthy robot does not move at all."""
    return 100.0 * distance / baseline if baseline > 0 else math.nan


@dataclass(frozen=True)
class FaultRun:
    failed: tuple[ModuleId, ...]
    distance: float
    mobility: float  # percent


@dataclass(frozen=True)
class SingleFaults:
    """One run per module failed alone, plus the healthy baseline."""

    baseline: float
    runs: tuple[FaultRun, ...]  # in all_modules order: leg by leg, lead first
    legs: int
    modules: int

    @property
    def table(self) -> np.ndarray:
        """M_D in percent, shape (legs, modules)."""
        return np.array([r.mobility for r in self.runs]).reshape(self.legs, self.modules)

    def count_at_least(self, percent: float) -> int:
        """How many single failures keep at least ``percent`` % mobility."""
        limit = percent - FULL_MOBILITY_TOLERANCE * max(1.0, percent)
        return int(sum(1 for r in self.runs if r.mobility >= limit))

    def to_json(self) -> dict[str, object]:
        return {
            "baseline_distance": self.baseline,
            "mobility": [[_finite(x) for x in row] for row in self.table.tolist()],
            "runs": [
                {
                    "failed": [str(m) for m in r.failed],
                    "distance": r.distance,
                    "mobility": _finite(r.mobility),
                }
                for r in self.runs
            ],
            "keep_80": self.count_at_least(80.0),
            "keep_100": self.count_at_least(100.0),
            "modules": len(self.runs),
        }


def single_failures(
    controller: Controller, evaluate: Evaluate, transitions: int, baseline: float | None = None
) -> SingleFaults:
    """Fail each module alone (n·m runs) and compute M_D for each (``baseline``: the healthy
    distance, when the caller has it already)."""
    modules = all_modules(controller.legs, controller.modules)
    distances = evaluate([controller.states(transitions, failed=[mid]) for mid in modules])
    if baseline is None:
        baseline = evaluate([controller.states(transitions)])[0]
    runs = tuple(
        FaultRun((mid,), d, mobility(d, baseline))
        for mid, d in zip(modules, distances, strict=True)
    )
    return SingleFaults(baseline, runs, controller.legs, controller.modules)


def random_failures(
    controller: Controller,
    evaluate: Evaluate,
    transitions: int,
    k: int,
    samples: int,
    seed: int = 0,
    baseline: float | None = None,
) -> list[FaultRun]:
    """``samples`` runs, each with ``k`` distinct modules failed, drawn uniformly at random.

    When there are fewer distinct k-subsets than ``samples``, every subset is run once.
    """
    modules = all_modules(controller.legs, controller.modules)
    if not 1 <= k <= len(modules):
        raise InputError(f"--k must be between 1 and {len(modules)}, got {k}")
    if samples < 1:
        raise InputError(f"--samples must be at least 1, got {samples}")
    subsets = _draw_subsets(len(modules), k, samples, np.random.default_rng(seed))
    failed_sets = [tuple(modules[i] for i in subset) for subset in subsets]
    sequences = [controller.states(transitions, failed=list(f)) for f in failed_sets]
    if baseline is None:
        sequences.insert(0, controller.states(transitions))
    distances = evaluate(sequences)
    if baseline is None:
        baseline, distances = distances[0], distances[1:]
    return [
        FaultRun(f, d, mobility(d, baseline)) for f, d in zip(failed_sets, distances, strict=True)
    ]


def _draw_subsets(
    population: int, k: int, samples: int, rng: np.random.Generator
) -> list[tuple[int, ...]]:
    total = math.comb(population, k)
    if total <= samples:
        from itertools import combinations

        return list(combinations(range(population), k))
    seen: set[tuple[int, ...]] = set()
    out: list[tuple[int, ...]] = []
    while len(out) < samples:
        subset = tuple(sorted(int(x) for x in rng.choice(population, size=k, replace=False)))
        if subset not in seen:
            seen.add(subset)
            out.append(subset)
    return out


def summarize(runs: Sequence[FaultRun]) -> dict[str, float]:
    """Mean, quartiles and extremes of M_D over a set of runs (NaNs ignored)."""
    values = np.array([r.mobility for r in runs], dtype=float)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return {"n": 0.0}
    q1, median, q3 = np.percentile(values, [25, 50, 75])
    return {
        "n": float(values.size),
        "mean": float(values.mean()),
        "median": float(median),
        "q1": float(q1),
        "q3": float(q3),
        "min": float(values.min()),
        "max": float(values.max()),
    }


def _finite(x: float) -> float | None:
    return None if not math.isfinite(x) else x
