"""The Python API (bstool.api, docs/api.md) and its walkthrough example, run as a script."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import bstool
import bstool.api as bst
from bstool.cli import main
from bstool.controllers import load_controller as load_file
from bstool.errors import InputError, SourceError

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "notebook_walkthrough.py"
TOY: dict[str, Any] = {"pop": 4, "transitions": 6, "seed": 2, "fitness": "toy"}


def files(d: Path) -> tuple[str, str]:
    return (d / "best.json").read_text(), (d / "history.csv").read_text()


def test_import_bstool_stays_cheap() -> None:
    code = (
        "import sys, bstool\n"
        "assert 'numpy' not in sys.modules and 'click' not in sys.modules\n"
        "assert bstool.load_controller is bstool.api.load_controller\n"
        "from bstool.evolve import evolve, EvolveResult\n"
        "assert 'mujoco' not in sys.modules, 'the API imports MuJoCo before it needs it'\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_top_level_names() -> None:
    assert bstool.states is bst.states and bstool.EvolveResult is bst.EvolveResult
    with pytest.raises(AttributeError):
        bstool.no_such_name  # noqa: B018


def test_load_controller_takes_a_path_a_dict_or_a_controller(tmp_path: Path) -> None:
    ctrl = bst.builtin_controller("ca1d")
    path = tmp_path / "c.json"
    path.write_text(json.dumps(ctrl.to_json()))
    assert bst.load_controller(path).hash() == ctrl.hash()
    assert bst.load_controller(str(path)).hash() == ctrl.hash()
    assert bst.load_controller(ctrl.to_json()).hash() == ctrl.hash()
    assert bst.load_controller(ctrl) is ctrl
    bad = {**ctrl.to_json(), "legs": 0}
    with pytest.raises(InputError, match="legs"):
        bst.load_controller(bad)
    with pytest.raises(InputError, match="not found"):
        bst.load_controller(tmp_path / "missing.json")
    with pytest.raises(InputError, match="expected a controller"):
        bst.load_controller(42)  # type: ignore[arg-type]


def test_states_and_simulate() -> None:
    ctrl = bst.builtin_controller("nnsin")
    seq = bst.states(ctrl, transitions=4)
    assert seq.shape == (5, 5, 6)
    assert np.array_equal(seq, ctrl.states(4))
    assert bst.states(ctrl).shape[0] == (ctrl.max_trans or 30) + 1
    held = bst.states(ctrl, transitions=4, failed=["1.2"])
    assert (held[:, 1, 2] == held[0, 1, 2]).all()
    a, b = bst.simulate(ctrl, transitions=4), bst.simulate(seq)
    assert np.array_equal(a.path, b.path) and a.transitions == 4
    batch = bst.evaluate([seq, ctrl], transitions=4, workers=2)
    assert [r.distance for r in batch] == [a.distance, a.distance]
    with pytest.raises(InputError, match="apply to a controller"):
        bst.simulate(seq, failed=["0.0"])
    with pytest.raises(InputError, match="transitions"):
        bst.states(ctrl, transitions=-1)
    with pytest.raises(InputError, match="--workers"):
        bst.evaluate([seq], workers=0)


def test_evolve_equals_the_command_and_reports_each_generation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    seen: list[bst.Generation] = []
    result = bst.evolve("nnsig", gens=3, out=tmp_path / "api", on_generation=seen.append, **TOY)
    cli = ["evolve", "nnsig", "--gens", "3", "--pop", "4", "--transitions", "6", "--seed", "2",
           "--fitness", "toy", "-q", "--out", str(tmp_path / "cli")]  # fmt: skip
    assert main(cli) == 0
    assert files(tmp_path / "api") == files(tmp_path / "cli")
    assert [g.step for g in seen] == [1, 2, 3] and seen[-1].total_steps == 3
    assert result.completed and result.path == tmp_path / "api"
    assert result.best_json == tmp_path / "api" / "best.json"
    assert result.controller is not None
    assert result.controller.hash() == load_file(tmp_path / "api" / "best.json").hash()
    assert result.fitness == max(r.best for r in result.history) == seen[-1].best_so_far
    assert result.params.pop == 4 and result.fitness_kind == "toy"
    assert "(toy units)" in result.fitness_text


def test_evolve_without_out_writes_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    result = bst.evolve("ca1d", gens=2, **TOY)
    assert result.path is None and result.best_json is None and len(result.history) == 2
    assert list(tmp_path.iterdir()) == []


def test_interrupt_leaves_a_resumable_run(tmp_path: Path) -> None:
    full, cut = tmp_path / "full", tmp_path / "cut"
    bst.evolve("ca2dsing", gens=4, out=full, **TOY)

    def stop_at_two(g: bst.Generation) -> None:
        if g.step == 2:
            raise KeyboardInterrupt

    with pytest.raises(bst.EvolveInterrupted) as caught:
        bst.evolve("ca2dsing", gens=4, out=cut, on_generation=stop_at_two, **TOY)
    partial = caught.value.result
    assert isinstance(caught.value, KeyboardInterrupt)
    assert not partial.completed and len(partial.history) == 2 and partial.path == cut
    assert caught.value.resume_hint == f"bstool evolve --resume {cut}"
    resumed = bst.resume(cut)
    assert resumed.completed and files(cut) == files(full)
    extended = bst.resume(cut, gens=5)
    assert len(extended.history) == 5


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"pop": 1}, "--pop must be"),
        ({"fitness": "magic"}, "unknown --fitness"),
        ({"workers": 0}, "--workers must be"),
        ({"out": "file/run"}, "is a file, not a folder"),
        ({"out": "mine"}, "not empty and was not made by this command"),
    ],
)
def test_evolve_errors_before_any_work(
    kwargs: dict[str, Any], message: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "file").write_text("")
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "best.json").write_text("{}")
    with pytest.raises(InputError, match=message):
        bst.evolve("ca1d", **{**TOY, **kwargs})
    assert (tmp_path / "mine" / "best.json").read_text() == "{}"
    with pytest.raises(InputError, match="no checkpoint"):
        bst.resume(tmp_path / "nowhere")


def test_tokenize_text_errors_carry_the_position() -> None:
    ok = bst.tokenize_text("' {$STAMP BS2sx}\n' {$PBASIC 2.5}\nDEBUG \"hi\"\nEND\n")
    assert len(ok.slots[0].eeprom) == 2048
    with pytest.raises(SourceError) as caught:
        bst.tokenize_text("' {$STAMP BS2sx}\n' {$PBASIC 2.5}\nGOTO nowhere\n", filename="x.bsx")
    assert caught.value.file == "x.bsx" and caught.value.line == 3


@pytest.mark.slow
def test_walkthrough_example_runs(tmp_path: Path) -> None:
    summary = tmp_path / "summary.json"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    args = ["--pop", "4", "--gens", "2", "--transitions", "6", "--twin-transitions", "2",
            "--keep", str(tmp_path / "work"), "--summary", str(summary)]  # fmt: skip
    proc = subprocess.run([sys.executable, str(EXAMPLE), *args], env=env, capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    for start in ("controller: nnsin", "rejected:", "states:", "simulate:", "evaluate:",
                  "evolve:", "compile:", "tokenize:", "flash:", "twin:"):  # fmt: skip
        assert f"\n{start}" in f"\n{out}", start
    assert out.count("  generation ") == 2 and " cm" in out
    s = json.loads(summary.read_text())
    assert s["states_shape"] == [7, 5, 6]
    assert s["distance_m"] == bst.simulate(bst.builtin_controller("nnsin"), transitions=6).distance
    assert s["batch_m"][0] == s["distance_m"] and s["batch_m"][1] != s["distance_m"]
    ev = s["evolve"]
    assert ev["generations"] == ev["history_rows"] == 2 and ev["completed"]
    assert load_file(ev["best_json"]).fitness == ev["fitness"]
    assert s["modules"] == 30 and s["tokenized_equal"] and s["flash_ok"]
    assert s["twin_states_equal"]
