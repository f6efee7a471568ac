"""The bstool.timing/1 format (bstool/timingfile.py): round trip, defaults, precise errors."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bstool import timingfile as tf
from bstool.errors import InputError


def _coeff(lo: float, hi: float) -> st.SearchStrategy[tf.Coefficient]:
    value = st.floats(lo, hi, allow_nan=False)
    sd = st.none() | st.floats(0, 10, allow_nan=False)
    return st.builds(tf.Coefficient, value, sd)


models = st.builds(
    tf.TimingModel,
    base_us=_coeff(0, 500),
    per_bit_us=_coeff(0, 50),
    run_us=_coeff(0, 5000),
    pause_unit_ms=_coeff(0.8, 1.2),
    pulsout_unit_us=_coeff(0.64, 0.96),
    serin_unit_ms=_coeff(0.32, 0.48),
    serout_item_us=_coeff(500, 5000),
    instruction_time_ratio=_coeff(0.2, 5),
    source=st.sampled_from(["default", "probe /dev/ttyUSB0"]),
    created=st.none() | st.just("2026-12-01T20:00:00Z"),
    measurements=st.just({}) | st.just({"repeats": 3, "kinds": {"empty": {"n": [1, 2]}}}),
)


@settings(max_examples=60, deadline=None)
@given(models)
def test_round_trip(model: tf.TimingModel) -> None:
    back = tf.from_json(json.loads(json.dumps(tf.to_json(model))), "t.json")
    assert back == model
    assert back.measurements == model.measurements


def test_dump_load_and_defaults(tmp_path: Path) -> None:
    path = tmp_path / "sub" / "stamp-timing.json"
    tf.dump(tf.DEFAULT, path)
    assert tf.load(path) == tf.DEFAULT
    assert not tf.DEFAULT.measured
    assert tf.DEFAULT.statement_us(tf.TYPICAL_BITS) == pytest.approx(100.0)
    assert [p.name for p in path.parent.iterdir()] == ["stamp-timing.json"]  # no temp files


def test_default_is_the_twin_and_compile_estimate() -> None:
    from bstool.compile import timing as ct
    from hil_mock.stamp import timing as ht

    d = tf.DEFAULT
    assert d.base_us.value * 1000 == ht.BASE_NS and d.per_bit_us.value * 1000 == ht.PER_BIT_NS
    assert d.run_us.value * 1000 == ht.RUN_NS == ct.DEFAULT.run_ms * 1e6
    assert d.pause_unit_ms.value * 1e6 == ht.PAUSE_UNIT_NS
    assert d.pulsout_unit_us.value * 1000 == ht.PULSOUT_UNIT_NS
    assert d.serin_unit_ms.value * 1e6 == ht.SERIN_TIMEOUT_UNIT_NS == ct.DEFAULT.serin_unit_ms * 1e6
    assert d.serout_item_us.value * 1000 == ht.byte_ns(240)
    assert ct.DEFAULT.model == d and ct.DEFAULT.stmt_ms == ct.STMT_MS


def _good() -> dict[str, Any]:
    return tf.to_json(replace(tf.DEFAULT, source="probe x"))


def _set(obj: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    *head, last = path.split(".")
    node = obj
    for key in head:
        node = node[key]
    if value is KeyError:
        del node[last]
    else:
        node[last] = value
    return obj


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        ("format", "bstool.build/1", "not a timing file"),
        ("coefficients.base_us", KeyError, "coefficients.base_us is missing"),
        ("coefficients.base_us.value", "20", "coefficients.base_us.value must be a finite"),
        ("coefficients.base_us.value", True, "must be a finite number"),
        ("coefficients.per_bit_us.value", 1e6, "outside the plausible range"),
        ("coefficients.pause_unit_ms.sd", -1, "coefficients.pause_unit_ms.sd must be >= 0"),
        ("coefficients.pause_unit_ms.unit", "ms", "unknown field 'unit'"),
        ("coefficients.run_us", 300, 'must be an object {"value"'),
        ("coefficients.speed", {"value": 1}, "unknown coefficient 'speed'"),
        ("instruction_time_ratio", KeyError, "instruction_time_ratio is missing"),
        ("instruction_time_ratio.value", 0.0, "outside the plausible range"),
        ("source", 3, "source must be a string"),
        ("measurements", [], "measurements must be an object"),
        ("extra", 1, "unknown field 'extra'"),
    ],
)
def test_errors_name_file_and_field(tmp_path: Path, path: str, value: Any, message: str) -> None:
    f = tmp_path / "t.json"
    f.write_text(json.dumps(_set(_good(), path, value)))
    with pytest.raises(InputError) as err:
        tf.load(f)
    assert message in err.value.message and str(f) in err.value.message
    assert err.value.hint


def test_not_json_and_missing(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    with pytest.raises(InputError, match="malformed JSON"):
        tf.load(bad)
    with pytest.raises(InputError):
        tf.load(tmp_path / "nope.json")
    bad.write_text("[]")
    with pytest.raises(InputError, match="a timing file is a JSON object"):
        tf.load(bad)
