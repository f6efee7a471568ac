"""Statistics of the GA operators: roulette wheel, one-point crossover, bit-flip mutation."""

from __future__ import annotations

import numpy as np

from bstool.evolve.ga import best_index, crossover, mutate, next_generation, roulette


def test_roulette_is_proportional_to_fitness() -> None:
    rng = np.random.default_rng(1)
    fitness = np.array([1.0, 2.0, 3.0, 4.0, 0.0])
    draws = roulette(fitness, 100_000, rng)
    freq = np.bincount(draws, minlength=5) / len(draws)
    np.testing.assert_allclose(freq, fitness / fitness.sum(), atol=0.006)
    assert freq[4] == 0


def test_roulette_degenerate_fitness() -> None:
    rng = np.random.default_rng(2)
    freq = np.bincount(roulette(np.zeros(4), 40_000, rng), minlength=4) / 40_000
    np.testing.assert_allclose(freq, 0.25, atol=0.01)  # all zero: uniform
    weird = np.array([np.nan, -3.0, np.inf, 1.0])  # broken runs count as zero fitness
    assert set(roulette(weird, 1000, rng).tolist()) == {3}


def test_one_point_crossover() -> None:
    rng = np.random.default_rng(3)
    pairs, length = 20_000, 10
    a = np.zeros((pairs, length), dtype=np.uint8)
    b = np.ones((pairs, length), dtype=np.uint8)
    c1, c2 = crossover(a, b, 1.0, rng)
    loci = (c1 == 0).sum(axis=1)
    # child 1 = a[:x] + b[x:] with x uniform in 1..L−1; child 2 is its complement
    assert (c1 == (np.arange(length)[None] >= loci[:, None])).all()
    assert (c2 == 1 - c1).all()
    freq = np.bincount(loci, minlength=length) / pairs
    assert freq[0] == 0 and np.allclose(freq[1:], 1 / (length - 1), atol=0.01)
    c1, c2 = crossover(a, b, 0.0, rng)
    assert (c1 == a).all() and (c2 == b).all()
    c1, _ = crossover(a, b, 0.3, rng)
    assert abs((c1[:, -1] == 1).mean() - 0.3) < 0.015  # crossed pairs end with b's genes


def test_mutation_flips_each_gene_with_pm() -> None:
    rng = np.random.default_rng(4)
    bits = rng.integers(0, 2, (200, 1000), dtype=np.uint8)
    out = mutate(bits, 0.01, rng)
    flipped = out != bits
    assert abs(flipped.mean() - 0.01) < 0.001
    per_gene = flipped.mean(axis=0)  # no gene position is favoured
    assert per_gene.max() < 0.05
    assert (mutate(bits, 0.0, rng) == bits).all() and (mutate(bits, 1.0, rng) == 1 - bits).all()


def test_next_generation_keeps_one_elite() -> None:
    rng = np.random.default_rng(5)
    for size in (2, 5, 8):
        pop = rng.integers(0, 2, (size, 64), dtype=np.uint8)
        fitness = rng.random(size)
        nxt = next_generation(pop, fitness, 0.8, 0.05, rng)
        assert nxt.shape == pop.shape and nxt.dtype == np.uint8
        assert (nxt[0] == pop[best_index(fitness)]).all()
    assert best_index([1.0, 3.0, 3.0]) == 1
    a = next_generation(pop, fitness, 0.8, 0.05, np.random.default_rng(9))
    b = next_generation(pop, fitness, 0.8, 0.05, np.random.default_rng(9))
    assert (a == b).all()


def test_selection_pressure_without_variation() -> None:
    """With P_C = P_M = 0 offspring are copies of roulette-selected parents."""
    rng = np.random.default_rng(6)
    pop = np.eye(4, dtype=np.uint8)
    fitness = np.array([0.0, 1.0, 1.0, 2.0])
    counts = np.zeros(4)
    for _ in range(10_000):
        nxt = next_generation(pop, fitness, 0.0, 0.0, rng)
        counts += nxt[1:].sum(axis=0)
    freq = counts / counts.sum()
    np.testing.assert_allclose(freq, fitness / fitness.sum(), atol=0.01)
