"""The five models on hand-checked cases, and the vectorised path equal to the reference."""

from __future__ import annotations

import math
import zlib

import numpy as np
import pytest

from bstool.controllers.angles import (
    TIE_EPS,
    angle_table,
    angle_to_state,
    angles_to_states,
    state_to_angle,
)
from bstool.controllers.reference import (
    activate,
    ca_neighbours,
    nn_initial_reference,
    nn_next_state,
    rule_index,
    sequence_reference,
)
from bstool.controllers.sequences import ca_sequences, nn_initial, nn_sequences

IDX = np.arange(4096)
COPY_LEFT = IDX // 256  # next = L
COPY_RIGHT = IDX % 16  # next = R
COPY_SELF = (IDX // 16) % 16
LEG = [1, 2, 3, 4, 5, 6]


def lattice() -> np.ndarray:
    """Leg i = 10·i + (1..6) mod 16: every cell distinguishable."""
    return np.array([[(10 * i + s) % 16 for s in LEG] for i in range(5)])


def one(model: str, init: np.ndarray, rules: np.ndarray, t: int = 1, failed=()) -> np.ndarray:
    r = rules[None]
    return ca_sequences(model, init[None], r, t, failed)[0].astype(int)


def test_paper_neighbour_examples() -> None:
    # §3.2: for leg 0 with 6 modules, S00's neighbours are S05 and S01; S05's are S04 and S00.
    assert ca_neighbours("ca1d", 5, 6, 0, 0) == ((0, 5), (0, 1))
    assert ca_neighbours("ca1d", 5, 6, 0, 5) == ((0, 4), (0, 0))
    # eq. 7–8: leads see the leads of legs i±1; the last module's right is its own lead.
    assert ca_neighbours("ca2dsing", 5, 6, 0, 0) == ((4, 0), (1, 0))
    assert ca_neighbours("ca2dsing", 5, 6, 4, 0) == ((3, 0), (0, 0))
    assert ca_neighbours("ca2dsing", 5, 6, 2, 5) == ((2, 4), (2, 0))
    assert ca_neighbours("ca2dsing", 5, 6, 2, 1) == ((2, 0), (2, 2))
    assert rule_index(1, 2, 3) == 256 + 32 + 3


def test_ca1d_ring_and_synchronous_update() -> None:
    init = lattice()
    left = one("ca1d", init, COPY_LEFT[None])[1]
    right = one("ca1d", init, COPY_RIGHT[None])[1]
    # A synchronous copy-left rotates each ring; a sequential update would smear one value.
    assert left[0].tolist() == [6, 1, 2, 3, 4, 5]
    assert right[0].tolist() == [2, 3, 4, 5, 6, 1]
    np.testing.assert_array_equal(left, np.roll(init, 1, axis=1))
    np.testing.assert_array_equal(right, np.roll(init, -1, axis=1))
    np.testing.assert_array_equal(one("ca1d", init, COPY_SELF[None], t=3)[3], init)


def test_ca2dsing_boundaries() -> None:
    init = lattice()
    left = one("ca2dsing", init, COPY_LEFT[None])[1]
    right = one("ca2dsing", init, COPY_RIGHT[None])[1]
    for i in range(5):
        # lead ← lead of leg i−1; module j ← module j−1 of the same leg
        assert left[i].tolist() == [init[(i - 1) % 5, 0], *init[i, :5]]
        # lead ← lead of leg i+1; module j ← j+1; the last module ← its own leg's lead
        assert right[i].tolist() == [init[(i + 1) % 5, 0], *init[i, 2:], init[i, 0]]
    assert left[0, 0] == init[4, 0] and right[4, 0] == init[0, 0]


def test_ca2ddiff_uses_control_rule_on_leads_only() -> None:
    init = lattice()
    seven = np.full(4096, 7)
    out = one("ca2ddiff", init, np.stack([COPY_LEFT, seven]))[1]
    assert out[:, 0].tolist() == np.roll(init[:, 0], 1).tolist()
    assert (out[:, 1:] == 7).all()


def test_rule_index_order_matches_table1() -> None:
    rule = np.zeros(4096, dtype=int)
    init = np.zeros((5, 6), dtype=int)
    init[0] = [3, 1, 2, 0, 0, 0]  # cell (0,1) sees L=3, S=1, R=2
    rule[256 * 3 + 16 * 1 + 2] = 9
    assert one("ca1d", init, rule[None])[1, 0, 1] == 9


def test_failed_lead_is_frozen_and_read_by_neighbours() -> None:
    init = lattice()
    seq = one("ca2dsing", init, COPY_LEFT[None], t=4, failed=[(1, 0)])
    assert (seq[:, 1, 0] == init[1, 0]).all()
    # leg 2's lead reads the frozen lead of leg 1 every step; module (1,1) reads it too
    assert (seq[1:, 2, 0] == init[1, 0]).all()
    assert (seq[1:, 1, 1] == init[1, 0]).all()
    ref = sequence_reference("ca2dsing", init.tolist(), 4, rules=[COPY_LEFT], failed=[(1, 0)])
    np.testing.assert_array_equal(seq, ref)


def test_angles() -> None:
    assert state_to_angle(0) == -math.pi / 3 and state_to_angle(15) == pytest.approx(math.pi / 3)
    assert angle_table().tolist() == [state_to_angle(s) for s in range(16)]
    step = (2 * math.pi / 3) / 15
    for s in range(15):
        mid = state_to_angle(s) + step / 2
        assert angle_to_state(mid) == s + 1  # exact tie → higher
        assert angle_to_state(mid - TIE_EPS / 2) == s + 1  # noise near a tie is a tie
        assert angle_to_state(mid - 10 * TIE_EPS) == s
        assert angle_to_state(state_to_angle(s)) == s
    assert angle_to_state(0.0) == 8  # halfway between 7 and 8
    assert angle_to_state(-5.0) == 0 and angle_to_state(5.0) == 15
    phis = np.linspace(-1.2, 1.2, 2001)
    assert angles_to_states(phis).tolist() == [angle_to_state(p) for p in phis]


def test_angles_match_robot() -> None:
    from bstool.robot import state_to_angle as robot_angle

    assert [robot_angle(s) for s in range(16)] == [state_to_angle(s) for s in range(16)]


def test_nn_next_state_hand_checked() -> None:
    # nnsin, one input from a lead in state 0: π/3·sin(−π/3) = −0.9069 → 1.0048 steps → 1
    assert nn_next_state("nnsin", [0], [1]) == 1
    # nnsig: 2π/(3(1+e^{π/3})) − π/3 = −0.5031 → 3.896 steps → 4
    assert nn_next_state("nnsig", [0], [1]) == 4
    assert nn_next_state("nnsig", [15], [1]) == 11
    # no input (X = 0) gives θ = 0: the exact tie between 7 and 8 rounds up, both activations
    assert nn_next_state("nnsin", [5, 9], [0, 0]) == 8
    assert nn_next_state("nnsig", [], []) == 8
    assert activate("nnsin", 0.0) == 0.0 and activate("nnsig", 0.0) == 0.0


def test_nn_leg_cycles_and_propagates() -> None:
    w = np.zeros((5, 6, 6), dtype=int)
    w[:, 0, 1] = 1  # module 1 follows the lead; the rest get X = 0 → 8
    leads = np.array([0, 3, 6, 9, 15])
    r0 = nn_initial("nnsin", leads[None], w[None])[0]
    assert r0[0].tolist() == [0, 1, 8, 8, 8, 8]
    assert r0.tolist() == nn_initial_reference("nnsin", leads.tolist(), w.tolist())
    seq = nn_sequences("nnsin", leads[None], w[None], 17)[0]
    assert seq[:, 4, 0].tolist() == [15, *range(16), 0]  # eq. 10: lead cycles mod 16
    assert seq[1, 0].tolist() == [1, nn_next_state("nnsin", [1], [1]), 8, 8, 8, 8]
    np.testing.assert_array_equal(seq[16], seq[0])  # period k


def test_nn_failures() -> None:
    rng = np.random.default_rng(3)
    w = np.triu(rng.integers(0, 2, (5, 6, 6)), 1)
    w[:, :, 5] = 0
    w[:, 2, 5] = 1  # module 5 reads only module 2
    leads = rng.integers(0, 16, 5)
    seq = nn_sequences("nnsig", leads[None], w[None], 10, [(0, 0), (1, 2)])[0]
    assert (seq[:, 0, :] == seq[0, 0, :]).all()  # failed lead: whole leg frozen
    assert (seq[:, 1, 2] == seq[0, 1, 2]).all()  # failed module keeps R^0
    assert (seq[:, 1, 5] == nn_next_state("nnsig", [0, 0, int(seq[0, 1, 2])], [0, 0, 1])).all()
    assert len(set(seq[:, 1, 0].tolist())) == 11  # its lead still cycles


@pytest.mark.parametrize("model", ["ca1d", "ca2dsing", "ca2ddiff", "nnsig", "nnsin"])
@pytest.mark.parametrize("shape", [(5, 6), (3, 4), (1, 2), (2, 1)])
def test_vectorised_equals_reference(model: str, shape: tuple[int, int]) -> None:
    n, m = shape
    rng = np.random.default_rng(zlib.crc32(f"{model}{shape}".encode()))
    p, t = 6, 25
    for failed in ([], [(0, 0)], [(n - 1, m - 1), (0, min(1, m - 1))]):
        if model.startswith("nn"):
            leads = rng.integers(0, 16, (p, n))
            w = np.triu(rng.integers(0, 2, (p, n, m, m)), 1)
            seq = nn_sequences(model, leads, w, t, failed)
            for q in range(p):
                init = [[int(s)] + [0] * (m - 1) for s in leads[q]]
                ref = sequence_reference(model, init, t, weights=w[q].tolist(), failed=failed)
                np.testing.assert_array_equal(seq[q], ref)
        else:
            init = rng.integers(0, 16, (p, n, m))
            # small-alphabet rules so runs revisit entries and cycles form
            rules = rng.integers(0, 4, (p, 2 if model == "ca2ddiff" else 1, 4096))
            seq = ca_sequences(
                model, init, rules if model == "ca2ddiff" else rules[:, 0], t, failed
            )
            for q in range(p):
                ref = sequence_reference(
                    model, init[q].tolist(), t, rules=rules[q].tolist(), failed=failed
                )
                np.testing.assert_array_equal(seq[q], ref)
        assert seq.shape == (p, t + 1, n, m) and seq.dtype == np.uint8
