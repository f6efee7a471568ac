"""SEROUT output formatting and the SERIN input state machine (bs2sx.md §6, TOK formatter codes).

Formatter codes (TOK symbol table): bit $100 = number; low nibble = 16 - base (6 dec, 0 hex,
$E bin); bits 4-7 = 16 - digits (0 = 16); $200 fixed number of digits; $400 signed; $800
indicated ($ or % prefix); $1000 NUM/SNUM (any base, input only). Other codes in an output item
([code, value] left on the stack): STR array\\L = [byte index, L], STR array = [$200 | index,
limit] (up to a 0 byte), REP c\\n = [c, $400, n]. Input items: STR = [(end,) index | $200 if end,
L], SKIP = [$400, n], WAITSTR = [$800 | index, 32] or [$A00 | index, L], WAIT(c1..cn) =
[cn..c1, $C44, n].
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from .errors import NotInTwin

NUMBER = 0x100
FIXED = 0x200
SIGNED = 0x400
INDICATED = 0x800
ANY_BASE = 0x1000
_BASES = {0x6: 10, 0x0: 16, 0xE: 2}
_DIGITS = "0123456789ABCDEF"
_INDICATOR = {16: "$", 2: "%", 10: ""}


def number_spec(code: int) -> tuple[int, int, bool, bool, bool]:
    """(base, digits, fixed, signed, indicated) of a number formatter code."""
    base = _BASES.get(code & 0xF, 10)
    field = (code >> 4) & 0xF
    return (
        base,
        (16 - field) if field else 16,
        bool(code & FIXED),
        bool(code & SIGNED),
        bool(code & INDICATED),
    )


def format_number(code: int, value: int) -> bytes:
    base, digits, fixed, signed, indicated = number_spec(code)
    value &= 0xFFFF
    neg = signed and bool(value & 0x8000)
    if neg:
        value = 0x10000 - value
    text = ""
    v = value
    while True:
        text = _DIGITS[v % base] + text
        v //= base
        if v == 0:
            break
    if fixed:
        text = text.rjust(digits, "0")[-digits:]
    prefix = ("-" if neg else "") + (_INDICATOR[base] if indicated else "")
    return (prefix + text).encode("ascii")


def output_bytes(items: tuple[tuple[int, ...], ...], ram: bytearray) -> bytes:
    """The bytes a SEROUT/DEBUG output list sends, from each item's stack values."""
    out = bytearray()
    for vals in items:
        if len(vals) == 1:
            out.append(vals[0] & 0xFF)
            continue
        code, param = vals[-2], vals[-1]
        if code & NUMBER:
            out += format_number(code, param)
        elif code & SIGNED and len(vals) >= 3:  # REP c\n
            out += bytes([vals[-3] & 0xFF]) * param
        elif code & FIXED:  # STR array: up to a 0 byte
            start = code & 0xFF
            for k in range(param):
                b = ram[(start + k) & 31]
                if b == 0:
                    break
                out.append(b)
        else:  # STR array\L
            start = code & 0xFF
            out += bytes(ram[(start + k) & 31] for k in range(param))
    return bytes(out)


Writer = Callable[[Any, int], None]


class InputItem:
    """One active SERIN item; ``feed`` returns True when the item is complete."""

    done = False

    def feed(self, s: Any, b: int) -> bool:  # pragma: no cover - overridden
        raise NotImplementedError


class ByteItem(InputItem):
    def __init__(self, write: Writer) -> None:
        self.write = write

    def feed(self, s: Any, b: int) -> bool:
        self.write(s, b)
        return True


class WaitItem(InputItem):
    def __init__(self, seq: list[int]) -> None:
        self.seq = seq
        self.k = 0
        self.done = not seq

    def feed(self, s: Any, b: int) -> bool:
        if b == self.seq[self.k]:
            self.k += 1
        else:
            self.k = 1 if b == self.seq[0] else 0
        return self.k == len(self.seq)


class SkipItem(InputItem):
    def __init__(self, n: int) -> None:
        self.n = n
        self.done = n == 0

    def feed(self, s: Any, b: int) -> bool:
        self.n -= 1
        return self.n <= 0


class StrItem(InputItem):
    def __init__(self, start: int, length: int, end: int | None) -> None:
        self.start, self.length, self.end, self.k = start, length, end, 0
        self.done = length == 0

    def feed(self, s: Any, b: int) -> bool:
        if self.end is not None and b == self.end:
            return True
        s.ram[(self.start + self.k) & 31] = b
        self.k += 1
        if self.start + self.k - 1 < 6:
            s._pins()
        return self.k >= self.length


class WaitStrItem(InputItem):
    def __init__(self, seq: list[int]) -> None:
        self.w = WaitItem(seq)
        self.done = self.w.done

    def feed(self, s: Any, b: int) -> bool:
        return self.w.feed(s, b)


class NumberItem(InputItem):
    def __init__(self, code: int, write: Writer) -> None:
        self.base, self.digits, self.fixed, self.signed, self.indicated = number_spec(code)
        self.any = bool(code & ANY_BASE)
        if self.any:
            self.base, self.digits = 10, 5
        self.write = write
        self.value = 0
        self.count = 0
        self.neg = False
        self.prefixed = not self.indicated

    def _digit(self, b: int) -> int | None:
        c = chr(b).upper()
        if c in _DIGITS[: self.base]:
            return _DIGITS.index(c)
        return None

    def _finish(self, s: Any) -> bool:
        v = (-self.value if self.neg else self.value) & 0xFFFF
        self.write(s, v)
        return True

    def feed(self, s: Any, b: int) -> bool:
        if self.count == 0:
            if self.signed and b == ord("-"):
                self.neg = True
                return False
            if self.any and b in (ord("$"), ord("%")):
                self.base, self.digits = (16, 4) if b == ord("$") else (2, 16)
                return False
            if not self.prefixed:
                if chr(b) == _INDICATOR[self.base] or not _INDICATOR[self.base]:
                    self.prefixed = True
                return False
            d = self._digit(b)
            if d is None:
                self.neg = False
                return False
        else:
            d = self._digit(b)
            if d is None:
                return self._finish(s)
        self.value = (self.value * self.base + d) & 0xFFFF
        self.count += 1
        if self.fixed and self.count >= self.digits:
            return self._finish(s)
        return False


def make_input_item(kind: str, fmt: Callable[[Any], tuple[int, ...]] | None, write: Any, s: Any):
    """Activate one SERIN item descriptor (kind, formatter function, writer)."""
    if kind == "byte":
        return ByteItem(write)
    assert fmt is not None
    vals = fmt(s)
    code, param = vals[-2], vals[-1]
    if code & NUMBER:
        return NumberItem(code, write)
    if code == 0xC44:
        return WaitItem([v & 0xFF for v in reversed(vals[:-2])][:param])
    if code & ANY_BASE:
        raise NotInTwin("SERIN SPSTR")
    if code & INDICATED:  # WAITSTR
        start = code & 0xFF
        ram = s.ram
        if code & FIXED:
            seq = [ram[(start + k) & 31] for k in range(param)]
        else:
            seq = []
            for k in range(32):
                b = ram[(start + k) & 31]
                if b == 0:
                    break
                seq.append(b)
        return WaitStrItem(seq)
    if code & SIGNED:
        return SkipItem(param)
    end = (vals[-3] & 0xFF) if code & FIXED and len(vals) >= 3 else None
    return StrItem(code & 0xFF, param, end)
