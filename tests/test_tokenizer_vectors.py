"""The 36 shared tokenizer vectors (tests/vectors/tokenizer, copied from ../shared/vectors):
27 programs whose images and records must match Parallax's tokenizer byte for byte and 9
that must fail at the given line and column. Six of them (names with ``fuzz``) are minimised
from random programs on which bstool and Parallax's tokenizer disagreed (issue 14)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bstool.errors import SourceError
from bstool.tokenizer import tokenize_file

ROOT = Path(__file__).parent / "vectors" / "tokenizer"
CASES = sorted(p.name for p in ROOT.iterdir() if p.is_dir())


def check_case(name: str) -> list[str]:
    """Differences between our output and the expected files (empty list = pass)."""
    case = ROOT / name
    expected = json.loads((case / "expected.json").read_text())
    source = case / expected["source"]
    try:
        project = tokenize_file(source)
    except SourceError as exc:
        if expected["ok"]:
            return [f"unexpected error: {exc}"]
        want = (expected["error"]["line"], expected["error"]["column"])
        return [] if (exc.line, exc.column) == want else [f"error at {exc} instead of {want}"]
    if not expected["ok"]:
        return [f"accepted, expected error {expected['error']}"]
    problems = []
    if sorted(project.slots) != sorted(int(n) for n in expected["slots"]):
        problems.append(f"slots {sorted(project.slots)}")
    for number, info in expected["slots"].items():
        slot = project.slots.get(int(number))
        if slot is None:
            continue
        if slot.eeprom != (case / f"slot{number}.eeprom").read_bytes():
            problems.append(f"slot {number}: EEPROM image differs")
        if slot.packets != (case / f"slot{number}.packets").read_bytes():
            problems.append(f"slot {number}: records differ")
        for key in ("program_bytes", "data_bytes", "undefined_data_bytes"):
            if getattr(slot, key) != info[key]:
                problems.append(f"slot {number}: {key} {getattr(slot, key)} != {info[key]}")
        if len(slot.records) != info["packets"]:
            problems.append(f"slot {number}: {len(slot.records)} records != {info['packets']}")
    return problems


def test_all_vectors_present() -> None:
    assert len(CASES) == 36
    assert sum(1 for name in CASES if "fuzz" in name) == 6
    assert sum(1 for name in CASES if name.startswith("fail_")) == 9


@pytest.mark.parametrize("name", CASES)
def test_vector(name: str) -> None:
    assert check_case(name) == []


def test_vector_report(capsys: pytest.CaptureFixture[str]) -> None:
    """One summary line per vector, so a run shows at a glance which ones pass."""
    results = {name: check_case(name) for name in CASES}
    with capsys.disabled():
        passed = sum(1 for r in results.values() if not r)
        print(f"\ntokenizer vectors: {passed}/{len(CASES)} pass")
        for name, problems in results.items():
            if problems:
                print(f"  FAIL {name}: {'; '.join(problems)}")
    assert passed == len(CASES)
