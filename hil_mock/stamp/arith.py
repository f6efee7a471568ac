"""BS2 arithmetic on the 16-bit unsigned workspace (bs2sx.md §3).

Every function takes and returns ints in 0..65535. Where the manuals do not pin a result down
(division by zero, shift counts of 16 or more, HYP/ATN rounding, SIN table rounding) the choice
is written here and in docs/twin.md.
"""

from __future__ import annotations

import math

MASK = 0xFFFF
TRUE = 0xFFFF  # comparisons yield $FFFF / 0, so NOT (~) of a condition is its negation

# SIN of an 8-bit binary-radian angle: round(127 sin), stored as 16-bit two's complement.
SIN_TABLE: tuple[int, ...] = tuple(
    round(127 * math.sin(2 * math.pi * a / 256)) & MASK for a in range(256)
)


def sqr(a: int) -> int:
    return math.isqrt(a)


def abs16(a: int) -> int:
    return (-a) & MASK if a & 0x8000 else a


def ncd(a: int) -> int:
    """Priority encoder: 1 + index of the highest 1 bit, 0 for 0."""
    return a.bit_length()


def div(a: int, b: int) -> int:
    """Unsigned division; x / 0 = $FFFF (choice: the stamp has no divide trap)."""
    return a // b if b else MASK


def mod(a: int, b: int) -> int:
    """Unsigned remainder; x // 0 = x (choice, consistent with div)."""
    return a % b if b else a


def shl(a: int, b: int) -> int:
    return (a << b) & MASK if b < 16 else 0


def dig(a: int, b: int) -> int:
    """Decimal digit b of a (0 = ones); 0 beyond the fifth digit."""
    return (a // 10**b) % 10 if b < 5 else 0


def rev(a: int, b: int) -> int:
    """The lowest b bits of a in reverse order (b counted up to 16)."""
    n = min(b, 16)
    out = 0
    for _ in range(n):
        out = (out << 1) | (a & 1)
        a >>= 1
    return out


def _signed_byte(v: int) -> int:
    v &= 0xFF
    return v - 256 if v & 0x80 else v


def hyp(a: int, b: int) -> int:
    """Length of the vector (a, b), each the signed low byte (-128..127); truncated."""
    x, y = _signed_byte(a), _signed_byte(b)
    return math.isqrt(x * x + y * y)


def atn(a: int, b: int) -> int:
    """Angle of the vector (x=a, y=b) in binary radians 0..255 (rounded); signed low bytes."""
    x, y = _signed_byte(a), _signed_byte(b)
    if x == 0 and y == 0:
        return 0
    return round(math.atan2(y, x) * 128 / math.pi) & 0xFF


def minop(a: int, b: int) -> int:
    """a MIN b: a, but not below b."""
    return a if a > b else b


def maxop(a: int, b: int) -> int:
    """a MAX b: a, but not above b."""
    return a if a < b else b


def random_next(v: int) -> int:
    """RANDOM: next value of a 16-bit Galois LFSR (taps $B400, period 65535; 0 seeds to 1).

    The BS2's own generator is not documented bit-exactly; programs only rely on it being a
    deterministic pseudo-random sequence of the variable's previous value.
    """
    if v == 0:
        v = 1
    lsb = v & 1
    v >>= 1
    if lsb:
        v ^= 0xB400
    return v


UNARY = {  # code -> python function (used by the reference model and the slow paths)
    0: sqr,
    1: abs16,
    2: lambda a: a ^ MASK,
    3: lambda a: (-a) & MASK,
    4: lambda a: 1 << (a & 15),
    5: ncd,
    6: lambda a: SIN_TABLE[(a + 64) & 0xFF],
    7: lambda a: SIN_TABLE[a & 0xFF],
}

BINARY = {
    0x08: hyp,
    0x09: atn,
    0x0A: lambda a, b: a & b,
    0x0B: lambda a, b: a | b,
    0x0C: lambda a, b: a ^ b,
    0x0D: minop,
    0x0E: maxop,
    0x0F: lambda a, b: (a + b) & MASK,
    0x10: lambda a, b: (a - b) & MASK,
    0x11: lambda a, b: ((a * b) >> 8) & MASK,
    0x12: lambda a, b: (a * b) & MASK,
    0x13: lambda a, b: (a * b) >> 16,
    0x14: mod,
    0x15: div,
    0x16: dig,
    0x17: shl,
    0x18: lambda a, b: a >> b,
    0x19: rev,
    0x1A: lambda a, b: TRUE if a >= b else 0,
    0x1B: lambda a, b: TRUE if a <= b else 0,
    0x1C: lambda a, b: TRUE if a == b else 0,
    0x1D: lambda a, b: TRUE if a != b else 0,
    0x1E: lambda a, b: TRUE if a > b else 0,
    0x1F: lambda a, b: TRUE if a < b else 0,
}
