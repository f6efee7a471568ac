"""The paper's GA operators (§3.2.3) on bit-string populations (P, L) of uint8 0/1.

Roulette-wheel selection, one elite carried over unchanged, one-point crossover with P_C at a
random locus, then an independent bit flip with P_M on every gene of every offspring.
All randomness comes from the ``numpy.random.Generator`` passed in, in a fixed order, so a run
is reproducible from its seed and resumable from a saved generator state.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

Bits = npt.NDArray[np.uint8]
Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.intp]


def clean_fitness(fitness: npt.ArrayLike) -> Floats:
    """Non-finite or negative fitness (a blown-up simulation) counts as 0."""
    f = np.asarray(fitness, dtype=np.float64)
    return np.where(np.isfinite(f) & (f > 0), f, 0.0)


def roulette(fitness: npt.ArrayLike, count: int, rng: np.random.Generator) -> Ints:
    """``count`` indices drawn with probability proportional to fitness (uniform if all 0)."""
    f = clean_fitness(fitness)
    total = f.sum()
    draws = rng.random(count)
    if total <= 0:
        return np.minimum((draws * len(f)).astype(np.intp), len(f) - 1)
    edges = np.cumsum(f) / total
    return np.minimum(np.searchsorted(edges, draws, side="right"), len(f) - 1).astype(np.intp)


def crossover(a: Bits, b: Bits, pc: float, rng: np.random.Generator) -> tuple[Bits, Bits]:
    """One-point crossover of pairs (a[i], b[i]) with probability ``pc``.

    The locus x is in 1..L−1: child 1 = a[:x] + b[x:], child 2 = b[:x] + a[x:]. Pairs that do
    not cross are copied.
    """
    pairs, length = a.shape
    cross = rng.random(pairs) < pc
    locus = rng.integers(1, length, size=pairs) if length > 1 else np.ones(pairs, dtype=np.int64)
    head = np.arange(length)[None, :] < np.where(cross, locus, length)[:, None]
    return np.where(head, a, b), np.where(head, b, a)


def mutate(bits: Bits, pm: float, rng: np.random.Generator) -> Bits:
    """Flip every gene independently with probability ``pm``."""
    flips = rng.random(bits.shape) < pm
    return bits ^ flips.astype(np.uint8)


def best_index(fitness: npt.ArrayLike) -> int:
    """Index of the fittest (first one on ties)."""
    return int(np.argmax(clean_fitness(fitness)))


def next_generation(
    population: Bits, fitness: npt.ArrayLike, pc: float, pm: float, rng: np.random.Generator
) -> Bits:
    """Row 0 = the elite (unchanged); rows 1.. = selected pairs, crossed over, mutated."""
    size, _ = population.shape
    elite = population[best_index(fitness)]
    children = size - 1
    pairs = (children + 1) // 2
    parents = roulette(fitness, 2 * pairs, rng)
    c1, c2 = crossover(population[parents[0::2]], population[parents[1::2]], pc, rng)
    offspring = np.empty((2 * pairs, population.shape[1]), dtype=np.uint8)
    offspring[0::2] = c1
    offspring[1::2] = c2
    offspring = mutate(offspring[:children], pm, rng)
    return np.concatenate([elite[None], offspring]).astype(np.uint8)
