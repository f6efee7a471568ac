"""Tokenizer facts beyond the shared vectors: item sizes and layout, error numbers and
positions, PBASIC 2.0, conditional compilation, project files and the `tokenize` command."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bstool.cli import main
from bstool.errors import InputError, SourceError
from bstool.tokenizer import SlotImage, tokenize_file, tokenize_source
from bstool.tokenizer import tokens as T
from bstool.tokenizer.lexer import INSTRUCTIONS_25, INSTRUCTIONS_COMMON
from bstool.tokenizer.project import _Slot

HEAD = "' {$STAMP BS2sx}\n' {$PBASIC 2.5}\n"
VECTORS = Path(__file__).parent / "vectors" / "tokenizer"


def slot0(body: str, head: str = HEAD) -> SlotImage:
    return tokenize_source(head + body, "t.bsx").slots[0]


def error(body: str, head: str = HEAD) -> tuple[int | None, int | None, int | None]:
    with pytest.raises(SourceError) as info:
        tokenize_source(head + body, "t.bsx")
    exc = info.value
    assert exc.file == "t.bsx" and exc.message
    return exc.code, exc.line, exc.column


def stream(slot: SlotImage, start: int, count: int) -> str:
    return slot.bits(start, count)


# ---- layout -------------------------------------------------------------------------------
def test_pause_20_is_19_bits_after_the_start_address() -> None:
    s = slot0("PAUSE 20\n")
    # start address 14 = %1110 -> low 3 bits 110, then 11-bit byte count 1
    assert stream(s, 0, 14) == "110" + "00000000001"
    # 1, constant item $24 (n=4), flag+4 low bits of 20 (10100), 0, PAUSE $15
    assert stream(s, 14, 19) == "1" + "100100" + "10100" + "0" + "010101"
    assert stream(s, 33, 7) == "0000000"  # END appended
    assert s.program_bytes == 5 and s.records and len(s.records) == 1


@pytest.mark.parametrize(
    ("value", "bits"), [(0, 8), (1, 8), (2, 8), (20, 12), (255, 15), (256, 8), (1875, 18)]
)
def test_constant_item_sizes(value: int, bits: int) -> None:
    assert T.constant_item_bits(value) == bits
    s = slot0(f"PAUSE {value}\nEND\n")
    assert s.statements[0][2] == bits + 7


def test_gosub_return_table_and_ids() -> None:
    s = slot0("GOSUB A\nGOSUB A\nEND\nA: RETURN\n")
    code = 3 * T.ADDRESS_BITS  # start address + 2 return slots
    assert s.statements[0][1] == code
    # GOSUB: 0 + code $0A, 8-bit id 1, 14-bit address
    assert stream(s, code, 15) == "0001010" + "00000001"
    ret1 = code + 7 + 8 + 14  # return address of the first GOSUB = bit after it
    assert stream(s, 14, 14) == format(ret1 & 7, "03b") + format(ret1 >> 3, "011b")


def test_records_have_zero_checksum_and_ascending_blocks() -> None:
    s = slot0('x DATA "hello", 0\nHIGH 1\n')
    assert s.data_bytes == 6 and s.program_bytes > 0
    blocks = [r[0] - 0x80 for r in s.records]
    assert blocks == sorted(blocks) and blocks[0] == 0 and blocks[-1] == 127
    assert all(len(r) == 18 and sum(r) % 256 == 0 for r in s.records)
    assert s.eeprom[:6] == b"hello\x00"


def test_undefined_data_is_reserved_but_not_sent() -> None:
    s = slot0("t DATA @64, (40)\nu DATA 7\nREAD u, B0\n")
    assert s.undefined_data_bytes == 40 and s.data_bytes == 1 and s.eeprom[104] == 7
    assert [r[0] - 0x80 for r in s.records] == [6, 127]  # blocks 4-5 hold only (40)


def test_variable_allocation_words_first() -> None:
    s = slot0("a VAR Bit\nb VAR Byte\nc VAR Word\nd VAR Nib\nc = b + a + d\n")
    assert s.variables_used == 4  # 16 + 8 + 4 + 1 bits
    # c is word 3 (first user word): write item $3B + index 0011 as the last item
    assert "1" + "111011" + "0011" in stream(s, 14, s.statements[0][2])


def test_every_instruction_has_a_compiler() -> None:
    for name in (*INSTRUCTIONS_COMMON, *INSTRUCTIONS_25):
        assert hasattr(_Slot, "op_" + name.lower()), name


def test_formatter_codes() -> None:
    f = T.NUMBER_FORMATTERS
    assert (f["DEC"], f["DEC1"], f["SDEC5"], f["HEX"], f["IHEX2"], f["BIN16"]) == (
        0x1B6, 0x3F6, 0x7B6, 0x1C0, 0xBE0, 0x30E,
    )  # fmt: skip
    assert len(f) == 100


# ---- errors: number, line, column ---------------------------------------------------------
@pytest.mark.parametrize(
    ("body", "expected"),
    [
        ("x VAR Byte\nx = 5 +\n", (141, 4, 8)),
        ("GOTO Nowhere\n", (111, 3, 6)),
        ("p PIN 16\n", (175, 3, 7)),
        ("x VAR Byte(0)\n", (125, 3, 12)),
        ("y CON 1/0\n", (113, 3, 9)),
        ("NEXT\n", (132, 3, 1)),
        ("LOOP\n", (164, 3, 1)),
        ("ENDIF\n", (160, 3, 1)),
        ("ELSE\n", (159, 3, 1)),
        ("CASE 1\n", (180, 3, 1)),
        ("ENDSELECT\n", (183, 3, 1)),
        ("EXIT\n", (167, 3, 1)),
        ("DO\nHIGH 1\n", (170, 3, 1)),
        ("  FOR B0 = 1 TO 3\nHIGH 1\n", (169, 3, 3)),
        ("SELECT B0\nCASE 1\nHIGH 1\n", (184, 3, 1)),
        ("Main\nGOTO Main\n", (174, 3, 1)),
        ('DEBUG "ab\n', (102, 3, 10)),
        ("B0 = $\n", (104, 3, 7)),
        ("B0 = 99999\n", (109, 3, 6)),
        ("B0 = y\n", (110, 3, 6)),
        ("B0 = 1 + (2 + (3 + (4 + (5 + (6 + (7 + (8 + 9)))))))\n", (144, 3, 45)),
        ("B0 = 5 B1\n", (142, 3, 8)),
        ("HIGH 1 2\n", (142, 3, 8)),
        ("END 5\n", (129, 3, 5)),
        ("x VAR Byte\nx VAR Word\n", (123, 4, 1)),
        ("Main:\nMain:\n", (117, 4, 1)),
        ("IF B0 THEN\nELSE\nELSE\nENDIF\n", (161, 5, 1)),
        ("IF B0 THEN\nELSE\nELSEIF B1 THEN\nENDIF\n", (230, 5, 1)),
        ("B0 = W0.LOWBYTE.HIGHBYTE\n", (139, 3, 17)),
        ("B0 = B1.BIT8\n", (140, 3, 9)),
        ("B0 = IN3.BIT0\n", (138, 3, 6)),
        ("LOOKDOWN B0, GOTO [1], B1\n", (143, 3, 14)),
        ("ON B0 HIGH A\n", (185, 3, 7)),
        ("x DATA @2048, 1\n", (114, 3, 9)),
        ("a DATA 1\nb DATA @0, 2\n", (115, 4, 12)),
        ("B0 = %2\n", (105, 3, 7)),
        ("B0 = " + "a" * 33 + "\n", (106, 3, 6)),
        ("B0 = 1 ! 2\n", (103, 3, 8)),
        ('x DATA ""\n', (101, 3, 8)),
    ],
)
def test_error_number_and_position(body: str, expected: tuple[int, int, int]) -> None:
    assert error(body) == expected


def test_label_reserved_on_bs2p_gets_a_clear_message() -> None:
    with pytest.raises(SourceError, match="BS2p") as info:
        tokenize_source(HEAD + "STORE 1\n", "t.bsx")
    assert (info.value.code, info.value.line, info.value.column) == (174, 3, 1)
    assert slot0("store VAR Byte\nstore = 1\n").program_bytes > 0  # an ordinary name


def test_directive_errors() -> None:
    assert error("HIGH 1\n", head="' {$PBASIC 2.5}\n") == (156, 1, 1)
    assert error("HIGH 1\n", head="' {$STAMP BS2p}\n' {$PBASIC 2.5}\n")[0] == 204
    assert error("", head=HEAD) == (157, 1, 1)
    assert error("HIGH 1\n", head="' {$STAMP BS2sx}\n' {$PBASIC 2.4}\n")[0] == 187
    assert error("HIGH 1\n", head=HEAD + "' {$PBASIC 2.5}\n")[0] == 155


def test_eeprom_full_and_gosub_limit() -> None:
    assert error("PAUSE 65535\n" * 600)[0] == 127
    assert error("A: GOSUB A\n" * 256) == (145, 258, 4)


# ---- language variants ----------------------------------------------------------------------
def test_pbasic_20_rules() -> None:
    head = "' {$STAMP BS2sx}\n"
    s = slot0("Main:\nIF B0 > 1 THEN Main\nDO\nGOTO DO\n", head=head)  # DO is a label in 2.0
    assert s.pbasic == "2.0" and s.program_bytes > 0
    assert error("IF B0 THEN HIGH 1\n", head=head)[0] == 148
    assert error("HIGH 1,\n2\n", head=head)[0] == 129  # no line continuation


def test_line_continuation_after_comma_with_comment() -> None:
    a = slot0("LOOKUP B0, [1, 2, ' one\n 3], B1\n")
    b = slot0("LOOKUP B0, [1, 2, 3], B1\n")
    assert a.eeprom == b.eeprom


def test_two_character_operators_may_contain_blanks() -> None:
    assert slot0("IF B0 < = 3 THEN X\nX:\n").eeprom == slot0("IF B0 <= 3 THEN X\nX:\n").eeprom


def test_conditional_compilation_selects_bs2sx_branch() -> None:
    program = (
        "#DEFINE Fast\n#SELECT $STAMP\n #CASE BS2, BS2E\n  Baud CON 84\n"
        ' #CASE BS2SX, BS2P\n  Baud CON 240\n #CASE #ELSE\n  #ERROR "no"\n#ENDSELECT\n'
        "#IF Fast #THEN\n  PAUSE 1\n#ELSE\n  PAUSE 2\n#ENDIF\nSEROUT 1, Baud, [1]\n"
    )
    plain = "PAUSE 1\nSEROUT 1, 240, [1]\n"
    assert slot0(program).eeprom == slot0(plain).eeprom
    assert error('#ERROR "stop here"\n')[0] == 199
    assert error("#IF 1 #THEN\nHIGH 1\n") == (191, 3, 1)


def test_word_modifiers_in_read_and_write() -> None:
    s = slot0("w VAR Word\nREAD 0, Word w\nWRITE 2, Word w\n")
    assert s.program_bytes > 0
    assert error("b VAR Byte\nREAD 0, Word b\n") == (173, 4, 14)


# ---- project files and API ----------------------------------------------------------------
def test_multi_slot_project_paths(tmp_path: Path) -> None:
    (tmp_path / "sub").mkdir()
    (tmp_path / "a b.bsx").write_text(HEAD + "HIGH 1\n")
    (tmp_path / "sub" / "c.bsx").write_text("' {$PBASIC 2.5}\nLOW 2\n")
    main_file = tmp_path / "sub" / "main.bsx"
    main_file.write_text("' {$STAMP BS2sx, \"../a b.bsx\", c.bsx}\n' {$PBASIC 2.5}\nRUN 1\n")
    project = tokenize_file(main_file)
    assert sorted(project.slots) == [0, 1, 2]
    assert project.slots[2].eeprom == slot0("LOW 2\n").eeprom


def test_missing_project_file_points_at_its_name(tmp_path: Path) -> None:
    main_file = tmp_path / "main.bsx"
    main_file.write_text("' {$STAMP BS2sx, gone.bsx}\n' {$PBASIC 2.5}\nRUN 1\n")
    with pytest.raises(SourceError) as info:
        tokenize_file(main_file)
    assert (info.value.line, info.value.column) == (1, 18)


def test_missing_source_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError):
        tokenize_file(tmp_path / "none.bsx")


# ---- command --------------------------------------------------------------------------------
def test_tokenize_command_writes_images(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    case = VECTORS / "multi_robot_rules"
    src = case / "multi_robot_rules.bsx"
    assert main(["tokenize", str(src), "-o", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "slot 2" in out and "records" in out
    for n in range(3):
        assert (tmp_path / f"slot{n}.eeprom").read_bytes() == (
            case / f"slot{n}.eeprom"
        ).read_bytes()
        assert (tmp_path / f"slot{n}.packets").read_bytes() == (
            case / f"slot{n}.packets"
        ).read_bytes()


def test_tokenize_command_json_and_listing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = VECTORS / "io_pin_commands" / "io_pin_commands.bsx"
    assert main(["tokenize", str(src), "-o", str(tmp_path), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["slots"]["0"]["program_bytes"] == 58
    assert main(["tokenize", str(src), "-o", str(tmp_path), "--listing"]) == 0
    listing = capsys.readouterr().out
    assert "  line   bit  bits" in listing and "   10    14  110000010000100" in listing


def test_tokenize_command_error_exit(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = VECTORS / "fail_too_many_variables" / "fail_too_many_variables.bsx"
    assert main(["tokenize", str(src), "-o", str(tmp_path)]) == 3
    err = capsys.readouterr().err
    assert ":20:21: error [126]" in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())


def test_symbol_table_holds_1024_names() -> None:
    body = "".join(f"c{i} CON {i}\n" for i in range(625)) + "HIGH c1\n"
    assert slot0(body).program_bytes > 0
    assert error("x CON 1\n" + body) == (128, 628, 1)


def test_conditional_select_ranges_and_nesting() -> None:
    program = (
        "#DEFINE Level = 3\n#SELECT Level\n #CASE 1 TO 2\n  PAUSE 1\n #CASE 3, 4\n"
        "  #IF Level = 3 #THEN\n   PAUSE 3\n  #ENDIF\n #CASE #ELSE\n  PAUSE 9\n#ENDSELECT\n"
    )
    assert slot0(program).eeprom == slot0("PAUSE 3\n").eeprom
    assert error("#ELSE\n") == (193, 3, 1)
    assert error("#IF B0 #THEN\n#ENDIF\n") == (195, 3, 5)
    assert error("#IF 1 + ~2 #THEN\n#ENDIF\n")[0] == 189


def test_pbasic_version_and_port_as_constants() -> None:
    s = slot0("v CON $PBASIC\nm CON BS2SX\nPAUSE v + m\nEND\n")
    assert s.eeprom == slot0("PAUSE 250 + 4\nEND\n").eeprom  # not folded at run time


# ---- number reading, DATA tables (bulk path) and the run-time stack model -----------------
@pytest.mark.parametrize(
    ("text", "base", "decimals", "expected"),
    [
        (b"123 ", 10, 0, (123, 3)),
        (b"FFFF", 16, 0, (0xFFFF, 4)),
        (b"0000000000000001 ", 2, 0, (1, 16)),
        (b"2.5}", 10, 2, (250, 3)),
        (b"2}", 10, 2, (200, 1)),
        (b"65536", 10, 0, 109),
        (b"00000000000000001", 10, 0, 108),
        (b"99999999999999999", 10, 0, 109),  # too big wins over too long
        (b"0.5", 10, 2, 186),
        (b"G", 16, 0, 104),
        (b"2", 2, 0, 105),
    ],
)
def test_read_number(text: bytes, base: int, decimals: int, expected: object) -> None:
    from bstool.tokenizer.diagnostics import Failure
    from bstool.tokenizer.lexer import read_number

    src = text + b"\x03"
    if isinstance(expected, int):
        with pytest.raises(Failure) as info:
            read_number(src, 0, base, 0, decimals)
        assert info.value.code == expected
    else:
        assert read_number(src, 0, base, 0, decimals) == expected


def test_data_table_bulk_path_matches_item_by_item() -> None:
    """A long continued DATA list (read in bulk) stores what one DATA line per item stores."""
    values = [(i * 37) % 256 for i in range(600)]
    items = [f"${v:02X}" if i % 3 else str(v) for i, v in enumerate(values)]
    lines = ", ".join(items).replace(", $1", ",\n  $1").replace(", 2", ", ' note\n   2")
    bulk = slot0(f"T DATA {lines}\nREAD T, B0\n")
    single = slot0("".join(f"DATA {item}\n" for item in items) + "READ 0, B0\n")
    assert bulk.eeprom == single.eeprom and bulk.data_bytes == len(values) == single.data_bytes


def test_data_table_bulk_path_errors_point_at_the_item() -> None:
    table = ", ".join(["1"] * 20)
    assert error(f"DATA {table}\nDATA @5, {table}\n") == (115, 4, 10)
    assert error(f"DATA @2040, {table}\n") == (114, 3, 37)
    assert error("DATA 1, 2, 70000, 3\n") == (109, 3, 12)


def test_stack_effect_of_items() -> None:
    from bstool.tokenizer.expressions import _STACK_EFFECT

    assert _STACK_EFFECT[T.Unary.ABS] == 0  # unary: replaces the top
    assert _STACK_EFFECT[T.Binary.ADD] == -1 and _STACK_EFFECT[T.Binary.EQ] == -1
    assert _STACK_EFFECT[T.CONSTANT_ITEM | 5] == 1  # constant pushes
    assert _STACK_EFFECT[0x33] == 1 and _STACK_EFFECT[0x37] == 0  # read / indexed read
    assert _STACK_EFFECT[0x3B] == 0 and _STACK_EFFECT[0x3F] == -1  # write / indexed write
    assert error("B0 = 1 + (2 + (3 + (4 + (5 + (6 + (7 + (8 + 9)))))))\n")[0] == 144
