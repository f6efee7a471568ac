"""Property tests: the interpreter's expression evaluation against a plain Python model of the
BS2's 16-bit unsigned, strictly postfix (left-to-right) arithmetic.

The model below is written from bs2sx.md §3 and the BS2 manuals' operator descriptions, not
from hil_mock/stamp/arith.py; where the manuals are silent it encodes the choices documented
in docs/twin.md (x / 0 = $FFFF, x // 0 = x, shifts of 16+ give 0, HYP/ATN on signed low bytes,
SIN = round(127 sin)).
"""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st
from interpreter_asm import Asm, const, op, var

from bstool.tokenizer.tokens import Binary, Unary, VarSize
from hil_mock.stamp import SimpleEeprom, Stamp

M = 0xFFFF


def _sb(v: int) -> int:
    v &= 0xFF
    return v - 256 if v >= 128 else v


def _sin(a: int) -> int:
    return round(127 * math.sin(2 * math.pi * (a & 255) / 256)) & M


def _isqrt(v: int) -> int:
    r = 0
    while (r + 1) * (r + 1) <= v:
        r += 1
    return r


def _rev(a: int, b: int) -> int:
    bits = format(a, "016b")[::-1][: min(b, 16)]
    return int(bits, 2) if bits else 0


def _atn(a: int, b: int) -> int:
    x, y = _sb(a), _sb(b)
    return 0 if x == y == 0 else round(math.degrees(math.atan2(y, x)) * 256 / 360) & 255


UNARY_MODEL = {
    Unary.SQR: lambda a: _isqrt(a),
    Unary.ABS: lambda a: (65536 - a) & M if a >= 32768 else a,
    Unary.NOT: lambda a: M - a,
    Unary.NEG: lambda a: (65536 - a) & M,
    Unary.DCD: lambda a: 2 ** (a % 16),
    Unary.NCD: lambda a: 0 if a == 0 else len(bin(a)) - 2,
    Unary.COS: lambda a: _sin(a + 64),
    Unary.SIN: _sin,
}
BINARY_MODEL = {
    Binary.HYP: lambda a, b: _isqrt(_sb(a) ** 2 + _sb(b) ** 2),
    Binary.ATN: _atn,
    Binary.AND: lambda a, b: a & b,
    Binary.OR: lambda a, b: a | b,
    Binary.XOR: lambda a, b: a ^ b,
    Binary.MIN: lambda a, b: max(a, b),
    Binary.MAX: lambda a, b: min(a, b),
    Binary.ADD: lambda a, b: (a + b) % 65536,
    Binary.SUB: lambda a, b: (a - b) % 65536,
    Binary.MULMID: lambda a, b: (a * b // 256) % 65536,
    Binary.MUL: lambda a, b: (a * b) % 65536,
    Binary.MULHIGH: lambda a, b: (a * b) // 65536,
    Binary.MOD: lambda a, b: a % b if b else a,
    Binary.DIV: lambda a, b: a // b if b else M,
    Binary.DIG: lambda a, b: int(str(a).zfill(5)[-1 - b]) if b < 5 else 0,
    Binary.SHL: lambda a, b: (a * 2**b) % 65536 if b < 16 else 0,
    Binary.SHR: lambda a, b: a // 2**b if b < 16 else 0,
    Binary.REV: _rev,
    Binary.GE: lambda a, b: M if a >= b else 0,
    Binary.LE: lambda a, b: M if a <= b else 0,
    Binary.EQ: lambda a, b: M if a == b else 0,
    Binary.NE: lambda a, b: M if a != b else 0,
    Binary.GT: lambda a, b: M if a > b else 0,
    Binary.LT: lambda a, b: M if a < b else 0,
}

# RAM preset: W3..W5 hold test words; byte 12, nib 26, bit 216 are read as small variables
LEAVES = st.one_of(
    st.integers(0, M).map(lambda v: ("const", v)),
    st.sampled_from([("w", 3), ("w", 4), ("w", 5), ("b", 12), ("n", 26), ("t", 216)]),
)


def trees(depth: int = 4) -> st.SearchStrategy[tuple]:
    return st.recursive(
        LEAVES,
        lambda sub: st.one_of(
            st.tuples(st.just("un"), st.sampled_from(list(Unary)), sub),
            st.tuples(st.just("bin"), st.sampled_from(list(Binary)), sub, sub),
        ),
        max_leaves=6,
    )


SIZES = {"w": VarSize.WORD, "b": VarSize.BYTE, "n": VarSize.NIB, "t": VarSize.BIT}


def postfix(tree: tuple) -> list[tuple]:
    kind = tree[0]
    if kind == "const":
        return [const(tree[1])]
    if kind in SIZES:
        return [var(SIZES[kind], tree[1])]
    if kind == "un":
        return [*postfix(tree[2]), op(tree[1])]
    return [*postfix(tree[2]), *postfix(tree[3]), op(tree[1])]


def depth(tree: tuple) -> int:
    """Evaluation-stack depth the postfix form needs (the stamp holds 8)."""
    if tree[0] == "un":
        return depth(tree[2])
    if tree[0] == "bin":
        return max(depth(tree[2]), depth(tree[3]) + 1)
    return 1


def model(tree: tuple, ram: bytes) -> int:
    kind = tree[0]
    if kind == "const":
        return int(tree[1])
    if kind == "w":
        return ram[2 * tree[1]] + 256 * ram[2 * tree[1] + 1]
    if kind == "b":
        return ram[tree[1]]
    if kind == "n":
        return (ram[tree[1] // 2] >> (4 * (tree[1] % 2))) % 16
    if kind == "t":
        return (ram[tree[1] // 8] >> (tree[1] % 8)) % 2
    if kind == "un":
        return int(UNARY_MODEL[tree[1]](model(tree[2], ram)))
    return int(BINARY_MODEL[tree[1]](model(tree[2], ram), model(tree[3], ram)))


def run_assignment(items: list[tuple], target: tuple, preset: bytes) -> Stamp:
    a = Asm()
    a.let(items, target)
    a.end()
    s = Stamp(SimpleEeprom([a.image()]))
    s.ram[6:32] = preset[6:32]
    s.run()
    return s


@settings(max_examples=150, deadline=None)
@given(tree=trees(), preset=st.binary(min_size=32, max_size=32))
def test_expressions_match_16_bit_model(tree: tuple, preset: bytes) -> None:
    if depth(tree) > 8:
        return
    s = run_assignment(postfix(tree), var(VarSize.WORD, 6, write=True), preset)
    assert s.memory.word(6) == model(tree, preset)


@settings(max_examples=100, deadline=None)
@given(
    value=st.integers(0, M),
    size=st.sampled_from(list(VarSize)),
    index=st.integers(0, 15),
    preset=st.binary(min_size=32, max_size=32),
)
def test_store_keeps_low_bits_and_neighbours(
    value: int, size: VarSize, index: int, preset: bytes
) -> None:
    """Storing into a smaller variable keeps the low bits; other RAM is untouched."""
    target = {VarSize.WORD: 3 + index % 13, VarSize.BYTE: 6 + index}.get(size, 48 + index)
    s = run_assignment([const(value)], var(size, target, write=True), preset)
    expect = bytearray(preset)
    expect[:6] = bytes(s.ram[:6])
    width = {VarSize.WORD: 16, VarSize.BYTE: 8, VarSize.NIB: 4, VarSize.BIT: 1}[size]
    bit0 = target * width
    for k in range(width):
        byte, bit = divmod(bit0 + k, 8)
        if (value >> k) & 1:
            expect[byte] |= 1 << bit
        else:
            expect[byte] &= ~(1 << bit) & 0xFF
    assert bytes(s.ram) == bytes(expect)


@settings(max_examples=100, deadline=None)
@given(
    index=st.integers(0, M),
    value=st.integers(0, M),
    size=st.sampled_from(list(VarSize)),
    preset=st.binary(min_size=32, max_size=32),
)
def test_indexed_variables_wrap_in_the_register_file(
    index: int, value: int, size: VarSize, preset: bytes
) -> None:
    """arr(i) = arr(i): an indexed read and write address base + i, wrapped to the file."""
    base = {VarSize.WORD: 4, VarSize.BYTE: 8, VarSize.NIB: 16, VarSize.BIT: 64}[size]
    count = {VarSize.WORD: 16, VarSize.BYTE: 32, VarSize.NIB: 64, VarSize.BIT: 256}[size]
    items = [const(index), var(size, base, indexed=True)]  # push arr(index)
    s = run_assignment(items, var(VarSize.WORD, 3, write=True), preset)
    slot = (base + index) % count
    kind = {VarSize.WORD: "w", VarSize.BYTE: "b", VarSize.NIB: "n", VarSize.BIT: "t"}[size]
    ram = bytearray(preset)
    ram[:6] = bytes(6)
    assert s.memory.word(3) == model((kind, slot), bytes(ram))


def test_left_to_right_without_precedence() -> None:
    """`a + b * 2` is tokenized as a b + 2 *: the interpreter just follows the postfix."""
    preset = bytearray(32)
    preset[6:10] = bytes([0xD2, 0x04, 0x38, 0x00])  # W3 = 1234, W4 = 56
    items = [var(VarSize.WORD, 3), var(VarSize.WORD, 4), op(Binary.ADD), const(2), op(Binary.MUL)]
    s = run_assignment(items, var(VarSize.WORD, 5, write=True), bytes(preset))
    assert s.memory.word(5) == 2580


def test_comparison_is_ffff_so_not_negates() -> None:
    """IF NOT a = 3 works because a true comparison is $FFFF and ~$FFFF = 0."""
    items = [const(3), const(3), op(Binary.EQ), op(Unary.NOT)]
    s = run_assignment(items, var(VarSize.WORD, 5, write=True), bytes(32))
    assert s.memory.word(5) == 0
