"""``Controller.states(T, failed_at=..., rejoin=...)`` and ``bstool states --rejoin``: a failed
module that comes back holds its state through R^T2 and follows its rule again from R^(T2+1),
starting from the state it held (docs/controllers.md "Rejoin"). Hand-checked cases, and a
property: the vectorised paths equal the plain per-module reference for every model."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bstool.cli import main
from bstool.controllers import load_controller, make_controller, save_controller
from bstool.controllers.reference import MODELS, NN_MODELS, sequence_reference
from bstool.errors import InputError

IDX = np.arange(4096)
COPY_LEFT = IDX // 256  # next = L: a ring rotates by one module per transition


def test_ca_module_rejoining_follows_its_rule_from_the_held_state() -> None:
    ctrl = make_controller("ca1d", [[1, 2, 3]], rule=COPY_LEFT)
    # 0.1 holds S^1 = 1 in R^2; from R^3 on it copies its left neighbour again
    got = ctrl.states(4, failed_at={"0.1": 1}, rejoin={"0.1": 2}).tolist()
    assert got == [[[1, 2, 3]], [[3, 1, 2]], [[2, 1, 1]], [[1, 2, 1]], [[1, 1, 2]]]


def test_rejoin_at_the_failure_is_healthy_and_past_the_end_is_failed_at() -> None:
    ctrl = make_controller("ca2dsing", [[1, 2, 3], [4, 5, 6]], rule=COPY_LEFT)
    free = ctrl.states(6)
    assert np.array_equal(ctrl.states(6, failed_at={"1.0": 2}, rejoin={"1.0": 2}), free)
    dead = ctrl.states(6, failed_at={"1.0": 2})
    assert np.array_equal(ctrl.states(6, failed_at={"1.0": 2}, rejoin={"1.0": 6}), dead)
    assert np.array_equal(ctrl.states(6, failed_at={"1.0": 2}, rejoin={"1.0": 60}), dead)
    # a module failed from power-up may come back too
    got = ctrl.states(6, failed=["1.0"], rejoin={"1.0": 3})
    assert np.array_equal(got[:4], ctrl.states(3, failed=["1.0"]))


def test_nn_lead_rejoining_counts_on_from_its_held_state() -> None:
    w = np.zeros((1, 4, 4), dtype=int)
    for j in range(1, 4):
        w[0, j - 1, j] = 1
    ctrl = make_controller("nnsin", [3], weights=w)
    got = ctrl.states(7, failed_at={"0.0": 2}, rejoin={"0.0": 4})
    assert got[:, 0, 0].tolist() == [3, 4, 5, 5, 5, 6, 7, 8]  # eq. 10 again after R^4
    free = ctrl.states(3)
    # from R^5 on the leg is the healthy leg for the lead's state (eq. 11 reads only upstream)
    for t in range(5, 8):
        lead = int(got[t, 0, 0])
        row = next(r for r in ctrl.states(16) if int(r[0, 0]) == lead)
        assert got[t].tolist() == row.tolist()
    assert np.array_equal(got[:3], free[:3])


def test_rejoin_errors() -> None:
    ctrl = make_controller("ca1d", [[1, 2, 3]], rule=COPY_LEFT)
    with pytest.raises(InputError, match="never fails"):
        ctrl.states(3, rejoin={"0.1": 1})
    with pytest.raises(InputError, match="before it fails"):
        ctrl.states(3, failed_at={"0.1": 2}, rejoin={"0.1": 1})


def test_states_cli_rejoin(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "c.json"
    save_controller(make_controller("ca1d", [[1, 2, 3]], rule=COPY_LEFT), path)
    assert main(["states", str(path), "-T", "4", "--fail-at", "0.1@1", "--rejoin", "0.1@2"]) == 0
    frames = json.loads(capsys.readouterr().out)
    want = load_controller(path).states(4, failed_at={"0.1": 1}, rejoin={"0.1": 2})
    assert frames == want.tolist()
    assert main(["states", str(path), "--rejoin", "0.1@x"]) == 2
    err = capsys.readouterr().err
    assert "comes back at" in err and "Traceback" not in err
    assert main(["states", str(path), "--rejoin", "0.1@2"]) == 2
    assert "never fails" in capsys.readouterr().err


@settings(max_examples=40, deadline=None)
@given(
    model=st.sampled_from(MODELS),
    seed=st.integers(0, 2**16),
    events=st.lists(
        st.tuples(st.integers(0, 2), st.integers(0, 3), st.integers(0, 6), st.integers(0, 4)),
        max_size=3,
    ),
)
def test_vectorised_rejoin_equals_the_reference(
    model: str, seed: int, events: list[tuple[int, int, int, int]]
) -> None:
    """Random failures (T0) and returns (T0 + d) on a 3 × 4 robot: ``Controller.states`` (the
    vectorised paths, piecewise) equals ``sequence_reference`` (one cell at a time)."""
    rng = np.random.default_rng(seed)
    n, m, T = 3, 4, 8
    fail = {(i, j): t0 for i, j, t0, _ in events}
    back = {(i, j): fail[i, j] + d for i, j, _, d in events if d}
    if model in NN_MODELS:
        w = np.triu(rng.integers(0, 2, (n, m, m)), 1)
        ctrl = make_controller(model, rng.integers(0, 16, n), weights=w)
        ref = sequence_reference(
            model, ctrl.initial_states.tolist(), T, weights=w.tolist(), failed_at=fail,
            rejoin=back,
        )  # fmt: skip
    else:
        rules = rng.integers(0, 4, (2, 4096))  # small alphabet: revisits and cycles
        kw = (
            {"control_rule": rules[0], "leg_rule": rules[1]}
            if model == "ca2ddiff"
            else {"rule": rules[0]}
        )
        ctrl = make_controller(model, rng.integers(0, 16, (n, m)), **kw)
        ref = sequence_reference(
            model, ctrl.initial_states.tolist(), T, rules=ctrl.rules().tolist(), failed_at=fail,
            rejoin=back,
        )  # fmt: skip
    np.testing.assert_array_equal(ctrl.states(T, failed_at=fail, rejoin=back), ref)
