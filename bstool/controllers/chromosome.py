"""Chromosomes (bit strings, one uint8 0/1 per gene) for each model and population.

Bit order (docs/controllers.md): every state or rule output is 4 bits, most significant first.

* ca1d, ca2dsing: initial states leg by leg, lead first (n·m·4 bits), then the rule outputs in
  rule-index order 0..4095 (Table 1's lexicographic order): 120 + 16384 = 16504 bits.
* ca2ddiff control population: the n lead initial states, then the control rule (16404 bits).
* ca2ddiff leg population: the non-lead initial states leg by leg (module 1 first), then the
  leg rule (16484 bits).
* nnsig, nnsin: per leg, 4 bits of lead initial state then the upper-triangular weights w_ab,
  a < b, in row order (0,1), (0,2), ..., (0,m−1), (1,2), ...: 19 bits per leg, 95 bits.

All functions take a population: bits (P, length), decoded fields with a leading P axis.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from bstool.controllers.angles import K

GENE = 4  # bits per state
RULE = K**3  # rule table entries
U8 = npt.NDArray[np.uint8]
IntArray = npt.NDArray[np.integer]
_WEIGHTS = np.array([8, 4, 2, 1], dtype=np.uint8)


def ints_to_bits(values: IntArray) -> U8:
    """(..., N) ints 0..15 → (..., 4N) bits, most significant bit first."""
    v = np.asarray(values, dtype=np.uint8)
    bits = (v[..., None] >> np.array([3, 2, 1, 0], dtype=np.uint8)) & 1
    return bits.reshape(*v.shape[:-1], v.shape[-1] * GENE).astype(np.uint8)


def bits_to_ints(bits: U8) -> U8:
    """(..., 4N) bits → (..., N) ints 0..15."""
    b = np.asarray(bits, dtype=np.uint8)
    grouped = b.reshape(*b.shape[:-1], b.shape[-1] // GENE, GENE)
    return (grouped * _WEIGHTS).sum(axis=-1).astype(np.uint8)


def ca_length(legs: int, modules: int) -> int:
    return legs * modules * GENE + RULE * GENE


def encode_ca(initial: IntArray, rule: IntArray) -> U8:
    """initial (P, n, m), rule (P, 4096) → (P, 16504) for n=5, m=6."""
    init = np.asarray(initial)
    p = init.shape[0]
    return np.concatenate([ints_to_bits(init.reshape(p, -1)), ints_to_bits(rule)], axis=1)


def decode_ca(bits: U8, legs: int, modules: int) -> tuple[U8, U8]:
    """(P, L) → initial states (P, n, m), rule (P, 4096)."""
    b = np.asarray(bits, dtype=np.uint8)
    cut = legs * modules * GENE
    initial = bits_to_ints(b[:, :cut]).reshape(-1, legs, modules)
    return initial, bits_to_ints(b[:, cut:])


def control_length(legs: int) -> int:
    return legs * GENE + RULE * GENE


def leg_length(legs: int, modules: int) -> int:
    return legs * (modules - 1) * GENE + RULE * GENE


def encode_control(leads: IntArray, rule: IntArray) -> U8:
    """ca2ddiff control population: lead initial states (P, n), control rule (P, 4096)."""
    return np.concatenate([ints_to_bits(leads), ints_to_bits(rule)], axis=1)


def decode_control(bits: U8, legs: int) -> tuple[U8, U8]:
    b = np.asarray(bits, dtype=np.uint8)
    cut = legs * GENE
    return bits_to_ints(b[:, :cut]), bits_to_ints(b[:, cut:])


def encode_leg(others: IntArray, rule: IntArray) -> U8:
    """ca2ddiff leg population: non-lead initial states (P, n, m−1), leg rule (P, 4096)."""
    o = np.asarray(others)
    p = o.shape[0]
    return np.concatenate([ints_to_bits(o.reshape(p, -1)), ints_to_bits(rule)], axis=1)


def decode_leg(bits: U8, legs: int, modules: int) -> tuple[U8, U8]:
    b = np.asarray(bits, dtype=np.uint8)
    cut = legs * (modules - 1) * GENE
    others = bits_to_ints(b[:, :cut]).reshape(-1, legs, modules - 1)
    return others, bits_to_ints(b[:, cut:])


def upper_pairs(modules: int) -> list[tuple[int, int]]:
    """(a, b), a < b, in chromosome order."""
    return [(a, b) for a in range(modules) for b in range(a + 1, modules)]


def nn_length(legs: int, modules: int) -> int:
    return legs * (GENE + modules * (modules - 1) // 2)


def encode_nn(leads: IntArray, weights: IntArray) -> U8:
    """leads (P, n), weights (P, n, m, m) 0/1 (only a < b read) → (P, 95) for n=5, m=6."""
    w = np.asarray(weights, dtype=np.uint8)
    p, n, m, _ = w.shape
    a, b = np.triu_indices(m, k=1)  # row order, same as upper_pairs
    lead_bits = ints_to_bits(np.asarray(leads).reshape(p, n, 1))  # (P, n, 4)
    per_leg = np.concatenate([lead_bits, w[:, :, a, b]], axis=2)
    return per_leg.reshape(p, -1)


def decode_nn(bits: U8, legs: int, modules: int) -> tuple[U8, U8]:
    """(P, 95) → leads (P, n), weights (P, n, m, m) with zeros on and below the diagonal."""
    b = np.asarray(bits, dtype=np.uint8)
    p = b.shape[0]
    per_leg = b.reshape(p, legs, -1)
    leads = bits_to_ints(per_leg[:, :, :GENE])[:, :, 0]
    weights = np.zeros((p, legs, modules, modules), dtype=np.uint8)
    ia, ib = np.triu_indices(modules, k=1)
    weights[:, :, ia, ib] = per_leg[:, :, GENE:]
    return leads, weights
