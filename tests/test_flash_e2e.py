"""The whole chain into twins: a controller compiled by bstool compile, flashed into 30 twins
through the protocol with ``--all --ports``, each announcing its module and controller."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import hil_mock  # noqa: F401
from bstool.cli import main
from bstool.moduleid import all_modules
from hil_mock.urlhandler import clear_twins, get_twin


@pytest.fixture
def controller(tmp_path: Path) -> Path:
    import numpy as np

    from bstool.controllers import make_controller, save_controller

    rng = np.random.default_rng(3)
    ctrl = make_controller("ca1d", rng.integers(0, 16, (5, 6)), rule=rng.integers(0, 16, 4096))
    path = tmp_path / "best.json"
    save_controller(ctrl, path)
    return path


@pytest.mark.slow
def test_compile_then_flash_all_30_twins(
    controller: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setenv("BSTOOL_FLASH_FAST", "1")
    clear_twins()
    build = tmp_path / "build"
    assert main(["compile", str(controller), "-o", str(build), "--quiet"]) == 0
    manifest = json.loads((build / "manifest.json").read_text())
    h8 = manifest["controller"]["hash"][:8]
    ports = tmp_path / "ports.json"
    ports.write_text(json.dumps({m.label: f"bstwin://e2e-{m.label}" for m in all_modules(5, 6)}))
    assert main(["flash", "--all", "--ports", str(ports), str(build), "-q"]) == 0
    out = capsys.readouterr().out
    assert "30 flashed, 0 failed, 0 skipped" in out
    for entry in manifest["modules"]:
        label = entry["label"]
        assert f"module {label} runs controller {h8}" in out
        device = get_twin(f"e2e-{label}")
        for slot in entry["slots"]:
            assert device.eeprom.slot(slot["slot"]) == (build / slot["eeprom"]).read_bytes()
    clear_twins()


@pytest.mark.slow
def test_controller_target_compiles_on_the_fly(
    controller: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("BSTOOL_FLASH_FAST", "1")
    clear_twins()
    assert main(["flash", "-p", "bstwin://otf", str(controller), "--module", "4.5"]) == 0
    assert "module L4.M5 runs controller" in capsys.readouterr().out
    clear_twins()
