"""`bstool compile --period P` sets HoldFrames, so the unperturbed period is about P at the
timing model's speed (docs/compile.md, "Period"); below what the handshakes can do it refuses."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from conftest import traced_controller

from bstool import timingfile as tf
from bstool.compile import compile_controller
from bstool.compile.calibration import DEFAULT
from bstool.compile.plan import build_plans, floor_period_ms, min_hold_frames, period_ms
from bstool.compile.timing import CompileTiming
from bstool.controllers import load_controller
from bstool.errors import BuildError

MODELS = ("ca1d", "ca2dsing", "ca2ddiff", "nnsin", "nnsig")


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("period", [0.4, 0.475, 0.8])
def test_the_estimated_period_follows_the_requested_one(model: str, period: float) -> None:
    ctrl = load_controller(traced_controller(model))
    plans = build_plans(ctrl, DEFAULT, period, "00000000")
    assert len({p.hold_frames for p in plans}) == 1
    assert plans[0].hold_frames >= min_hold_frames(plans)
    assert period_ms(plans) == pytest.approx(period * 1000, rel=0.04)


def test_a_longer_period_holds_longer_and_a_slower_stamp_shorter() -> None:
    ctrl = load_controller(traced_controller("nnsin"))
    holds = [build_plans(ctrl, DEFAULT, p, "x")[0].hold_frames for p in (0.4, 0.6, 0.8)]
    assert holds == sorted(holds) and len(set(holds)) == 3
    slow = CompileTiming(tf.TimingModel(instruction_time_ratio=tf.Coefficient(1.8), source="t"))
    assert build_plans(ctrl, DEFAULT, 0.6, "x", model=slow)[0].hold_frames < holds[1]


@pytest.mark.parametrize("model", ["ca1d", "nnsig"])
def test_programs_and_manifest_carry_the_hold(model: str, tmp_path: Path) -> None:
    res = compile_controller(traced_controller(model), tmp_path, period=0.8, tokenize=False)
    man = json.loads((tmp_path / "manifest.json").read_text())
    assert man["period_s"] == 0.8
    hold = man["link"]["hold_frames"]
    assert hold == res.modules[0].plan.hold_frames > 26
    for m in man["modules"]:
        text = (tmp_path / m["entry"]).read_text()
        assert re.search(rf"^HoldFrames\s+CON\s+{hold}\b", text, re.M), m["label"]
        assert m["timing"]["nominal_transition_s"] == pytest.approx(0.8, rel=0.04)


def test_a_period_below_the_handshakes_is_refused(tmp_path: Path) -> None:
    ctrl = load_controller(traced_controller("nnsin"))
    floor = floor_period_ms(build_plans(ctrl, DEFAULT, 0.475, "x")) / 1000
    with pytest.raises(BuildError) as info:
        compile_controller(traced_controller("nnsin"), tmp_path, period=floor * 0.8)
    assert "too short" in info.value.message and "--period" in (info.value.hint or "")
    compile_controller(traced_controller("nnsin"), tmp_path / "ok", period=floor, tokenize=False)
