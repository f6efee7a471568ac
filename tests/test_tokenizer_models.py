"""The models behind issue 14's families (each stands for many programs, not one line), the
lexer's bulk path for long number lists, and large tables (rejected or accepted at once)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bstool.errors import SourceError
from bstool.tokenizer import SlotImage, tokenize_source
from bstool.tokenizer import lexer as lexer_module
from bstool.tokenizer.diagnostics import Failure
from bstool.tokenizer.expressions import Bits
from bstool.tokenizer.lexer import Lexer, prepare
from bstool.tokenizer.statements import _drop_word_item

HEAD = "' {$STAMP BS2sx}\n' {$PBASIC 2.5}\n"


def slot0(body: str) -> SlotImage:
    return tokenize_source(HEAD + body, "t.bsx").slots[0]


def error(body: str) -> tuple[int | None, int | None, int | None]:
    with pytest.raises(SourceError) as info:
        tokenize_source(HEAD + body, "t.bsx")
    return info.value.code, info.value.line, info.value.column


def constant_bits(value: int) -> str:
    """A constant item as a bit string (6-bit code, flag, low bits)."""
    top = max(value.bit_length() - 1, 0)
    code = f"{0x20 | top:06b}"
    if value == 0 or value == 1 << top:
        return code + ("1" if value == 0 else "0")
    return code + "1" + f"{value:0{top + 1}b}"[1:]


# ---- family 1: the high byte's write item of READ/GET ... WORD w(index) ---------------------
def test_drop_word_item_keeps_the_prefix_when_the_item_spans_two_words() -> None:
    prefix = Bits(0b1010101, 7)  # 7 + 10 = 17 bits: the item starts in word 0, ends in word 1
    item = 0b1111110011
    assert _drop_word_item(Bits(prefix.value << 10 | item, 17)) == prefix
    full = Bits(0b110011, 6)  # 6 + 10 = 16: one full word
    assert _drop_word_item(Bits(full.value << 10 | item, 16)) == full


@pytest.mark.parametrize("in_last", range(11, 16))
def test_drop_word_item_shifts_the_bits_sharing_a_partial_last_word(in_last: int) -> None:
    """16 + in_last bits: the item and ``in_last - 10`` prefix bits share the last word; those
    bits come out shifted right by ``16 - in_last`` (zeros above)."""
    before = in_last - 10
    head, tail = 0xBEEF, (1 << before) - 1  # all ones, so the shift is visible
    expr = Bits(((head << before | tail) << 10) | 0x3FF, 16 + in_last)
    got = _drop_word_item(expr)
    assert got.length == 16 + before
    assert got.value >> before == head
    assert got.value & ((1 << before) - 1) == tail >> (16 - in_last)


@pytest.mark.parametrize("index", [513, 1000, 2047, 4095, 5000, 12345, 16383])
def test_read_word_with_10_to_14_bit_constant_index(index: int) -> None:
    """The high-byte READ's write expression is ``index * 2`` and the byte item, but the bits
    of ``index`` + the 1 that announced the Word item that shared the buffer's last 16-bit
    word with that item come out shifted right by 16 - (bits in that word)."""
    slot = slot0(f"wa VAR Word(2)\nREAD 0, WORD wa({index})\n")
    prefix = constant_bits(index) + "1"  # 17..21 bits
    in_last = len(prefix) + 10 - 16  # 11..15 bits of the buffer in its last word
    before = in_last - 10
    shifted = f"{int(prefix[-before:], 2) >> (16 - in_last):0{before}b}"
    rebuilt = prefix[:-before] + shifted + "100001" + "0" + "1010010" + "1" + "111110" + "00111"
    # the second READ follows the start address and the first READ: location 0, code,
    # resume address, write expression (index, 1 + the Word item), 0
    start = 14 + 8 + 7 + 14 + len(prefix) + 10 + 1
    location = "1" + constant_bits(0) + "1" + constant_bits(1) + "1001111"  # 0, 1, +
    got = slot.bits(start, len(location) + 7 + 14 + len(rebuilt) + 1)
    assert got[: len(location) + 7] == location + "0010011"
    assert got[len(location) + 7 + 14 :] == rebuilt + "0"
    assert shifted != prefix[-before:]  # the announcing 1 is lost


@pytest.mark.parametrize("index", [3, 255, 256, 512, 16384, 32767])
def test_read_word_with_other_constant_indices_is_plain_index_times_two(index: int) -> None:
    slot = slot0(f"wa VAR Word(2)\nREAD 0, WORD wa({index})\n")
    bits = constant_bits(index) + "1" + "100001" + "0" + "1010010" + "1" + "111110" + "00111"
    assert bits in slot.bits(71, 200)


def test_get_word_with_nested_index_loses_a_bit_of_the_inner_register() -> None:
    """``v3(v5(1))``: the inner byte v5(1) is register 10 (01010); in the high byte's GET its
    last 4 bits share the last buffer word with the item and come out as 0001 (register 8)."""
    slot = slot0("v5 VAR Byte(3)\nv3 VAR Word(2)\nGET 0, WORD v3(v5(1))\n")
    first = constant_bits(1) + "1" + "110110" + "01010"
    second = constant_bits(1) + "1" + "110110" + "01000"
    bits = slot.bits(0, 140)
    assert first + "1" + "111111" + "0011" in bits
    assert second + "1" + "100001" + "0" in bits


def test_write_and_put_word_are_not_affected() -> None:
    for op in ("WRITE", "PUT"):
        slot = slot0(f"wa VAR Word(2)\n{op} 0, WORD wa(1000)\n")
        assert constant_bits(1000) + "1" + "110111" + "0011" in slot.bits(0, 200)


# ---- family 2: CASE items joined into the expression buffer ---------------------------------
def test_case_item_of_255_bits_or_more_cannot_be_appended() -> None:
    """Appending counts copied bits in a byte: a CASE item of 255+ bits wraps it (error 144 at
    the element after that item), even when the joined condition would fit in 496 bits."""
    select = "SELECT b + 46089 + 46089 + 46089 + 46089\n"  # 131 bits
    assert error(f"b VAR Byte\n{select}CASE 14, 240 TO 4\nSTOP\nENDSELECT\n") == (144, 5, 18)
    # the range alone (307 bits) is fine; so is a single item before it
    slot0(f"b VAR Byte\n{select}CASE 240 TO 4\nSTOP\nENDSELECT\n")
    slot0(f"b VAR Byte\n{select}CASE 240 TO 4, 14\nSTOP\nENDSELECT\n")


def test_case_item_position_is_the_item_that_overflows() -> None:
    body = (
        "v5 VAR Word\nv7 VAR Byte\nbuf9 VAR Byte(4)\nK16 CON %10100001010\n"
        "SELECT (K16) - 42036 */ buf9(2) DIG 53466\n"
        "  CASE 39599, v7 TO v5.LOWBIT, K16 TO 135\n"
    )
    assert error(body) == (144, 8, 30)


def test_cc_case_lists_follow_the_same_buffer_model() -> None:
    long = " + ".join(["40000"] * 9)  # 9 constants: 24 + 8 * 30 = 264 bits per test
    assert error(f"#SELECT {long}\n#CASE 1, 2\nHIGH 1\n#ENDSELECT\n")[0] == 144
    slot0(f"#SELECT {' + '.join(['40000'] * 3)}\n#CASE 1, 2 TO 3\nHIGH 1\n#ENDSELECT\nLOW 1\n")


# ---- families 3 and 4: a full slot -----------------------------------------------------------
def filler(lines: int) -> str:
    """DEBUG statements of 11 characters each, as in the vectors that fill the slot."""
    return 'DEBUG "01234567890"\n' * lines


def test_expression_written_a_word_at_a_time_reaches_data_first() -> None:
    """A long expression is written 16 bits at a time: the word that reaches DATA at $000 is
    error 124 at the DATA item (the whole expression would not fit: 127 otherwise)."""
    sum_ = " + ".join(str(n * 1000) for n in range(1, 10))
    body = f'D DATA (3)\nx VAR Word\nDEBUG "pppppp"\n{filler(87)}x = x + {sum_}\n'
    assert error(body) == (124, 3, 8)


def test_final_end_that_does_not_fit_is_reported_at_the_last_statement() -> None:
    body = f'x VAR Word\nDEBUG "ppppppp"\n{filler(88)}x = 5\nPAUSE 1\n'
    assert error(body) == (127, 94, 1)
    # after a label the IDE's statement loop last looked at the ':' that follows it
    body = f'x VAR Word\nDEBUG "ppppppp"\n{filler(88)}x = 5\nPAUSE 1\nHere:\n'
    assert error(body) == (127, 95, 5)


# ---- the lexer's bulk path ------------------------------------------------------------------
def _elements(source: str, bulk: bool, monkeypatch: pytest.MonkeyPatch) -> object:
    if not bulk:
        monkeypatch.setattr(Lexer, "_number_list", lambda self, pos: pos)
    try:
        lexer = Lexer(prepare(source), True, {})
        result: object = [(e.kind, e.value, e.start, e.length) for e in lexer.run()]
    except Failure as exc:
        result = ("fail", exc.code, exc.offset)
    monkeypatch.undo()
    return result


NUMBER = st.one_of(
    st.integers(0, 70000).map(str),
    st.integers(0, 0xFFFF).map(lambda v: f"${v:X}"),
)
GAP = st.sampled_from([", ", ",", " , ", ",\n", ", ' note\n  ", ",\t"])


@settings(max_examples=80, deadline=None)
@given(st.lists(st.tuples(NUMBER, GAP), min_size=1, max_size=40), st.integers(8, 90))
def test_bulk_number_lists_give_the_general_path_elements(
    items: list[tuple[str, str]], limit: int
) -> None:
    """Same elements or the same error (107 at the same element with a small element list,
    109 for a number over 16 bits) with and without the bulk path."""
    body = "".join(number + gap for number, gap in items[:-1]) + items[-1][0]
    source = f"T DATA {body}\nLOOKUP 1, [{body}], B0\n"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(lexer_module, "MAX_ELEMENTS", limit)
        bulk = _elements(source, True, mp)
        mp.setattr(lexer_module, "MAX_ELEMENTS", limit)
        general = _elements(source, False, mp)
    assert bulk == general


# ---- large tables ---------------------------------------------------------------------------
def test_huge_lookup_is_rejected_by_the_element_limit() -> None:
    items = ", ".join(str((i * 7919) % 65536) for i in range(12000))  # 24,000 elements
    code, line, column = error(f"x VAR Word\nLOOKUP 0, [{items}], x\n")
    assert (code, line) == (107, 4)
    # 8 elements before the list (x VAR Word <end> LOOKUP 0 , [), item k is element 9 + 2k:
    # the 10241st, item 5116, is the first that does not fit
    values = [str((i * 7919) % 65536) for i in range(5116)]
    assert column == len("LOOKUP 0, [") + 1 + len(", ".join(values)) + 2


def test_lookup_over_the_slot_is_rejected_at_the_item_that_does_not_fit() -> None:
    items = ", ".join(str(40000 + i) for i in range(4000))  # < 10240 elements, > 2048 bytes
    code, line, _ = error(f"x VAR Word\nLOOKUP 0, [{items}], x\n")
    assert (code, line) == (127, 4)


def test_huge_data_tables_are_rejected_or_accepted() -> None:
    full = ", ".join(str(i % 256) for i in range(2048))
    assert slot0(f"T DATA {full}\n").data_bytes == 2048
    over = ", ".join(str(i % 256) for i in range(4000))
    assert error(f"T DATA {over}\n")[0] == 114
    huge = ", ".join(str(i % 256) for i in range(16000))
    assert error(f"T DATA {huge}\n")[0] == 107


def test_reading_past_the_last_element_reports_the_element_read_last() -> None:
    """Parallax's reader leaves the caller's element as it was past the end: SELECT as the
    last line wants a CASE after its line end and reports 179 at that line end."""
    assert error("b VAR Byte\nSELECT b\n") == (179, 4, 9)
    assert error("b VAR Byte\nSELECT b\nc VAR Byte\n") == (179, 4, 9)  # (cancelled after)
