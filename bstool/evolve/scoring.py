"""How a population's state sequences become fitness: plain, ``--robust``, ``--coevolve-faults``.

Every mode is a batch of ordinary state sequences for :class:`FitnessCache` (one evaluator call
per step), followed by arithmetic on the distances:

- plain: one sequence per candidate, fitness = its distance.
- robust: the n leg rotations of each candidate's sequence (``rotate_states``), fitness = their
  mean or their minimum ("worst").
- fault co-evolution (paper §6): the healthy sequence plus one sequence per parasite (a set of
  failed modules, applied by the vectorised controllers); host fitness = mean of those Q+1
  distances, parasite fitness = mean over hosts of the fraction of healthy distance it took away.

The cache holds raw distances keyed by the hash of each (rotated or faulted) sequence, so a
sequence's distance is shared by every mode and every candidate that produces it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from bstool.controllers.rotation import rotate_states
from bstool.errors import InputError
from bstool.evolve.fitness import Evaluator, FitnessCache
from bstool.evolve.ga import Bits, best_index, clean_fitness, roulette
from bstool.evolve.problem import Problem

Floats = npt.NDArray[np.float64]
Parasites = npt.NDArray[np.int16]  # (Q, K_max) module indices leg·m + module, −1 = unused
ROBUST_MODES = ("mean", "worst")
RESIZE_PROBABILITY = 1 / 3  # parasite mutation: add/drop a module (when K is a range)


@dataclass(frozen=True)
class Scored:
    """One step's outcome: candidate fitness, which candidates cost nothing, and the bill."""

    fitness: Floats
    known: npt.NDArray[np.bool_]
    paid: int
    parasite_fitness: Floats | None = None


def score_plain(
    problem: Problem,
    name: str,
    bits: Bits,
    partner: Bits | None,
    cache: FitnessCache,
    ev: Evaluator,
    robot: Any = None,
) -> Scored:
    seqs = problem.sequences(name, bits, partner)
    raw, known, paid = cache.evaluate(seqs, ev, robot)
    return Scored(clean_fitness(raw), known, paid)


def rotations(seqs: np.ndarray, legs: int) -> np.ndarray:
    """(P, T+1, n, m) → (P·n, T+1, n, m): candidate p's rotation r is row p·n + r."""
    return np.stack([rotate_states(s, r) for s in seqs for r in range(legs)])


def combine(distances: Floats, mode: str) -> Floats:
    """Robust fitness of rows of per-rotation distances (non-finite/negative count as 0)."""
    d = clean_fitness(distances)
    return d.min(axis=1) if mode == "worst" else d.mean(axis=1)


def score_robust(
    problem: Problem,
    name: str,
    bits: Bits,
    partner: Bits | None,
    cache: FitnessCache,
    ev: Evaluator,
    mode: str,
    robot: Any = None,
) -> Scored:
    seqs = problem.sequences(name, bits, partner)
    n = problem.legs
    raw, known, paid = cache.evaluate(rotations(seqs, n), ev, robot)
    p = len(seqs)
    return Scored(
        combine(raw.reshape(p, n), mode), np.asarray(known.reshape(p, n).all(axis=1)), paid
    )


# --- parasites: sets of failed modules -----------------------------------------------------


def parse_k(text: str, cells: int) -> tuple[int, int]:
    """``--parasite-k``: "K" or "A..B" (failed modules per parasite), within 1..n·m."""
    try:
        lo, dots, hi = text.partition("..")
        k = (int(lo), int(hi if dots else lo))
    except ValueError:
        raise InputError(
            f"--parasite-k {text!r} is not a number or a range",
            hint='give K (e.g. 1) or a range A..B (e.g. "1..2")',
        ) from None
    if not 1 <= k[0] <= k[1] <= cells:
        raise InputError(
            f"--parasite-k {text!r} must lie within 1..{cells} (the robot's modules), low ≤ high",
            hint='e.g. --parasite-k 1 or --parasite-k "1..2"',
        )
    return k


def parasite_cells(row: npt.ArrayLike, modules: int) -> list[tuple[int, int]]:
    """(leg, module) cells of one parasite row."""
    return [(int(c) // modules, int(c) % modules) for c in np.asarray(row) if c >= 0]


def _row(members: list[int], kmax: int) -> npt.NDArray[np.int16]:
    out = np.full(kmax, -1, dtype=np.int16)
    out[: len(members)] = sorted(members)
    return out


def new_parasites(
    count: int, k: tuple[int, int], cells: int, rng: np.random.Generator
) -> Parasites:
    """``count`` random parasites: size uniform in k, distinct modules uniform."""
    rows = []
    for _ in range(count):
        size = int(rng.integers(k[0], k[1] + 1))
        members = [int(c) for c in rng.choice(cells, size=size, replace=False)]
        rows.append(_row(members, k[1]))
    return np.stack(rows)


def mutate_parasite(
    row: npt.ArrayLike, k: tuple[int, int], cells: int, rng: np.random.Generator
) -> npt.NDArray[np.int16]:
    """One move: swap a failed module for a working one, or (K a range, probability 1/3, or
    always when every module has failed) add or drop one. Always consumes the same three draws,
    so the random stream has a fixed shape."""
    members = [int(c) for c in np.asarray(row) if c >= 0]
    coin, pick, other = rng.random(3)
    size = len(members)
    free = [c for c in range(cells) if c not in members]
    can_grow, can_shrink = size < k[1], size > k[0]
    resize = (can_grow or can_shrink) and (coin < RESIZE_PROBABILITY or not free)
    if resize and can_grow and (not can_shrink or pick < 0.5):
        members.append(free[min(int(other * len(free)), len(free) - 1)])
    elif resize:
        members.pop(min(int(other * size), size - 1))
    elif free:
        members[min(int(pick * size), size - 1)] = free[min(int(other * len(free)), len(free) - 1)]
    return _row(members, k[1])


def next_parasites(
    parasites: Parasites,
    fitness: npt.ArrayLike,
    k: tuple[int, int],
    cells: int,
    rng: np.random.Generator,
) -> Parasites:
    """Row 0 = the most harmful parasite (unchanged); rows 1.. = roulette-selected parents,
    each mutated by :func:`mutate_parasite` (no crossover)."""
    elite = parasites[best_index(fitness)]
    parents = roulette(fitness, len(parasites) - 1, rng)
    children = [mutate_parasite(parasites[i], k, cells, rng) for i in parents]
    return np.stack([elite, *children]).astype(np.int16)


def score_faults(
    problem: Problem,
    name: str,
    bits: Bits,
    partner: Bits | None,
    cache: FitnessCache,
    ev: Evaluator,
    parasites: Parasites,
    robot: Any = None,
) -> Scored:
    """Every host meets every parasite: (Q+1)·P sequences in one batch.

    host fitness  = (d_healthy + Σ_q d_q) / (Q + 1)
    parasite fit. = mean over hosts of max(0, 1 − d_q / d_healthy)  (0 where d_healthy = 0)
    """
    m = problem.modules
    batches = [problem.sequences(name, bits, partner)]
    batches += [
        problem.sequences(name, bits, partner, failed=parasite_cells(q, m)) for q in parasites
    ]
    p = len(bits)
    raw, known, paid = cache.evaluate(np.concatenate(batches), ev, robot)
    d = clean_fitness(raw).reshape(len(batches), p)  # row 0 healthy, row q+1 parasite q
    host = d.mean(axis=0)
    healthy = d[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        lost = np.where(healthy > 0, 1.0 - d[1:] / np.where(healthy > 0, healthy, 1.0), 0.0)
    parasite = np.maximum(lost, 0.0).mean(axis=1)
    return Scored(host, np.asarray(known.reshape(len(batches), p).all(axis=0)), paid, parasite)
