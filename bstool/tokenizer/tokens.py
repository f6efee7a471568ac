"""The BS2sx token format, defined once.

The tokenizer (which writes tokens) and hil_mock's interpreter (which reads them) both import
this module, so the two can never disagree about a code or a field width. Facts from
../shared/reference/bs2sx.md §5-§6.
"""

from __future__ import annotations

from enum import IntEnum

# ---- image layout -------------------------------------------------------------------------
SLOT_BYTES = 2048  # one EEPROM slot
SLOTS = 8  # BS2sx: 8 slots of 2048 bytes
BLOCK_BYTES = 16  # one download record carries one 16-byte block
RECORD_BYTES = 18  # [0x80 + block][16 bytes][check]
RECORD_HEADER_BASE = 0x80
ADDRESS_BITS = 14  # code addresses are bit positions 0..16383
MAX_GOSUBS = 255
RAM_VARIABLE_BYTES = 26  # 32 bytes of RAM less INS/OUTS/DIRS
SCRATCHPAD_BYTES = 64

# ---- field widths -------------------------------------------------------------------------
ITEM_BITS = 6  # every expression item and instruction code is 6 bits
INSTRUCTION_BITS = 6
VARIABLE_INDEX_BITS = {0: 8, 1: 6, 2: 5, 3: 4}  # by VarSize: bit, nib, byte, word
GOSUB_ID_BITS = 8
COMPARE_BITS = 3  # LOOKDOWN comparison field


class VarSize(IntEnum):
    """The S field of a variable item."""

    BIT = 0
    NIB = 1
    BYTE = 2
    WORD = 3


class Unary(IntEnum):
    """Expression items $00-$07: unary operators (apply to the top of the stack)."""

    SQR = 0x00
    ABS = 0x01
    NOT = 0x02  # ~ (bitwise NOT; also NOT in conditions)
    NEG = 0x03  # unary -
    DCD = 0x04
    NCD = 0x05
    COS = 0x06
    SIN = 0x07


class Binary(IntEnum):
    """Expression items $08-$1F: binary operators and comparisons (pop right, then left)."""

    HYP = 0x08
    ATN = 0x09
    AND = 0x0A  # &  (also AND in conditions)
    OR = 0x0B  # |  (also OR)
    XOR = 0x0C  # ^  (also XOR)
    MIN = 0x0D
    MAX = 0x0E
    ADD = 0x0F
    SUB = 0x10
    MULMID = 0x11  # */
    MUL = 0x12  # *
    MULHIGH = 0x13  # **
    MOD = 0x14  # //
    DIV = 0x15  # /
    DIG = 0x16
    SHL = 0x17  # <<
    SHR = 0x18  # >>
    REV = 0x19
    GE = 0x1A
    LE = 0x1B
    EQ = 0x1C
    NE = 0x1D
    GT = 0x1E
    LT = 0x1F


CONSTANT_ITEM = 0x20  # $20 + n, n = index of highest 1 bit; then flag bit and n low bits
VARIABLE_ITEM = 0x30  # $30 + 8*W + 4*I + S, then the index field
VARIABLE_WRITE_FLAG = 0x08  # W: pop a value and store it
VARIABLE_INDEXED_FLAG = 0x04  # I: index taken from the stack


class Instruction(IntEnum):
    """6-bit BS2sx instruction codes (after the 0 bit that ends the argument items)."""

    END = 0x00
    SLEEP = 0x01
    NAP = 0x02
    STOP = 0x03
    OUTPUT = 0x04
    HIGH = 0x05
    TOGGLE = 0x06
    LOW = 0x07
    REVERSE = 0x08
    GOTO = 0x09
    GOSUB = 0x0A
    RETURN = 0x0B
    INPUT = 0x0C
    IF = 0x0D
    NEXT = 0x0E
    BRANCH = 0x0F
    LOOKUP = 0x10
    LOOKDOWN = 0x11
    RANDOM = 0x12
    READ = 0x13
    WRITE = 0x14
    PAUSE = 0x15
    FREQOUT1 = 0x16
    FREQOUT2 = 0x17
    DTMFOUT = 0x18
    XOUT = 0x19
    GET = 0x1A
    PUT = 0x1B
    RUN = 0x1C
    DONE = 0x1D  # closes an assignment `v = e`
    SEROUT = 0x20
    SEROUT_FLOW = 0x21
    SERIN = 0x22
    SERIN_FLOW = 0x23
    PULSOUT = 0x24
    PULSIN = 0x25
    COUNT = 0x26
    SHIFTIN = 0x27
    SHIFTOUT = 0x28
    RCTIME = 0x29
    BUTTON = 0x2A
    PWM = 0x2B


class LookdownCompare(IntEnum):
    """3-bit comparison field of LOOKDOWN."""

    GE = 2
    LE = 3
    EQ = 4
    NE = 5
    GT = 6
    LT = 7


# ---- fixed register names (word / byte / nib / bit indices) -------------------------------
WORD_REGISTERS = {"INS": 0, "OUTS": 1, "DIRS": 2, **{f"W{i}": 3 + i for i in range(13)}}
BYTE_REGISTERS = {
    "INL": 0, "INH": 1, "OUTL": 2, "OUTH": 3, "DIRL": 4, "DIRH": 5,
    **{f"B{i}": 6 + i for i in range(26)},
}  # fmt: skip
NIB_REGISTERS = {
    **{f"IN{c}": i for i, c in enumerate("ABCD")},
    **{f"OUT{c}": 4 + i for i, c in enumerate("ABCD")},
    **{f"DIR{c}": 8 + i for i, c in enumerate("ABCD")},
}
BIT_REGISTERS = {
    **{f"IN{i}": i for i in range(16)},
    **{f"OUT{i}": 16 + i for i in range(16)},
    **{f"DIR{i}": 32 + i for i in range(16)},
}
FIRST_USER_WORD = 3  # VAR allocation starts at word 3 (W0)

# ---- timing units on the BS2sx ------------------------------------------------------------
PULSOUT_UNIT_US = 0.8
PAUSE_UNIT_MS = 1.0
SERIN_TIMEOUT_UNIT_MS = 0.4
DEBUG_BAUDMODE = 240  # DEBUG = SEROUT on pin 16 at 9600 baud
SERIAL_PIN = 16  # SIN/SOUT
BAUD_CLOCK = 2_500_000  # baudmode bits 0-11 = INT(2.5e6 / baud) - 20
BAUD_OFFSET = 20


def baudmode_to_baud(mode: int) -> float:
    """Bit rate of a BS2sx baudmode (bits 0-11 only; parity/invert/open flags ignored)."""
    return BAUD_CLOCK / ((mode & 0x0FFF) + BAUD_OFFSET)


def constant_item_bits(value: int) -> int:
    """Bits of a constant item *including* its leading 1 bit (8 for 0 or a power of two)."""
    if value < 0 or value > 0xFFFF:
        raise ValueError(f"constant out of 16 bits: {value}")
    n = max(value.bit_length() - 1, 0)
    exact = value == 0 or value == 1 << n
    return 1 + ITEM_BITS + 1 + (0 if exact else n)


# ---- additions for the PBASIC 2.5 tokenizer (names above are stable; only add below) -------
CODE_START_BITS = ADDRESS_BITS  # bits 0-13: start address; then one return slot per GOSUB
LOOKDOWN_DEFAULT_COMPARE = LookdownCompare.EQ
EXPRESSION_STACK_DEPTH = 8  # run-time evaluation stack of the BS2sx
EXPRESSION_BUFFER_BITS = 496  # one argument expression may hold fewer bits than this
DEBUGIN_FLAG = 1  # DEBUGIN pushes 1 (no timeout) like a SERIN without labels
DTMF_DEFAULT_ON_MS = 200
DTMF_DEFAULT_OFF_MS = 50
SHIFT_DEFAULT_BITS = 8
XOUT_DEFAULT_CYCLES = 2
X10_KEY_BASE = 16  # XOUT encodes house\key as house // 16 + key * 16
LABEL_CONSTANT_PREFIX = 0xDD  # 1 + item $2E + flag 1: a 14-bit code address pushed as data
LABEL_CONSTANT_PREFIX_BITS = 8
SERIAL_ITEM_STRING = 0x0200  # STR var: OR-ed into the byte-variable index
SERIAL_ITEM_REPEAT = 0x0400  # REP value\count (output) / SKIP n (input)
SERIAL_ITEM_WAITSTR = 0x0800  # WAITSTR var (input); | 0x0200 when a length follows
SERIAL_ITEM_WAIT = 0x0C44  # WAIT(...) (input), followed by the count of values
SERIAL_STRING_DEFAULT = 32  # STR/WAITSTR without a length
SERIAL_INDICATED = 0x0800  # formatter flag: print the $ / % indicator (HEX?, BIN?)
ASCII_QUOTE = 0x22
ASCII_CR = 13


def number_formatter(
    base: str, digits: int | None = None, *, signed: bool = False, indicated: bool = False
) -> int:
    """Formatter word of DEC/HEX/BIN (with optional digit count, S and I prefixes).

    Layout: $100 always, $200 fixed digit count, $400 signed, $800 indicated, bits 4-7 hold
    16 minus the digit count (the maximum when none is given), bits 0-3 the base code.
    """
    base_code, max_digits = {"DEC": (0x6, 5), "HEX": (0x0, 4), "BIN": (0xE, 16)}[base]
    count = max_digits if digits is None else digits
    word = 0x100 | ((16 - count) & 0xF) << 4 | base_code
    if digits is not None:
        word |= 0x200
    if signed:
        word |= 0x400
    if indicated:
        word |= 0x800
    return word


def _formatters() -> dict[str, int]:
    table: dict[str, int] = {}
    for base, max_digits, prefixes in (
        ("DEC", 5, ("", "S")),
        ("HEX", 4, ("", "S", "I", "IS")),
        ("BIN", 16, ("", "S", "I", "IS")),
    ):
        for prefix in prefixes:
            for digits in (None, *range(1, max_digits + 1)):
                name = f"{prefix}{base}{'' if digits is None else digits}"
                table[name] = number_formatter(
                    base, digits, signed="S" in prefix, indicated="I" in prefix
                )
    return table


NUMBER_FORMATTERS: dict[str, int] = _formatters()  # DEC, DEC1.., SHEX2, ISBIN16, ...
ANY_NUMBER_FORMATTERS: dict[str, int] = {"NUM": 0x1106, "SNUM": 0x1506}  # input only

# Built-in constants of the language (value of the name in any expression).
BUILTIN_CONSTANTS: dict[str, int] = {
    "CLS": 0, "HOME": 1, "BELL": 7, "BKSP": 8, "TAB": 9, "CR": 13,
    "UNITON": 0x12, "UNITOFF": 0x1A, "UNITSOFF": 0x1C, "LIGHTSON": 0x14, "DIM": 0x1E,
    "BRIGHT": 0x16, "LSBFIRST": 0, "MSBFIRST": 1, "MSBPRE": 0, "LSBPRE": 1, "MSBPOST": 2,
    "LSBPOST": 3,
}  # fmt: skip
BUILTIN_CONSTANTS_25: dict[str, int] = {  # PBASIC 2.5 only
    "CRSRXY": 2, "CRSRLF": 3, "CRSRRT": 4, "CRSRUP": 5, "CRSRDN": 6, "LF": 10,
    "CLREOL": 11, "CLRDN": 12, "CRSRX": 14, "CRSRY": 15,
}  # fmt: skip

# Variable modifiers: name -> (size of the result, index within the variable).
# HIGH* name the last part of whatever size the variable has (index None).
VARIABLE_MODIFIERS: dict[str, tuple[VarSize, int | None]] = {
    **{f"BIT{i}": (VarSize.BIT, i) for i in range(16)},
    "LOWBIT": (VarSize.BIT, 0), "HIGHBIT": (VarSize.BIT, None),
    **{f"NIB{i}": (VarSize.NIB, i) for i in range(4)},
    "LOWNIB": (VarSize.NIB, 0), "HIGHNIB": (VarSize.NIB, None),
    "BYTE0": (VarSize.BYTE, 0), "BYTE1": (VarSize.BYTE, 1),
    "LOWBYTE": (VarSize.BYTE, 0), "HIGHBYTE": (VarSize.BYTE, None),
}  # fmt: skip
