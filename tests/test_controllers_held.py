"""``Controller.states(T, failed_at=..., held=...)`` and ``bstool states --held-by``: a failure
per link (CA), each reader N of the failed module c reading S_c^(T_N) while c is dead
(docs/controllers.md "Per-link failure"). A hand-checked case, the errors, and properties: the
vectorised path equals the per-cell reference, and all T_N = T0 is plain ``failed_at``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bstool.cli import main
from bstool.controllers import CA_MODELS, Controller, make_controller, save_controller
from bstool.controllers.reference import ca_neighbours, sequence_reference
from bstool.errors import InputError

IDX = np.arange(4096)
COPY_LEFT = IDX // 256  # next = L


def test_a_reader_holding_an_earlier_state_reads_it_until_the_rejoin() -> None:
    ctrl = make_controller("ca1d", [[1, 2, 3]], rule=COPY_LEFT)
    # 0.1 fails at 1 (holds S^1 = 1); 0.2 (whose left is 0.1) holds S^0 = 2 of it
    got = ctrl.states(4, failed_at={"0.1": 1}, held={"0.1": {"0.2": 0}}).tolist()
    assert got == [[[1, 2, 3]], [[3, 1, 2]], [[2, 1, 2]], [[2, 1, 2]], [[2, 1, 2]]]
    plain = ctrl.states(4, failed_at={"0.1": 1}).tolist()
    assert plain[2] == [[2, 1, 1]]
    # back at 3: from R^3 -> R^4 on 0.2 reads 0.1's own state again
    back = ctrl.states(4, failed_at={"0.1": 1}, rejoin={"0.1": 3}, held={"0.1": {"0.2": 0}})
    assert back.tolist()[3:] == [[[2, 1, 2]], [[2, 2, 1]]]


def test_a_per_link_rejoin_reads_the_held_state_until_its_own_end() -> None:
    ctrl = make_controller("ca1d", [[1, 2, 3]], rule=COPY_LEFT)
    held = {"0.1": {"0.2": 0}}
    back = ctrl.states(5, failed_at={"0.1": 1}, rejoin={"0.1": 3}, held=held)
    # T2_N = T2 is the plain per-link failure
    until = {"0.1": {"0.2": (0, 3)}}
    same = ctrl.states(5, failed_at={"0.1": 1}, rejoin={"0.1": 3}, held=until)
    np.testing.assert_array_equal(same, back)
    # T2_N = 4: 0.2 still reads 0.1's S^0 = 2 in R^3 -> R^4, and 0.1's own state from R^4 on
    late = ctrl.states(5, failed_at={"0.1": 1}, rejoin={"0.1": 3}, held={"0.1": {"0.2": (0, 4)}})
    assert late.tolist()[:4] == back.tolist()[:4]
    assert late.tolist()[4] == [[2, 2, 2]]  # 0.2 copied S^0 = 2 again, 0.1 its left 2
    assert late.tolist()[5] == [[2, 2, 2]]
    assert back.tolist()[4] == [[2, 2, 1]]


def test_a_rejoin_with_an_older_state_shows_it_until_the_rejoin_and_resumes_from_it() -> None:
    ctrl = make_controller("ca1d", [[1, 2, 3]], rule=COPY_LEFT)
    # healthy: R^0..R^2 = [1,2,3], [3,1,2], [2,3,1]; 0.1 fails at 2 (S^2 = 3) and rejoins at
    # 4 with S^1 = 1: R^3 = [1,1,3] (0.2 copied the S^2 = 3 shown in R^2), R^4 = [3,1,1] (held
    # S^1), then the rule again: R^5 = [1,3,1], R^6 = [1,1,3]
    got = ctrl.states(6, failed_at={"0.1": 2}, rejoin={"0.1": 4}, rejoin_with={"0.1": 1})
    assert got.tolist() == [
        [[1, 2, 3]], [[3, 1, 2]], [[2, 3, 1]], [[1, 1, 3]], [[3, 1, 1]], [[1, 3, 1]], [[1, 1, 3]]
    ]  # fmt: skip
    with pytest.raises(InputError, match="never rejoins"):
        ctrl.states(6, failed_at={"0.1": 2}, rejoin_with={"0.1": 1})
    with pytest.raises(InputError, match="T_R < T0"):
        ctrl.states(6, failed_at={"0.1": 2}, rejoin={"0.1": 4}, rejoin_with={"0.1": 2})
    with pytest.raises(InputError, match="T_R < T0"):
        ctrl.states(6, failed_at={"0.1": 2}, rejoin={"0.1": 2}, rejoin_with={"0.1": 1})
    w = np.triu(np.ones((1, 3, 3), dtype=int), 1)
    nn = make_controller("nnsin", [3], weights=w)
    with pytest.raises(InputError, match="CA models only"):
        nn.states(6, failed_at={"0.1": 2}, rejoin={"0.1": 4}, rejoin_with={"0.1": 1})


def test_held_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ctrl = make_controller("ca2dsing", [[1, 2, 3], [4, 5, 6]], rule=COPY_LEFT)
    with pytest.raises(InputError, match="never fails"):
        ctrl.states(3, held={"0.0": {"1.0": 0}})
    with pytest.raises(InputError, match="does not read"):
        ctrl.states(3, failed_at={"0.0": 2}, held={"0.0": {"1.1": 1}})
    with pytest.raises(InputError, match=r"must be 0\.\.2"):
        ctrl.states(3, failed_at={"0.0": 2}, held={"0.0": {"1.0": 3}})
    w = np.triu(np.ones((1, 3, 3), dtype=int), 1)
    nn = make_controller("nnsin", [3], weights=w)
    with pytest.raises(InputError, match="CA models only"):
        nn.states(3, failed_at={"0.0": 2}, held={"0.0": {"0.1": 1}})
    path = tmp_path / "c.json"
    save_controller(ctrl, path)
    assert main(["states", str(path), "--fail-at", "0.0@2", "--held-by", "1.0=0.0"]) == 2
    err = capsys.readouterr().err
    assert "expected N=L.M@T" in err and "Traceback" not in err
    assert main(["states", str(path), "--fail-at", "0.0@2", "--held-by", "1.0=0.0@1..x"]) == 2
    err = capsys.readouterr().err
    assert "N=L.M@T..T2" in err and "Traceback" not in err
    with pytest.raises(InputError, match="must be >= 1"):
        ctrl.states(3, failed_at={"0.0": 2}, held={"0.0": {"1.0": (1, 0)}})
    assert main(["states", str(path), "--fail-at", "0.0@2", "--rejoin-with", "0.0"]) == 2
    err = capsys.readouterr().err
    assert "bad --rejoin-with" in err and "Traceback" not in err


def test_states_cli_held_by(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "c.json"
    ctrl = make_controller("ca1d", [[1, 2, 3]], rule=COPY_LEFT)
    save_controller(ctrl, path)
    args = ["-T", "5", "--fail-at", "0.1@2", "--held-by", "0.2=0.1@1", "--rejoin", "0.1@4"]
    assert main(["states", str(path), *args]) == 0
    want = ctrl.states(5, failed_at={"0.1": 2}, rejoin={"0.1": 4}, held={"0.1": {"0.2": 1}})
    assert json.loads(capsys.readouterr().out) == want.tolist()
    args = ["-T", "5", "--fail-at", "0.1@2", "--held-by", "0.2=0.1@1..5", "--rejoin", "0.1@4"]
    assert main(["states", str(path), *args, "--rejoin-with", "0.1@1"]) == 0
    want = ctrl.states(
        5, failed_at={"0.1": 2}, rejoin={"0.1": 4}, held={"0.1": {"0.2": (1, 5)}},
        rejoin_with={"0.1": 1},
    )  # fmt: skip
    assert json.loads(capsys.readouterr().out) == want.tolist()


def _ca(model: str, seed: int, n: int = 3, m: int = 4) -> Controller:
    rng = np.random.default_rng(seed)
    rules = rng.integers(0, 4, (2, 4096))  # small alphabet: revisits and cycles
    kw = {"control_rule": rules[0], "leg_rule": rules[1]} if model == "ca2ddiff" else {}
    return make_controller(
        model, rng.integers(0, 16, (n, m)), rule=rules[0] if not kw else None, **kw
    )


def _readers(model: str, cell: tuple[int, int], n: int = 3, m: int = 4) -> list[tuple[int, int]]:
    return [(i, j) for i in range(n) for j in range(m) if cell in ca_neighbours(model, n, m, i, j)]


FAILURES = st.lists(
    st.tuples(st.integers(0, 2), st.integers(0, 3), st.integers(0, 6), st.integers(0, 4)),
    min_size=1,
    max_size=3,
)


@settings(max_examples=40, deadline=None)
@given(model=st.sampled_from(CA_MODELS), seed=st.integers(0, 2**16), events=FAILURES,
       data=st.data())  # fmt: skip
def test_vectorised_held_equals_the_reference(
    model: str, seed: int, events: list[tuple[int, int, int, int]], data: st.DataObject
) -> None:
    """Random per-link failures and returns on a 3 × 4 robot: ``Controller.states`` (piecewise,
    vectorised) equals ``sequence_reference`` (one cell at a time)."""
    ctrl, T = _ca(model, seed), 8
    fail = {(i, j): t0 for i, j, t0, _ in events}
    back = {(i, j): fail[i, j] + d for i, j, _, d in events if d}
    held: dict[tuple[int, int], dict[tuple[int, int], int | tuple[int, int]]] = {}
    for c, t0 in fail.items():
        readers = [r for r in _readers(model, c) if data.draw(st.booleans())]
        held[c] = {}
        for r in readers:
            tn = data.draw(st.integers(0, t0))
            per_link = data.draw(st.booleans())  # a rejoin per link: until T2_N
            held[c][r] = (tn, data.draw(st.integers(tn, T + 1))) if per_link else tn
    older = {
        c: data.draw(st.integers(0, fail[c] - 1))
        for c in back
        if 0 < fail[c] < back[c] and data.draw(st.booleans())
    }
    ref = sequence_reference(
        model, ctrl.initial_states.tolist(), T, rules=ctrl.rules().tolist(), failed_at=fail,
        rejoin=back, held=held, rejoin_with=older,
    )  # fmt: skip
    got = ctrl.states(T, failed_at=fail, rejoin=back, held=held, rejoin_with=older)
    np.testing.assert_array_equal(got, ref)


@settings(max_examples=40, deadline=None)
@given(model=st.sampled_from(CA_MODELS), seed=st.integers(0, 2**16), events=FAILURES)
def test_every_reader_at_the_failure_is_plain_failed_at(
    model: str, seed: int, events: list[tuple[int, int, int, int]]
) -> None:
    """All T_N = T0 is ``failed_at`` (with or without a rejoin); without one it is the twin's
    ``--die L.M@T0`` reference."""
    ctrl, T = _ca(model, seed), 8
    fail = {(i, j): t0 for i, j, t0, _ in events}
    back = {(i, j): fail[i, j] + d for i, j, _, d in events if d}
    held = {c: dict.fromkeys(_readers(model, c), t0) for c, t0 in fail.items()}
    plain = ctrl.states(T, failed_at=fail, rejoin=back)
    np.testing.assert_array_equal(ctrl.states(T, failed_at=fail, rejoin=back, held=held), plain)
    die = ctrl.states(T, failed_at=fail)
    np.testing.assert_array_equal(ctrl.states(T, failed_at=fail, held=held), die)
