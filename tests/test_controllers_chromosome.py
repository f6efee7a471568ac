"""Chromosome encode/decode round trips and the documented bit order."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from bstool.controllers import chromosome as ch

FAST = settings(max_examples=25, deadline=None)


def test_lengths_match_the_paper() -> None:
    assert ch.ca_length(5, 6) == 16504
    assert ch.nn_length(5, 6) == 95
    assert ch.control_length(5) == 20 + 16384
    assert ch.leg_length(5, 6) == 100 + 16384


def test_bit_order() -> None:
    init = np.zeros((1, 5, 6), dtype=int)
    init[0, 0, 0] = 0b1000
    init[0, 0, 1] = 0b0001
    rule = np.zeros((1, 4096), dtype=int)
    rule[0, 1] = 0b0100  # Table 1's row 1 output
    rule[0, 4095] = 0b1101
    bits = ch.encode_ca(init, rule)[0]
    assert bits.shape == (16504,)
    assert bits[:8].tolist() == [1, 0, 0, 0, 0, 0, 0, 1]  # MSB first, leg 0 lead then module 1
    assert bits[120 + 4 : 120 + 8].tolist() == [0, 1, 0, 0]
    assert bits[-4:].tolist() == [1, 1, 0, 1]
    w = np.zeros((1, 5, 6, 6), dtype=int)
    w[0, 0, 0, 1] = 1
    w[0, 0, 4, 5] = 1
    w[0, 1, 0, 2] = 1
    nn = ch.encode_nn(np.array([[0b1010, 0, 0, 0, 0]]), w)[0]
    assert nn[:4].tolist() == [1, 0, 1, 0]
    assert nn[4] == 1 and nn[4 + 14] == 1 and nn[4:19].sum() == 2  # (0,1) first, (4,5) last
    assert nn[19 + 4 + 1] == 1  # leg 1: lead bits, then (0,1), (0,2)
    assert ch.upper_pairs(6)[:6] == [(0, 1), (0, 2), (0, 3), (0, 4), (0, 5), (1, 2)]


@FAST
@given(
    init=arrays(np.uint8, (3, 5, 6), elements=st.integers(0, 15)),
    rule=arrays(np.uint8, (3, 4096), elements=st.integers(0, 15)),
)
def test_ca_round_trip(init: np.ndarray, rule: np.ndarray) -> None:
    bits = ch.encode_ca(init, rule)
    assert set(np.unique(bits)) <= {0, 1}
    i2, r2 = ch.decode_ca(bits, 5, 6)
    np.testing.assert_array_equal(i2, init)
    np.testing.assert_array_equal(r2, rule)


@FAST
@given(
    leads=arrays(np.uint8, (2, 5), elements=st.integers(0, 15)),
    others=arrays(np.uint8, (2, 5, 5), elements=st.integers(0, 15)),
    rule=arrays(np.uint8, (2, 4096), elements=st.integers(0, 15)),
)
def test_ca2ddiff_round_trip(leads: np.ndarray, others: np.ndarray, rule: np.ndarray) -> None:
    cbits = ch.encode_control(leads, rule)
    lbits = ch.encode_leg(others, rule)
    assert cbits.shape == (2, 16404) and lbits.shape == (2, 16484)
    d_leads, d_rule = ch.decode_control(cbits, 5)
    d_others, d_rule2 = ch.decode_leg(lbits, 5, 6)
    np.testing.assert_array_equal(d_leads, leads)
    np.testing.assert_array_equal(d_others, others)
    np.testing.assert_array_equal(d_rule, rule)
    np.testing.assert_array_equal(d_rule2, rule)


@FAST
@given(bits=arrays(np.uint8, (4, 95), elements=st.integers(0, 1)))
def test_nn_round_trip_from_bits(bits: np.ndarray) -> None:
    leads, weights = ch.decode_nn(bits, 5, 6)
    assert (np.tril(np.ones((6, 6), dtype=bool)) & (weights > 0)).sum() == 0
    np.testing.assert_array_equal(ch.encode_nn(leads, weights), bits)


@FAST
@given(bits=arrays(np.uint8, (2, 16504), elements=st.integers(0, 1)))
def test_ca_round_trip_from_bits(bits: np.ndarray) -> None:
    np.testing.assert_array_equal(ch.encode_ca(*ch.decode_ca(bits, 5, 6)), bits)
