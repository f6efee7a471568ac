"""``Controller.states(T, failed_at=...)`` and ``bstool states --fail-at``: a module that fails
during the run follows its rule up to S^T0, then holds S^T0 (hand-checked small cases)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bstool.cli import main
from bstool.controllers import load_controller, make_controller, save_controller
from bstool.controllers.reference import nn_next_state
from bstool.errors import InputError

IDX = np.arange(4096)
COPY_LEFT = IDX // 256  # next = L: a ring rotates by one module per transition


def test_ca_ring_module_failing_at_1_holds_and_is_read() -> None:
    ctrl = make_controller("ca1d", [[1, 2, 3]], rule=COPY_LEFT)
    assert ctrl.states(3).tolist() == [[[1, 2, 3]], [[3, 1, 2]], [[2, 3, 1]], [[1, 2, 3]]]
    # 0.1 shows S^1 = 1 and keeps it; 0.2 copies the held 1, then 0.0 copies 0.2's 1
    got = ctrl.states(3, failed_at={"0.1": 1}).tolist()
    assert got == [[[1, 2, 3]], [[3, 1, 2]], [[2, 1, 1]], [[1, 1, 1]]]


def test_failed_at_0_is_failed_and_late_failures_change_nothing() -> None:
    ctrl = make_controller("ca1d", [[1, 2, 3], [4, 5, 6]], rule=COPY_LEFT)
    assert np.array_equal(ctrl.states(5, failed_at={(1, 2): 0}), ctrl.states(5, failed=["1.2"]))
    assert np.array_equal(ctrl.states(5, failed_at={"1.2": 5}), ctrl.states(5))
    assert np.array_equal(ctrl.states(5, failed_at={"1.2": 99}), ctrl.states(5))
    # a module failed from power-up stays failed whatever failed_at says
    assert np.array_equal(
        ctrl.states(5, failed=["0.0"], failed_at={"0.0": 3}), ctrl.states(5, failed=["0.0"])
    )


def test_two_failures_at_different_times() -> None:
    ctrl = make_controller("ca1d", [[1, 2, 3, 4]], rule=COPY_LEFT)
    got = ctrl.states(4, failed_at={"0.0": 1, "0.2": 2})[:, 0].tolist()
    # R^1 = [4,1,2,3]; 0.0 holds 4; R^2 = [4,4,1,2]; 0.2 holds 1; R^3 = [4,4,1,1]; R^4 same
    assert got == [[1, 2, 3, 4], [4, 1, 2, 3], [4, 4, 1, 2], [4, 4, 1, 1], [4, 4, 1, 1]]


def _chain_nn() -> np.ndarray:
    w = np.zeros((1, 4, 4), dtype=int)
    for j in range(1, 4):
        w[0, j - 1, j] = 1  # each module reads only the one before it
    return w


def test_nn_lead_failing_stops_counting_and_freezes_its_leg() -> None:
    ctrl = make_controller("nnsin", [3], weights=_chain_nn())
    free = ctrl.states(6)
    got = ctrl.states(6, failed_at={"0.0": 2})
    assert got[:, 0, 0].tolist() == [3, 4, 5, 5, 5, 5, 5]  # eq. 10 up to S^2, then held
    assert np.array_equal(got[:3], free[:3])
    assert (got[2:] == got[2]).all()  # the whole leg follows its held lead


def test_nn_middle_module_failing_is_read_downstream() -> None:
    w = _chain_nn()
    ctrl = make_controller("nnsig", [7], weights=w)
    free = ctrl.states(6)
    got = ctrl.states(6, failed_at={"0.2": 3})
    assert np.array_equal(got[:4], free[:4])
    assert np.array_equal(got[:, 0, :2], free[:, 0, :2])  # upstream modules unaffected
    held = int(free[3, 0, 2])
    assert got[3:, 0, 2].tolist() == [held] * 4
    after = nn_next_state("nnsig", [0, 0, held], [0, 0, 1])  # eq. 11 reads the held state
    assert got[4:, 0, 3].tolist() == [after] * 3


def test_failed_at_errors() -> None:
    ctrl = make_controller("ca1d", [[1, 2, 3]], rule=COPY_LEFT)
    with pytest.raises(InputError, match="unknown module"):
        ctrl.states(3, failed_at={"0.3": 1})
    with pytest.raises(InputError, match=">= 0"):
        ctrl.states(3, failed_at={"0.1": -1})


def test_states_cli_fail_at(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "c.json"
    save_controller(make_controller("ca1d", [[1, 2, 3]], rule=COPY_LEFT), path)
    assert main(["states", str(path), "-T", "3", "--fail-at", "0.1@1"]) == 0
    frames = json.loads(capsys.readouterr().out)
    assert frames == load_controller(path).states(3, failed_at={"0.1": 1}).tolist()
    for bad, what in (("0.1", "L.M@T"), ("0.1@x", "L.M@T"), ("0.1@-2", "L.M@T"), ("0.7@1", "0.7")):
        assert main(["states", str(path), "--fail-at", bad]) == 2
        err = capsys.readouterr().err
        assert what in err and "Traceback" not in err
    assert main(["states", str(path), "--fail", "0.1", "--fail-at", "0.1@2"]) == 2
    assert "both failed from power-up and failing at 2" in capsys.readouterr().err
