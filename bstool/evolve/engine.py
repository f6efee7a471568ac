"""The evolution loop: GA or §3.4 co-evolution, one step = one population evaluated and bred.

Everything a run needs to continue is in :class:`RunState` and saved after every step
(:mod:`bstool.evolve.checkpoint`), including the random generator's state and the fitness
cache, so a resumed run repeats exactly what an uninterrupted one would do.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from bstool.controllers import Controller
from bstool.controllers.reference import NN_MODELS
from bstool.evolve.fitness import Evaluator, FitnessCache
from bstool.evolve.ga import Bits, best_index, clean_fitness, next_generation
from bstool.evolve.problem import Problem

MAX_COEVOL_GENERATION = 20  # §3.4


def default_pm(model: str) -> float:
    """About one flip that matters per chromosome (docs/evolution.md): NN 95 bits → 0.01;
    CA ≈ 3.3 flips over 16504 bits, ≈ 0.75 of them on rule entries a 30-step run reads."""
    return 0.01 if model in NN_MODELS else 0.0002


def default_gens(model: str) -> int:
    """ca2ddiff counts outer loops of 2×20 GA generations; 3 ≈ the others' budget of 100."""
    return 3 if model == "ca2ddiff" else 100


@dataclass(frozen=True)
class GAParams:
    """Table 2 (POP_SIZE, MAX_GEN, P_C, P_M, MAX_TRANS) plus MAX_COEVOL_GENERATION, seed."""

    pop: int = 50
    gens: int = 100
    pc: float = 0.8
    pm: float = 0.0002
    transitions: int = 30
    coevol_gens: int = MAX_COEVOL_GENERATION
    seed: int = 0

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class HistoryRow:
    generation: int
    best: float
    mean: float
    population: str
    evaluations: int


@dataclass
class RunState:
    problem: Problem
    params: GAParams
    rng: np.random.Generator
    populations: dict[str, Bits]
    best_of: dict[str, Bits] = field(default_factory=dict)
    step: int = 0
    cache: FitnessCache = field(default_factory=FitnessCache)
    history: list[HistoryRow] = field(default_factory=list)
    best_fitness: float = -math.inf
    best_name: str = ""
    best_row: Bits | None = None
    best_partner: Bits | None = None
    offspring: int = 0
    offspring_skipped: int = 0

    @property
    def total_steps(self) -> int:
        p = self.params
        return p.gens * 2 * p.coevol_gens if self.problem.model == "ca2ddiff" else p.gens

    @property
    def done(self) -> bool:
        return self.step >= self.total_steps

    def schedule(self, step: int) -> str:
        """Which population step ``step`` evaluates: §3.4 runs 20 leg, then 20 control steps."""
        if self.problem.model != "ca2ddiff":
            return "main"
        c = self.params.coevol_gens
        return "leg" if step % (2 * c) < c else "control"

    def best_controller(self) -> Controller | None:
        if self.best_row is None:
            return None
        return self.problem.controller(
            self.best_name,
            self.best_row,
            self.best_partner,
            fitness=self.best_fitness,
            max_trans=self.params.transitions,
            ga=self.params.to_json(),
            seed=self.params.seed,
        )

    def stats(self) -> dict[str, int]:
        return {
            "evaluations": self.cache.evaluations,
            "cache_hits": self.cache.hits,
            "offspring": self.offspring,
            "offspring_skipped": self.offspring_skipped,
        }


def new_run(problem: Problem, params: GAParams) -> RunState:
    """Random initial population(s); for ca2ddiff the first 'best' control rule is a random one."""
    if params.pop < 2:
        raise ValueError("population size must be at least 2")
    rng = np.random.default_rng(params.seed)
    pops = {
        name: rng.integers(0, 2, (params.pop, problem.length(name)), dtype=np.uint8)
        for name in problem.populations
    }
    state = RunState(problem, params, rng, pops)
    if problem.model == "ca2ddiff":
        state.best_of["control"] = pops["control"][int(rng.integers(params.pop))].copy()
    return state


def evolve_step(state: RunState, evaluator: Evaluator) -> HistoryRow:
    """Evaluate the scheduled population (cached), record it, breed the next generation."""
    name = state.schedule(state.step)
    partner_name = state.problem.partner_of(name)
    partner = state.best_of[partner_name] if partner_name else None
    bits = state.populations[name]
    seqs = state.problem.sequences(name, bits, partner)
    raw, known, paid = state.cache.evaluate(seqs, evaluator)
    fitness = clean_fitness(raw)
    generation = sum(1 for r in state.history if r.population == name)
    if generation > 0:
        state.offspring += len(bits) - 1
        state.offspring_skipped += int(known[1:].sum())
    row = HistoryRow(generation, float(fitness.max()), float(fitness.mean()), name, paid)
    state.history.append(row)
    i = best_index(fitness)
    state.best_of[name] = bits[i].copy()
    if fitness[i] > state.best_fitness:
        state.best_fitness = float(fitness[i])
        state.best_name = name
        state.best_row = bits[i].copy()
        state.best_partner = None if partner is None else partner.copy()
    p = state.params
    state.populations[name] = next_generation(bits, fitness, p.pc, p.pm, state.rng)
    state.step += 1
    return row


def run(
    state: RunState,
    evaluator: Evaluator,
    after_step: Callable[[RunState, HistoryRow], None] | None = None,
) -> RunState:
    """Step until done; ``after_step`` saves outputs / shows progress after every step."""
    while not state.done:
        row = evolve_step(state, evaluator)
        if after_step is not None:
            after_step(state, row)
    return state
