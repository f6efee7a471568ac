"""The evolution loop: GA or §3.4 co-evolution, one step = one population evaluated and bred.

Everything a run needs to continue is in :class:`RunState` and saved after every step
(:mod:`bstool.evolve.checkpoint`), including the random generator's state and the fitness
cache, so a resumed run repeats exactly what an uninterrupted one would do.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from bstool.controllers import Controller
from bstool.controllers.reference import NN_MODELS
from bstool.evolve.fitness import Evaluator, FitnessCache
from bstool.evolve.ga import Bits, best_index, clean_fitness, mutate, next_generation
from bstool.evolve.problem import Problem
from bstool.evolve.randomize import (
    Randomize,
    combine,
    training_robots,
    validates,
    validation_robots,
)
from bstool.evolve.scoring import (
    ROBUST_MODES,
    Parasites,
    Scored,
    new_parasites,
    next_parasites,
    score_faults,
    score_plain,
    score_robust,
)
from bstool.robot.robotfile import Robot

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
    robust: str | None = None  # --robust: "mean" | "worst" over the n leg rotations
    parasites: int = 0  # --coevolve-faults: parasite population size (0 = off)
    parasite_k: tuple[int, int] = (1, 2)  # failed modules per parasite, low..high

    def __post_init__(self) -> None:
        object.__setattr__(self, "parasite_k", tuple(int(x) for x in self.parasite_k))

    @property
    def coevolve_faults(self) -> bool:
        return self.parasites > 0

    def to_json(self) -> dict[str, Any]:
        """The parameters; the options of --robust / --coevolve-faults only when in use, so a
        plain run's "ga" is unchanged."""
        out = asdict(self)
        if self.robust is None:
            del out["robust"]
        if not self.coevolve_faults:
            del out["parasites"], out["parasite_k"]
        else:
            out["parasite_k"] = list(self.parasite_k)
        return out


@dataclass
class HistoryRow:
    generation: int
    best: float
    mean: float
    population: str
    evaluations: int
    validation: float | None = None  # --randomize: the best's mean over the validation robots

    def to_json(self) -> dict[str, Any]:
        """The row (``validation`` only when measured: a plain run's record is unchanged)."""
        out = asdict(self)
        if self.validation is None:
            del out["validation"]
        return out


@dataclass
class Validated:
    """--randomize: the candidate with the best validation mean so far (best.json's)."""

    name: str
    row: Bits
    partner: Bits | None
    validation: float


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
    parasites: Parasites | None = None  # --coevolve-faults: (Q, K_max) module indices
    robot: Robot | None = None  # --robot: the nominal robot and its ranges (None: the default)
    randomize: Randomize | None = None  # --randomize
    validated: Validated | None = None  # --randomize: the best on the validation robots

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

    def label(self, name: str) -> str:
        """history.csv's population column: "host" for a fault co-evolution's main population."""
        return "host" if name == "main" and self.params.coevolve_faults else name

    def best_controller(self, evaluation: Mapping[str, Any] | None = None) -> Controller | None:
        """The best candidate as a controller; ``evaluation``: how it was evaluated
        (``--stamp-timed``, its period and timing file), added to its ``ga`` settings."""
        if self.best_row is None:
            return None
        name, row, partner, fitness = (
            self.best_name, self.best_row, self.best_partner, self.best_fitness
        )  # fmt: skip
        if self.validated is not None:  # --randomize: the best on the validation robots
            v = self.validated
            name, row, partner, fitness = v.name, v.row, v.partner, v.validation
        return self.problem.controller(
            name,
            row,
            partner,
            fitness=fitness,
            max_trans=self.params.transitions,
            ga={**self.params.to_json(), **(evaluation or {})},
            seed=self.params.seed,
            robot=None if self.robot is None else self.robot.to_json(),
        )

    def stats(self) -> dict[str, int]:
        return {
            "evaluations": self.cache.evaluations,
            "cache_hits": self.cache.hits,
            "offspring": self.offspring,
            "offspring_skipped": self.offspring_skipped,
        }


def new_run(problem: Problem, params: GAParams, init: Mapping[str, Bits] | None = None) -> RunState:
    """Random initial population(s); for ca2ddiff the first 'best' control rule is a random one.

    ``init`` (``evolve --init C.json``): a chromosome per population to start from instead:
    row 0 is it, rows 1.. are copies of it mutated with the run's P_M (drawn after the random
    population, whose draws are kept so the stream has one shape)."""
    if params.pop < 2:
        raise ValueError("population size must be at least 2")
    if params.robust is not None and params.robust not in ROBUST_MODES:
        raise ValueError(f"robust mode must be one of {ROBUST_MODES}")
    if params.robust is not None and params.coevolve_faults:
        raise ValueError("--robust and --coevolve-faults do not combine")
    if params.parasites == 1:
        raise ValueError("the parasite population needs at least 2 members")
    rng = np.random.default_rng(params.seed)
    pops = {
        name: rng.integers(0, 2, (params.pop, problem.length(name)), dtype=np.uint8)
        for name in problem.populations
    }
    state = RunState(problem, params, rng, pops)
    if problem.model == "ca2ddiff":
        state.best_of["control"] = pops["control"][int(rng.integers(params.pop))].copy()
    if params.coevolve_faults:  # drawn last: a plain run's random stream is unchanged
        cells = problem.legs * problem.modules
        state.parasites = new_parasites(params.parasites, params.parasite_k, cells, rng)
    if init is not None:  # after every other draw: a run without it is unchanged
        for name in problem.populations:
            row = np.asarray(init[name], dtype=np.uint8)
            copies = np.repeat(row[None], params.pop - 1, axis=0)
            state.populations[name] = np.concatenate([row[None], mutate(copies, params.pm, rng)])
        if problem.model == "ca2ddiff":
            state.best_of["control"] = np.asarray(init["control"], dtype=np.uint8).copy()
    return state


def score(state: RunState, name: str, partner: Bits | None, evaluator: Evaluator) -> Scored:
    """Fitness of population ``name`` under the run's scoring mode (one evaluator call per
    robot: one, or the step's K with ``--randomize``)."""
    p, bits = state.params, state.populations[name]
    args = (state.problem, name, bits, partner, state.cache, evaluator)

    def on(robot: Any) -> Scored:
        if p.robust is not None:
            return score_robust(*args, p.robust, robot)
        if state.parasites is not None:
            return score_faults(*args, state.parasites, robot)
        return score_plain(*args, robot)

    if state.randomize is None:
        return on(None)
    robots = training_robots(state.robot or Robot(), state.randomize, p.seed, state.step)
    parts = [on(r) for r in robots]
    parasite = None
    if parts[0].parasite_fitness is not None:
        found = [x.parasite_fitness for x in parts if x.parasite_fitness is not None]
        parasite = np.mean(found, axis=0)
    return Scored(
        combine(np.stack([x.fitness for x in parts]), state.randomize.score),
        np.all([x.known for x in parts], axis=0),
        sum(x.paid for x in parts),
        parasite,
    )


def validate(
    state: RunState, name: str, row: Bits, partner: Bits | None, evaluator: Evaluator
) -> tuple[float, int]:
    """The mean distance of one candidate (its plain run) over the validation robots, and the
    evaluations it cost (repeats are cached)."""
    assert state.randomize is not None
    robots = validation_robots(state.robot or Robot(), state.randomize, state.params.seed)
    seq = state.problem.sequences(name, row[None], partner)
    raw, _known, paid = state.cache.evaluate(np.repeat(seq, len(robots), axis=0), evaluator,
                                             robots)  # fmt: skip
    return float(np.mean(clean_fitness(raw))), paid


def evolve_step(
    state: RunState, evaluator: Evaluator, validator: Evaluator | None = None
) -> HistoryRow:
    """Evaluate the scheduled population (cached), record it, breed the next generation."""
    name = state.schedule(state.step)
    partner_name = state.problem.partner_of(name)
    partner = state.best_of[partner_name] if partner_name else None
    bits = state.populations[name]
    scored = score(state, name, partner, evaluator)
    fitness, known = scored.fitness, scored.known
    label = state.label(name)
    generation = sum(1 for r in state.history if r.population == label)
    if generation > 0:
        state.offspring += len(bits) - 1
        state.offspring_skipped += int(known[1:].sum())
    row = HistoryRow(generation, float(fitness.max()), float(fitness.mean()), label, scored.paid)
    state.history.append(row)
    i = best_index(fitness)
    state.best_of[name] = bits[i].copy()
    # Against parasites or random robots, fitness depends on the parasites or robots of the
    # moment: scores of different generations are not comparable, so the best is the best of
    # the latest generation (and with --randomize, best.json is the best validated one).
    changing = state.parasites is not None or state.randomize is not None
    if fitness[i] > state.best_fitness or changing:
        state.best_fitness = float(fitness[i])
        state.best_name = name
        state.best_row = bits[i].copy()
        state.best_partner = None if partner is None else partner.copy()
    if state.randomize is not None and validates(state.randomize, state.step, state.total_steps):
        value, paid = validate(state, name, bits[i], partner, validator or evaluator)
        row.validation, row.evaluations = value, row.evaluations + paid
        if state.validated is None or value > state.validated.validation:
            kept = None if partner is None else partner.copy()
            state.validated = Validated(name, bits[i].copy(), kept, value)
    p = state.params
    state.populations[name] = next_generation(bits, fitness, p.pc, p.pm, state.rng)
    if state.parasites is not None and scored.parasite_fitness is not None:
        pf = scored.parasite_fitness
        pgen = sum(1 for r in state.history if r.population == "parasite")
        state.history.append(HistoryRow(pgen, float(pf.max()), float(pf.mean()), "parasite", 0))
        cells = state.problem.legs * state.problem.modules
        state.parasites = next_parasites(state.parasites, pf, p.parasite_k, cells, state.rng)
    state.step += 1
    return row


def run(
    state: RunState,
    evaluator: Evaluator,
    after_step: Callable[[RunState, HistoryRow], None] | None = None,
    validator: Evaluator | None = None,
) -> RunState:
    """Step until done; ``after_step`` saves outputs / shows progress after every step.
    ``validator``: the evaluator of --randomize's validation (the robot's own timestep when
    training runs at a coarser one; default ``evaluator``)."""
    while not state.done:
        row = evolve_step(state, evaluator, validator)
        if after_step is not None:
            after_step(state, row)
    return state
