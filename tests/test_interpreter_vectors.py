"""Run the tokenizer vectors' EEPROM images (Parallax's tokens) on the interpreter.

Expected values are worked out by hand from each .bsx source with BS2 semantics (16-bit
unsigned, strictly left to right); the comment on each value shows the derivation. RAM
addresses follow the VAR allocation rule of bs2sx.md §4 (words from W0 = word 3, then bytes,
nibs, bits).
"""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest

from hil_mock.eeprom import Eeprom
from hil_mock.stamp import NotInTwin, SimpleEeprom, Stamp, Status
from hil_mock.stamp.decoder import decode_image

VECTORS = Path(__file__).resolve().parent / "vectors" / "tokenizer"  # copied from ../shared

pytestmark = pytest.mark.skipif(not VECTORS.is_dir(), reason="tests/vectors/tokenizer missing")


def load(name: str) -> Stamp:
    folder = VECTORS / name
    slots = []
    for n in range(8):
        f = folder / f"slot{n}.eeprom"
        if not f.exists():
            break
        slots.append(f.read_bytes())
    return Stamp(SimpleEeprom(slots), name=name)


def assignments(stamp: Stamp, max_steps: int = 100_000) -> list[bytes]:
    """RAM snapshot after every executed assignment (DONE), until the stamp stops."""
    snaps = []
    for _ in range(max_steps):
        if stamp.status is not Status.RUNNING:
            break
        ins = stamp.program.decoded.instructions.get(stamp.pc)
        stamp.step()
        if ins is not None and ins.name == "DONE":
            snaps.append(bytes(stamp.ram))
    return snaps


def W(k: int):  # register-file notation
    return lambda ram: ram[2 * k] | ram[2 * k + 1] << 8


def B(j: int):
    return lambda ram: ram[j]


def N(n: int):
    return lambda ram: (ram[n >> 1] >> 4 * (n & 1)) & 15


def check_sequence(snaps: list[bytes], expected: list[tuple[object, int]]) -> None:
    assert len(snaps) == len(expected)
    for k, (snap, (reader, value)) in enumerate(zip(snaps, expected, strict=True)):
        assert reader(snap) == value, f"assignment {k + 1}"  # type: ignore[operator]


def test_ops_binary_arith() -> None:
    # a = W3, b = W4, c = W5, d = byte 12
    s = load("ops_binary_arith")
    a, b, c, d = W(3), W(4), W(5), B(12)
    check_sequence(
        assignments(s),
        [
            (a, 1234),
            (b, 56),
            (c, 1283),  # 1234 + 56 - 7
            (c, 3568),  # 1234 * 56 = 69104, low 16 bits = 69104 - 65536
            (c, 1),  # 69104 >> 16
            (c, 1851),  # 1234 * 384 >> 8 = 473856 / 256
            (c, 22),  # 1234 / 56
            (c, 2),  # 1234 - 22 * 56
            (c, 2000),  # 1234 MIN 2000: not below 2000
            (c, 40),  # 56 MAX 40: not above 40
            (d, 2),  # digit 2 of 1234
            (c, 5),  # 3 HYP 4
            (c, 32),  # 100 ATN 100 = 45 degrees = 32 brads
            (c, 2580),  # (1234 + 56) * 2
            (c, 1346),  # 1234 + 112
            (c, 168),  # 1178 / (56 // 10 + 1 = 7) = 168; MAX 500 MIN 10 keep it
            (c, 2387),  # 1234 * 50000 >> 16 = 941; 1234 * 300 >> 8 = 1446
            (d, 9),  # ((2387 DIG 0) + 2387) DIG 1 = 2394 DIG 1
            (c, 85),  # atan2(35, -20) = 119.74 deg * 256 / 360 = 85.2 brads
            (c, 36),  # low bytes signed: 1234 -> -46, 56: sqrt(5252) = 72.5 -> 72; / 2
            (c, 5),  # 1234 = %...0010, REV 4 = %0100 = 4; + 1
        ],
    )
    assert s.status is Status.ENDED


def test_ops_unary() -> None:
    # valA = W3, valB = W4, ang = byte 10, bitNo = nib 22
    s = load("ops_unary")
    va, vb, ang, bit_no = W(3), W(4), B(10), N(22)
    check_sequence(
        assignments(s),
        [
            (va, 100),  # SQR 10000
            (vb, 30),  # (SQR 100) * 3
            (va, 300),  # ABS (-300)
            (vb, 200),  # ABS (100 - 500 = 65336) = 200
            (va, 65335),  # ~200
            (vb, 201),  # -65335 mod 65536
            (va, 65533),  # (-5) + 2
            (bit_no, 10),  # NCD 1000: highest bit is bit 9
            (vb, 1024),  # DCD 10
            (va, 32767),  # (DCD 15) - 1
            (ang, 127),  # COS 0
            (ang, 127),  # SIN 64
            (va, 0),  # SIN 127 = round(127 sin 178.6 deg) = 3; COS 191 = SIN 255 = -3
            (vb, 125),  # SIN 200 = round(127 sin 281.25 deg) = -125; ABS
            (va, 4),  # SQR ABS -16
            (vb, 125),  # ~~125
            (va, 8),  # NCD DCD 7 = NCD 128
        ],
    )


def test_mods_aliases() -> None:
    # packed = W3 (bytes 6, 7), status = byte 8
    s = load("mods_aliases")
    packed, status = W(3), B(8)
    check_sequence(
        assignments(s),
        [
            (packed, 0xABCD),
            (status, 0xAB),  # hiPart
            (status, 0xAA),  # code (low nib) = NIB3 of packed = $A
            (status, 0xCA),  # other (high nib) = NIB1 = $C
            (status, 0xCA),  # ready (bit 7) = BIT15 = 1, already set
            (packed, 0xABCC),  # flagA (BIT0) = status.LOWBIT = 0
            (packed, 0xAB77),  # copy (low byte) = $AB + $CC = $177 -> $77
            (status, 0xCA),  # status.BIT3 = packed.HIGHBIT = 1, already set
            (packed, 0xAC77),  # NIB2 = status.HIGHNIB = $C
            (packed, 0xAD77),  # BIT8 = ~0 -> 1
            (status, 3),  # bits 4..7 of $77: 1 + 1 + 1 + 0
            (packed, 0xADAD),  # LOWBYTE = HIGHBYTE
            (packed, 0xADA3),  # NIB0 = code = 3
            (packed, 0xA0A3),  # NIB0(2) = nibble 2 of packed = other = 0
        ],
    )
    assert s.status is Status.ENDED  # ready = 0: the IF does not clear packed


def test_vars_sizes_arrays() -> None:
    # ww = W3, wa = W4..W6, bb = byte 14, ba = bytes 15..19, nn = nib 40, na = nibs 41..46,
    # i = nib 47, tt = bit 192, ta = bits 193..202
    s = load("vars_sizes_arrays")
    s.run()
    m = s.memory
    assert s.status is Status.ENDED
    assert m.word(3) == 3021  # 7 + 1007 + 2007
    assert [m.word(k) for k in (4, 5, 6)] == [17, 1007, 2007]  # wa(i) = i*1000+7, then wa = 17
    assert [m.byte(j) for j in range(15, 20)] == [0, 62, 125, 0, 62]  # wa(i//3) >> 4
    assert m.byte(14) == 0  # bb = ba(ba(0) // 5) = ba(0)
    # na(i) = ba(i//5) & 15 -> 0 14 13 0 14 0, then ba(7) = 1 overwrites byte 22 (nibs 44, 45)
    assert [m.nib(n) for n in range(41, 47)] == [0, 14, 13, 1, 0, 0]
    assert m.nib(47) == 10  # i after FOR i = 0 TO 9: 9 + 1
    # nn = na((5 - 10) // 6) = na(65531 // 6 = 10921): nib (41 + 10921) mod 64 = 18 = 0
    assert m.nib(40) == 0
    ta = [m.bit(i) for i in range(193, 203)]
    assert ta == [0, 0, 1, 0, 0, 0, 0, 0, 1, 0]  # na(i//6) & 1
    assert m.bit(192) == 0  # ta(9) ^ ta(0)


def test_for_next_steps() -> None:
    # k = W3, total = W4, i = byte 10, lim = byte 11
    s = load("for_next_steps")
    s.run()
    m = s.memory
    # total: 0+..+9 = 45; - (10+8+6+4+2+0) = 15; + 9 passes (20..60 step 5) = 24;
    # ^ 16 values $FF0F | n<<4 XOR to 0 -> 24
    assert m.word(4) == 24
    assert m.word(3) == 0xFF00 - 1  # k: $FFFF down by $10 past $FF00 -> $FEFF
    assert m.byte(10) == 0  # i after FOR i = 5 TO 1 (counts down): 1 - 1
    assert m.byte(11) == 20
    assert m.outs == m.dirs == 0b111110  # TOGGLE 5..1 from low inputs
    # PAUSE k/100 for k = 1000, 850, ..., 100: 10+8+7+5+4+2+1 = 37 ms
    assert 37e-3 < s.time < 60e-3


def test_for_next_counter_values() -> None:
    """The counter ends one step past the limit; counting below 0 ends the loop."""
    s = load("for_next_steps")
    seen = []
    while s.status is Status.RUNNING:
        ins = s.program.decoded.instructions.get(s.pc)
        s.step()
        if ins is not None and ins.name == "NEXT":
            seen.append(s.memory.byte(10))
    assert seen[:10] == list(range(1, 11))  # FOR i = 0 TO 9: i = 10 after the loop
    assert seen[10:16] == [8, 6, 4, 2, 0, 254]  # 10 TO 0 STEP 2: -2 ends it, stored as 254


def test_if_block_chain() -> None:
    # temp = byte 6, state = nib 14, alarm = bit 60; halts when temp > 240 sets alarm
    s = load("if_block_chain")
    s.run()
    m = s.memory
    assert m.byte(6) == 245  # 7 * 35, the first multiple of 7 above 240
    assert m.nib(14) == 3
    assert m.bit(60) == 1
    assert m.outs == m.dirs == 1 << 9  # HIGH 9


def test_do_loop_conditions() -> None:
    # cnt = W3, limit = byte 8; 12, 0, 30, 10 (28..10 step -2), then +6 while cnt & 15
    s = load("do_loop_conditions")
    s.run()
    assert s.memory.word(3) == 16
    assert s.memory.byte(8) == 6  # 12 - 6
    assert s.memory.outs == 1 << 3  # one TOGGLE 3: IN4 reads 0 and EXITs


def test_lookup_lookdown_ops() -> None:
    # out = W3, value = byte 8, pos = nib 18
    s = load("lookup_lookdown_ops")
    positions = []
    while s.status is Status.RUNNING:
        ins = s.program.decoded.instructions.get(s.pc)
        s.step()
        if ins is not None and ins.name == "LOOKDOWN":
            positions.append(s.memory.nib(18))
    # value = 42: [10,20,42,80] -> 2; =[42,43] -> 0; <>[42,0,1] -> 1; ><[1,42] -> 0;
    # >[100,50,40,30] -> 2; <[5,10,50] -> 2; >=[90,42,10] -> 1; =>[90,43,10] -> 2;
    # <=[10,42] -> 1; =<[41,99] -> 1; 84 in ["A","T","U"] -> 1
    assert positions == [2, 0, 1, 0, 2, 2, 1, 2, 1, 1, 1]
    assert s.memory.word(3) == 42  # LOOKUP 1 -> 2000; LOOKUP 2, [out, out*2, value, ..] -> 42


def test_read_write_words() -> None:
    # w = W3, ws = W4..W6, b = byte 14, i = nib 30; Cal at 0 (1875 1250 2500), Store at 6
    ee_folder = VECTORS / "read_write_words"
    ee = SimpleEeprom([(ee_folder / "slot0.eeprom").read_bytes()])
    s = Stamp(ee)
    s.run()
    m = s.memory
    assert [m.word(k) for k in (3, 4, 5, 6)] == [2500, 1875, 1250, 2500]
    assert m.byte(14) == 0 and m.nib(30) == 3
    # Store: w=1875, ws(2)=2500, b=0, $1234 (low byte kept), then ws(i)+1 from Store+6 = 12
    assert bytes(ee.slots[0][6:18]) == bytes(
        [0x53, 0x07, 0xC4, 0x09, 0x00, 0x34, 0x54, 0x07, 0xE3, 0x04, 0xC5, 0x09]
    )
    assert s.time > 12 * 5e-3  # 12 EEPROM writes


def test_getput_scratchpad() -> None:
    # visits = W3, first = byte 8, second = byte 9, slot = nib 20
    s = load("getput_scratchpad")
    s.run()
    assert bytes(s.debug) == b"slot 0 visits 0\r"
    sp = s.memory.scratch
    assert list(sp[:5]) == [1, 0, 0, 7, 1]  # visits = 1; slot, 7, first + 1
    assert sp[62] == 255 and sp[63] == 0
    assert s.memory.byte(9) == 7  # second
    s.reset()  # the scratchpad survives a reset: visits counts on
    s.run()
    assert list(s.memory.scratch[:2]) == [2, 0]


def test_flow_goto_gosub() -> None:
    # counter = byte 6, depth = nib 14: Outer/Inner/Leaf nest 3 deep, counter += 3 per Outer;
    # counter is reset at Start, so the program loops forever between Start and the IF
    s = load("flow_goto_gosub")
    names = []
    for _ in range(40):
        ins = s.program.decoded.instructions[s.pc]
        names.append(ins.name)
        s.step()
        if ins.name == "IF":
            break
    assert names.count("GOSUB") == 6 and names.count("RETURN") == 6
    assert s.memory.byte(6) == 6 and s.memory.nib(14) == 0
    s.run(seconds=0.5)
    assert s.status is Status.RUNNING and s.memory.nib(14) == 0


def test_io_pin_commands() -> None:
    # pinNo = nib 12, level = bit 52
    s = load("io_pin_commands")
    s.run()
    m = s.memory
    assert m.dirs == 0b0000_1111_0110_1001  # 0 3 5 6 8-11 (1 INPUT, 14 and 15 inputs)
    assert m.outs == (1 << 14) | (1 << 10)  # TOGGLE 14, OUT5 = level ^ 1 = 0, TOGGLE 10
    assert m.bit(52) == 1  # level = IN5 while HIGH 5
    assert m.nib(12) == 12


def test_const_expressions() -> None:
    s = load("const_expressions")
    s.run()
    pulses = s.io.pulses  # type: ignore[attr-defined]
    # pulse = 1250 + idx * 78 - 25 for idx = 0..15, PULSOUT 12 in 0.8 us units, high pulses
    assert [(p[0], p[2], p[3]) for p in pulses] == [
        (12, (1225 + 78 * i) * 800, 1) for i in range(16)
    ]
    # 4095 + 61440 + 3840 + 42 = 69417 -> 3881 (mod 65536)
    assert s.memory.word(3) == 3881
    serial = s.io.serial  # type: ignore[attr-defined]
    assert bytes(b for _, b, _, _ in serial) == b"3881"
    assert {(p, m) for p, _, _, m in serial} == {(15, 240 | 0x4000)}


def test_data_directives() -> None:
    s = load("data_directives")
    s.run()
    assert bytes(s.debug) == b"Hello\r"
    assert s.memory.word(3) == 200 and s.memory.byte(8) == 9  # Word Tail = 200; READ Tail


def test_serout_formatters_until_flow_pin() -> None:
    s = load("serout_formatters")
    with pytest.raises(NotInTwin, match="SEROUT_FLOW"):
        s.run()
    out = bytes(b for _, b, _, _ in s.io.serial)  # type: ignore[attr-defined]
    # n = -1234 = 64302 = $FB2E = %1111101100101110
    assert out == (
        b"Raw: AB\r"
        b"64302 -1234 FB2E 1111101100101110\r"
        b"302" b"64302" b"-34" b"2E" b"-04D2" b"$FB2E" b"-$4D2"
        b"00101110" b"-10011010010" b"%1110" b"-%0000010011010010" b"2" b"E"
        + bytes(8) + b"-" * 10 + b"\r\n"
        b"paced"
    )  # fmt: skip
    paced = [t for _, b, t, m in s.io.serial if m == 1021 + 0x4000]  # type: ignore[attr-defined]
    # 2400 baud: 4.164 ms per byte, plus the 5 ms pace between bytes
    assert [b - a for a, b in itertools.pairwise(paced)] == [4_164_000 + 5_000_000] * 4


@pytest.mark.parametrize(
    ("name", "what"),
    [("timing_sound", "FREQOUT"), ("pulse_measure", "PULSIN"), ("shift_modes", "SHIFTOUT")],
)
def test_unmodelled_instructions_raise(name: str, what: str) -> None:
    s = load(name)
    with pytest.raises(NotInTwin, match=what):
        s.run(seconds=100)


def test_debug_bytes_take_their_time_on_the_wire() -> None:
    """DEBUG = SEROUT on pin 16 at baudmode 240 (9600 baud): 10 bits = 1.04 ms per byte."""
    s = load("getput_scratchpad")
    s.run()
    serial = s.io.serial  # type: ignore[attr-defined]
    assert {(p, m) for p, _, _, m in serial} == {(16, 240)}
    starts = [t for _, _, t, _ in serial]
    assert len(starts) == len(b"slot 0 visits 0\r")
    assert [b - a for a, b in itertools.pairwise(starts)] == [1_040_000] * (len(starts) - 1)


def test_if_single_compare_first_passes() -> None:
    # hits = W3, a = byte 8, b = byte 9: with a = b = 0 every pass takes Equal (hits + 10),
    # Back1 (0 >< 7), then Back2: a <= 100 -> Small: a = a * 2 = 0 -> Top, forever
    s = load("if_single_compare")
    for passes in range(1, 6):
        while True:
            ins = s.program.decoded.instructions[s.pc]
            s.step()
            if ins.name == "DONE" and s.memory.word(3) == 10 * passes:
                break
        assert s.memory.byte(8) == 0 and s.memory.byte(9) == 0
    s.run(seconds=1)
    assert s.status is Status.RUNNING and s.memory.word(3) % 10 == 0


def test_every_vector_image_decodes() -> None:
    """All code reachable in every vector image decodes; only instructions whose inline layout
    the twin does not model (DTMFOUT, BUTTON) stop the walk."""
    images = sorted(VECTORS.glob("*/slot*.eeprom"))
    assert len(images) >= 25
    for path in images:
        decoded = decode_image(path.read_bytes())
        unknown = {i.name for i in decoded.instructions.values() if i.unknown}
        assert unknown <= {"DTMFOUT", "BUTTON"}, path


def test_runs_from_the_hil_mock_eeprom_store() -> None:
    """The interpreter reads and writes hil_mock.eeprom.Eeprom (slot()/write()) directly."""
    ee = Eeprom()
    ee.load_slot(0, (VECTORS / "read_write_words" / "slot0.eeprom").read_bytes())
    s = Stamp(ee)
    s.run()
    assert s.memory.word(3) == 2500
    assert ee.slot(0)[6:8] == bytes([0x53, 0x07])  # WRITE Store, Word w (1875)
