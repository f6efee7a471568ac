"""The compiled tables reproduce the Python reference (property tests, random controllers).

``bstool.compile.emulate`` runs the compiled plans with the tables exactly as the PBASIC
templates look them up (packed rule slots, NN sum tables); it must equal
``controller.states(T, failed)`` for every CA model with any dead modules, and for the NN
models with any dead modules no two of which are neighbours on a leg (the bypass wire j-1 -> j+1
covers one dead module; docs/compile.md explains the limit).
"""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bstool.compile import emulate, tables
from bstool.compile.calibration import DEFAULT
from bstool.compile.plan import build_plans
from bstool.controllers import Controller, make_controller, nn_next_state
from bstool.moduleid import ModuleId

SETTINGS = settings(max_examples=25, deadline=None)


def _controller(model: str, seed: int, legs: int, modules: int) -> Controller:
    rng = np.random.default_rng(seed)
    init = rng.integers(0, 16, (legs, modules))
    if model in ("ca1d", "ca2dsing"):
        return make_controller(model, init, rule=rng.integers(0, 16, 4096))
    if model == "ca2ddiff":
        return make_controller(
            model, init, control_rule=rng.integers(0, 16, 4096), leg_rule=rng.integers(0, 16, 4096)
        )
    weights = np.triu(rng.integers(0, 2, (legs, modules, modules)), 1)
    return make_controller(model, init, weights=weights)


@SETTINGS
@given(
    model=st.sampled_from(["ca1d", "ca2dsing", "ca2ddiff"]),
    seed=st.integers(0, 2**32 - 1),
    legs=st.integers(1, 5),
    modules=st.integers(1, 6),
    dead=st.lists(st.tuples(st.integers(0, 4), st.integers(0, 5)), max_size=4),
)
def test_ca_tables_reproduce_reference(
    model: str, seed: int, legs: int, modules: int, dead: list[tuple[int, int]]
) -> None:
    ctrl = _controller(model, seed, legs, modules)
    cells = sorted({(i, j) for i, j in dead if i < legs and j < modules})
    plans = build_plans(ctrl, DEFAULT, 0.5, "0" * 8)
    got = emulate.run(plans, 24, [ModuleId(i, j) for i, j in cells])
    assert np.array_equal(got, ctrl.states(24, cells))


@SETTINGS
@given(
    model=st.sampled_from(["nnsig", "nnsin"]),
    seed=st.integers(0, 2**32 - 1),
    legs=st.integers(1, 5),
    modules=st.integers(1, 6),
    dead=st.lists(st.tuples(st.integers(0, 4), st.integers(0, 5)), max_size=3),
)
def test_nn_tables_reproduce_reference(
    model: str, seed: int, legs: int, modules: int, dead: list[tuple[int, int]]
) -> None:
    ctrl = _controller(model, seed, legs, modules)
    cells: list[tuple[int, int]] = []
    for i, j in sorted(set(dead)):  # the bypass covers dead modules that are not neighbours
        if i < legs and j < modules and (i, j - 1) not in cells:
            cells.append((i, j))
    plans = build_plans(ctrl, DEFAULT, 0.5, "0" * 8)
    got = emulate.run(plans, 40, [ModuleId(i, j) for i, j in cells])
    assert np.array_equal(got, ctrl.states(40, cells))


@SETTINGS
@given(
    model=st.sampled_from(["ca1d", "ca2dsing", "ca2ddiff", "nnsig", "nnsin"]),
    seed=st.integers(0, 2**32 - 1),
    legs=st.integers(1, 5),
    modules=st.integers(1, 6),
    leg=st.integers(0, 4),
    module=st.integers(0, 5),
    at=st.integers(0, 12),
)
def test_a_module_dying_mid_run_matches_failed_at(
    model: str, seed: int, legs: int, modules: int, leg: int, module: int, at: int
) -> None:
    """The compiled plans with one module dying after S^T (its neighbours keep S^T, an NN
    bypass takes over) equal ``controller.states(T, failed_at=...)``."""
    ctrl = _controller(model, seed, legs, modules)
    mid = ModuleId(leg % legs, module % modules)
    plans = build_plans(ctrl, DEFAULT, 0.5, "0" * 8)
    got = emulate.run(plans, 16, die={mid: at})
    assert np.array_equal(got, ctrl.states(16, failed_at={mid: at}))


@SETTINGS
@given(
    model=st.sampled_from(["nnsig", "nnsin"]),
    seed=st.integers(0, 2**32 - 1),
    ups=st.lists(st.integers(0, 15), min_size=5, max_size=5),
)
def test_nn_table_matches_reference_for_any_upstream(model: str, seed: int, ups: list[int]) -> None:
    """Any upstream states, not only reachable ones: the table depends on the sum alone."""
    ctrl = _controller(model, seed, 1, 6)
    mid = ModuleId(0, 5)
    weights = tables.nn_weights_in(ctrl, mid)
    total = sum(s for s, w in zip(ups, weights, strict=True) if w)
    assert tables.nn_table(ctrl, mid)[total] == nn_next_state(model, ups, weights)


def test_nn_table_exhaustive_for_three_inputs() -> None:
    """Every combination of three weighted upstream states (4096) agrees with its sum's entry."""
    for model in ("nnsig", "nnsin"):
        weights = np.zeros((1, 4, 4), dtype=int)
        weights[0, :3, 3] = 1
        ctrl = make_controller(model, [[0, 0, 0, 0]], weights=weights)
        table = tables.nn_table(ctrl, ModuleId(0, 3))
        for ups in itertools.product(range(16), repeat=3):
            assert table[sum(ups)] == nn_next_state(model, list(ups), [1, 1, 1])


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1))
def test_rule_slots_round_trip(seed: int) -> None:
    rule = np.random.default_rng(seed).integers(0, 16, 4096).tolist()
    slots = [tables.rule_slot_bytes(rule, s) for s in range(1, tables.RULE_SLOTS + 1)]
    assert all(len(s) == tables.SLOT_TABLE_BYTES for s in slots)
    for left, me, right in itertools.product(range(16), range(0, 16, 5), range(16)):
        assert tables.rule_lookup(slots, left, me, right) == rule[256 * left + 16 * me + right]


def test_every_single_dead_nn_module_equals_the_failed_reference() -> None:
    """The bypass wire j-1 -> j+1 carries the upstream states past a dead module j."""
    for model in ("nnsig", "nnsin"):
        ctrl = _controller(model, 3, 2, 6)
        plans = build_plans(ctrl, DEFAULT, 0.5, "0" * 8)
        for mid in [ModuleId(i, j) for i in range(2) for j in range(6)]:
            got = emulate.run(plans, 30, [mid])
            assert np.array_equal(got, ctrl.states(30, [(mid.leg, mid.module)])), (model, mid)


def test_two_neighbouring_dead_nn_modules_are_a_documented_difference() -> None:
    """Two dead neighbours j, j+1 hide modules 0..j-1 from j+2 on (docs/compile.md): the modules
    before them and the dead ones still agree with `--fail`."""
    ctrl = _controller("nnsin", 3, 1, 5)
    plans = build_plans(ctrl, DEFAULT, 0.5, "0" * 8)
    got = emulate.run(plans, 20, [ModuleId(0, 1), ModuleId(0, 2)])
    ref = ctrl.states(20, [(0, 1), (0, 2)])
    assert np.array_equal(got[:, :, :3], ref[:, :, :3])
