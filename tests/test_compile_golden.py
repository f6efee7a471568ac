"""Golden files of the generated PBASIC, WIRING.md and manifest, one controller per model.

The controllers are tests/golden/compile/<model>.json; the expected outputs live beside them
in tests/golden/compile/<model>/. After an intended change to the templates or the compiler,
regenerate with:

    BSTOOL_REGEN_GOLDEN=1 python -m pytest tests/test_compile_golden.py

and review the diff before committing.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from bstool.compile.build import compile_controller

GOLDEN = Path(__file__).parent / "golden" / "compile"
MODELS = ["ca1d", "ca2dsing", "ca2ddiff", "nnsig", "nnsin"]
MODULES = ["L0.M0", "L1.M2", "L4.M5"]
REGEN = os.environ.get("BSTOOL_REGEN_GOLDEN") == "1"


def _check(expected: Path, actual: str) -> None:
    if REGEN:
        expected.parent.mkdir(parents=True, exist_ok=True)
        expected.write_text(actual, encoding="utf-8")
        return
    assert expected.is_file(), f"missing golden file {expected}: run with BSTOOL_REGEN_GOLDEN=1"
    assert actual == expected.read_text(encoding="utf-8"), f"{expected} differs"


@pytest.mark.parametrize("model", MODELS)
def test_golden_sources(model: str, tmp_path: Path) -> None:
    out = tmp_path / "build"
    compile_controller(GOLDEN / f"{model}.json", out, period=0.5, tokenize=False)
    for label in MODULES:
        folder = out / "modules" / label
        for src in sorted(folder.glob("*.bsx")):
            _check(GOLDEN / model / label / src.name, src.read_text(encoding="utf-8"))
    _check(GOLDEN / model / "WIRING.md", (out / "WIRING.md").read_text(encoding="utf-8"))
    if model in ("ca2ddiff", "nnsin"):
        _check(
            GOLDEN / model / "manifest.json", (out / "manifest.json").read_text(encoding="utf-8")
        )
