"""The controller file (bstool.controller/1): round trip, hash, and every bad input's error."""

from __future__ import annotations

import copy
import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bstool.controllers import (
    Controller,
    controller_hash,
    from_json,
    load_controller,
    make_controller,
    save_controller,
)
from bstool.controllers.reference import nn_initial_reference, sequence_reference
from bstool.errors import InputError


def sample(model: str, seed: int = 0) -> Controller:
    rng = np.random.default_rng(seed)
    init = rng.integers(0, 16, (5, 6))
    if model.startswith("nn"):
        w = np.triu(rng.integers(0, 2, (5, 6, 6)), 1)
        return make_controller(model, init, weights=w, fitness=0.5, max_trans=30, seed=seed)
    rule = rng.integers(0, 16, 4096)
    if model == "ca2ddiff":
        return make_controller(
            model, init, control_rule=rule, leg_rule=rule[::-1], fitness=1.0, seed=seed
        )
    return make_controller(model, init, rule=rule, ga={"pop": 10}, seed=seed)


MODELS = ["ca1d", "ca2dsing", "ca2ddiff", "nnsig", "nnsin"]


@pytest.mark.parametrize("model", MODELS)
def test_save_load_round_trip(model: str, tmp_path: Path) -> None:
    ctrl = sample(model)
    path = tmp_path / "best.json"
    save_controller(ctrl, path)
    back = load_controller(path)
    assert back.to_json() == ctrl.to_json()
    assert json.loads(path.read_text()) == ctrl.to_json()
    assert list(ctrl.to_json())[:6] == [
        "format",
        "model",
        "legs",
        "modules",
        "states",
        "initial_states",
    ]
    np.testing.assert_array_equal(
        back.states(12, ["1.0", "3.4"]), ctrl.states(12, [(1, 0), (3, 4)])
    )
    frames = ctrl.states(12, ["1.0"])
    assert frames.shape == (13, 5, 6) and frames.dtype == np.int64
    obj = ctrl.to_json()
    rules = [obj[k] for k in ("rule", "control_rule", "leg_rule") if k in obj]
    ref = sequence_reference(
        model,
        obj["initial_states"],
        12,
        rules=rules,
        weights=obj.get("weights", ()),
        failed=[(1, 0)],
    )
    np.testing.assert_array_equal(frames, ref)


def test_hash_is_canonical_sha256() -> None:
    ctrl = sample("nnsin")
    obj = ctrl.to_json()
    text = json.dumps(obj, sort_keys=True, separators=(",", ":"))
    assert controller_hash(obj) == hashlib.sha256(text.encode()).hexdigest() == ctrl.hash()
    shuffled = dict(reversed(list(obj.items())))
    assert controller_hash(shuffled) == controller_hash(ctrl)
    assert controller_hash(sample("nnsin", 1)) != controller_hash(ctrl)


def test_nn_initial_states_are_propagated() -> None:
    ctrl = sample("nnsig")
    assert ctrl.weights is not None
    r0 = nn_initial_reference("nnsig", ctrl.initial_states[:, 0].tolist(), ctrl.weights.tolist())
    assert ctrl.initial_states.tolist() == r0
    np.testing.assert_array_equal(ctrl.states(0)[0], r0)


def broken(model: str, change: Any) -> dict[str, Any]:
    obj = copy.deepcopy(sample(model).to_json())
    change(obj)
    return obj


def _set(path: tuple[Any, ...], value: Any) -> Any:
    def change(obj: dict[str, Any]) -> None:
        target = obj
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value

    return change


def _del(key: str) -> Any:
    return lambda obj: obj.pop(key)


BAD: list[tuple[str, Any, str]] = [
    ("ca1d", _set(("format",), "bstool.controller/2"), r"field 'format': expected 'bstool"),
    ("ca1d", _set(("model",), "ca3d"), r"field 'model': expected one of ca1d, .*got 'ca3d'"),
    ("ca1d", _del("rule"), r"field 'rule': missing"),
    ("ca1d", _del("initial_states"), r"field 'initial_states': missing"),
    ("ca1d", _set(("legs",), 0), r"field 'legs': expected an integer 1..64, got the number 0"),
    ("ca1d", _set(("legs",), True), r"field 'legs': expected an integer 1..64, got a boolean"),
    ("ca1d", _set(("modules",), "6"), r"field 'modules': expected an integer .*string '6'"),
    ("ca1d", _set(("states",), 8), r"field 'states': expected the integer 16, got the number 8"),
    ("ca1d", _set(("initial_states",), [[0] * 6] * 4), r"'initial_states': expected a list of 5"),
    ("ca1d", _set(("initial_states", 2), [0] * 5), r"'initial_states\[2\]': expected a list of 6"),
    ("ca1d", _set(("initial_states", 2, 3), 16), r"'initial_states\[2\]\[3\]': expected an int"),
    ("ca1d", _set(("initial_states", 2, 3), 1.0), r"'initial_states\[2\]\[3\]': .*number 1.0"),
    ("ca1d", _set(("rule",), [0] * 4095), r"field 'rule': expected a list of 4096 ints"),
    ("ca1d", _set(("rule", 17), -1), r"field 'rule\[17\]': expected an integer 0..15"),
    ("ca1d", _set(("weights",), []), r"field 'weights': unknown field for model ca1d \(it bel"),
    ("ca1d", _set(("rules",), []), r"field 'rules': unknown field for model ca1d"),
    ("ca2ddiff", _del("leg_rule"), r"field 'leg_rule': missing"),
    ("ca2ddiff", _set(("rule",), [0] * 4096), r"field 'rule': unknown field .*ca1d/ca2dsing"),
    ("nnsin", _set(("weights", 1, 2, 3), 2), r"'weights\[1\]\[2\]\[3\]': expected an integer 0..1"),
    ("nnsin", _set(("weights", 1, 3, 2), 1), r"'weights\[1\]\[3\]\[2\]': expected 0: only"),
    ("nnsin", _set(("weights", 1, 3, 3), 1), r"'weights\[1\]\[3\]\[3\]': expected 0"),
    ("nnsin", _set(("weights", 4), [[0] * 6] * 5), r"'weights\[4\]': expected a list of 6"),
    ("nnsig", _set(("fitness",), "far"), r"field 'fitness': expected a number or null"),
    ("nnsig", _set(("max_trans",), -1), r"field 'max_trans': expected an integer 0.."),
    ("nnsig", _set(("ga",), [1]), r"field 'ga': expected an object or null, got a list of 1"),
    ("nnsig", _set(("seed",), "x"), r"field 'seed': expected an integer"),
    ("nnsig", _set(("bstool_version",), 1), r"field 'bstool_version': expected a string"),
]


@pytest.mark.parametrize(("model", "change", "message"), BAD)
def test_bad_fields(model: str, change: Any, message: str) -> None:
    with pytest.raises(InputError, match=message) as info:
        from_json(broken(model, change), "x.json")
    assert str(info.value).startswith("x.json: field '")
    assert info.value.hint


def test_nn_non_lead_must_equal_propagated_r0() -> None:
    obj = sample("nnsin").to_json()
    good = obj["initial_states"][3][4]
    obj["initial_states"][3][4] = (good + 1) % 16
    with pytest.raises(InputError, match=rf"'initial_states\[3\]\[4\]': expected {good}, the st"):
        from_json(obj, "x.json")


def test_not_an_object_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="top level: expected a JSON object, got a list of 0"):
        from_json([], "x.json")
    with pytest.raises(InputError, match="controller file not found"):
        load_controller(tmp_path / "nope.json")


def test_failed_modules_out_of_range() -> None:
    ctrl = sample("ca1d")
    with pytest.raises(InputError, match=r"leg 5 is not in 0\.\.4"):
        ctrl.states(3, ["5.0"])
    with pytest.raises(InputError, match=r"unknown module 0\.6"):
        ctrl.states(3, [(0, 6)])
    with pytest.raises(InputError, match="transitions must be 0 or more"):
        ctrl.states(-1)
