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
