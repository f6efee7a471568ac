"""Robustness: whatever the input, the tokenizer returns images or raises SourceError with a
position inside the source, never another exception (hypothesis: random bytes, random token
soup, truncated real programs)."""

from __future__ import annotations

from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bstool.errors import SourceError
from bstool.tokenizer import tokenize_source
from bstool.tokenizer.lexer import RESERVED

ROOT = Path(__file__).parent / "vectors" / "tokenizer"
PROGRAMS = sorted(
    p.read_text() for p in ROOT.glob("*/*.bsx") if not p.parent.name.startswith("multi")
)
HEADER = "' {$STAMP BS2sx}\n' {$PBASIC 2.5}\n"
WORDS = [
    *sorted(RESERVED[True]),
    "x", "y", "tab", "Main", "Main:", "0", "1", "255", "65535", "70000", "$FF", "%101", "$",
    "%", '"ab"', '""', '"', "'", ":", ",", "\n", "\r\n", "\t", " ", "(", ")", "[", "]", "@",
    "?", "\\", ".", "#", "{", "x VAR Byte\n", "c CON 5\n", "t DATA 1,2\n", "p PIN 3\n",
]  # fmt: skip
FUZZ = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _tokenize_or_error(text: str) -> None:
    try:
        project = tokenize_source(text, "fuzz.bsx")
    except SourceError as exc:
        assert exc.code is not None and exc.line is not None and exc.column is not None
        assert 1 <= exc.line <= text.count("\n") + text.count("\r") + 2
        assert exc.message
        return
    for slot in project.slots.values():
        assert len(slot.eeprom) == 2048
        assert all(len(r) == 18 and sum(r) % 256 == 0 for r in slot.records)


@FUZZ
@given(st.binary(max_size=400))
def test_random_bytes(data: bytes) -> None:
    _tokenize_or_error(HEADER + data.decode("latin-1"))


@FUZZ
@given(st.lists(st.sampled_from(WORDS), max_size=60))
def test_token_soup(words: list[str]) -> None:
    _tokenize_or_error(HEADER + " ".join(words))


@FUZZ
@given(st.lists(st.sampled_from(WORDS), max_size=40), st.integers(0, 40))
def test_token_soup_lines(words: list[str], every: int) -> None:
    text = "".join(w + ("\n" if every and i % every == 0 else " ") for i, w in enumerate(words))
    _tokenize_or_error(HEADER + text)


@FUZZ
@given(st.sampled_from(PROGRAMS), st.data())
def test_truncated_programs(program: str, data: st.DataObject) -> None:
    cut = data.draw(st.integers(0, len(program)))
    _tokenize_or_error(program[:cut])


@FUZZ
@given(st.sampled_from(PROGRAMS), st.data())
def test_mutated_programs(program: str, data: st.DataObject) -> None:
    at = data.draw(st.integers(0, len(program)))
    drop = data.draw(st.integers(0, 12))
    insert = data.draw(st.sampled_from(WORDS))
    _tokenize_or_error(program[:at] + insert + program[at + drop :])


@FUZZ
@given(st.sampled_from(PROGRAMS), st.data())
def test_records_reassemble_the_image(program: str, data: st.DataObject) -> None:
    """Property: every record is [$80+block][the block's 16 image bytes][check]."""
    at = data.draw(st.integers(0, len(program)))
    try:
        slot = tokenize_source(program[:at] + "\n" + program[at:], "p.bsx").slots[0]
    except SourceError:
        return
    for record in slot.records:
        block = record[0] - 0x80
        assert record[1:17] == slot.eeprom[block * 16 : block * 16 + 16]
