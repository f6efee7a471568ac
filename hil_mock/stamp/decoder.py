"""Decode a BS2sx slot image into instructions.

The program is one bit stream that starts at byte $7FF and grows down (bs2sx.md §5): stream bit
b is bit 7 - b mod 8 of byte 2047 - b div 8, fields MSB first. Bits 0-13 hold the start address,
then one 14-bit return address per GOSUB statement. Codes and widths come from
:mod:`bstool.tokenizer.tokens` only.

Decoding follows the control flow from the start address and every return-table entry, so bytes
that are not code (DATA, unused EEPROM) are never read as instructions. An instruction whose
inline fields the twin does not know decodes to a ``Instr`` with ``unknown=True`` and no
successors: executing it raises :class:`~hil_mock.stamp.errors.NotInTwin`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from bstool.tokenizer import tokens as T

from .errors import StampFault

I = T.Instruction  # noqa: E741 - short alias for the enum

# ---- expression items ------------------------------------------------------------------------
# ("u", code) unary, ("b", code) binary, ("c", value) constant,
# ("v", size, index, indexed, write) variable.  Tuples keep decoding and code generation simple.
Item = tuple


@dataclass
class Instr:
    """One decoded statement."""

    addr: int  # bit address of its first bit
    code: int  # 6-bit instruction code
    name: str
    args: list[Item]  # argument items in push order (one postfix sequence)
    end: int  # bit address right after it
    fields: dict[str, Any] = field(default_factory=dict)
    successors: list[int] = field(default_factory=list)
    unknown: bool = False

    @property
    def bits(self) -> int:
        return self.end - self.addr


class BitReader:
    """Reads fields from the downward-growing stream of one 2048-byte slot."""

    __slots__ = ("image", "limit", "pos")

    def __init__(self, image: bytes, pos: int = 0) -> None:
        if len(image) != T.SLOT_BYTES:
            raise StampFault(f"slot image has {len(image)} bytes, expected {T.SLOT_BYTES}")
        self.image = image
        self.pos = pos
        self.limit = T.SLOT_BYTES * 8

    def bit(self) -> int:
        p = self.pos
        if p >= self.limit:
            raise StampFault("token stream runs past the start of the slot")
        self.pos = p + 1
        return (self.image[T.SLOT_BYTES - 1 - (p >> 3)] >> (7 - (p & 7))) & 1

    def bits(self, n: int) -> int:
        v = 0
        for _ in range(n):
            v = (v << 1) | self.bit()
        return v

    def address(self) -> int:
        """A 14-bit code address: low 3 bits first, then the byte count (bs2sx.md §5)."""
        low = self.bits(3)
        count = self.bits(T.ADDRESS_BITS - 3)
        return count * 8 + low

    def item(self) -> Item:
        code = self.bits(T.ITEM_BITS)
        if code < 0x08:
            return ("u", code)
        if code < T.CONSTANT_ITEM:
            return ("b", code)
        if code < T.VARIABLE_ITEM:
            n = code - T.CONSTANT_ITEM
            if self.bit() == 0:
                return ("c", 1 << n)
            return ("c", 0 if n == 0 else (1 << n) + self.bits(n))
        size = code & 3
        index = self.bits(T.VARIABLE_INDEX_BITS[size])
        indexed = bool(code & T.VARIABLE_INDEXED_FLAG)
        write = bool(code & T.VARIABLE_WRITE_FLAG)
        return ("v", size, index, indexed, write)

    def expression(self) -> list[Item]:
        """An inline expression: a bare item, then 1+item ..., ended by a 0 bit."""
        items = [self.item()]
        while self.bit():
            items.append(self.item())
        return items


def label_address(value: int) -> int:
    """Code address carried by a 15-bit label constant ($2E, flag 1, 14-bit address field)."""
    field14 = value & 0x3FFF
    return (field14 & 0x7FF) * 8 + (field14 >> 11)


def stack_effect(items: list[Item]) -> int:
    """Net number of values an item sequence leaves on the stack."""
    depth = 0
    for it in items:
        kind = it[0]
        if kind == "c":
            depth += 1
        elif kind == "b":
            depth -= 1
        elif kind == "v":
            if it[3]:
                depth -= 1  # index popped
            depth += -1 if it[4] else 1
    return depth


def constant_stack(items: list[Item]) -> list[int | None]:
    """Stack left by ``items`` with each entry's value if it is a lone constant, else None."""
    stack: list[int | None] = []
    for it in items:
        kind = it[0]
        if kind == "c":
            stack.append(it[1])
        elif kind == "u":
            stack[-1] = None
        elif kind == "b":
            stack.pop()
            stack[-1] = None
        else:
            if it[3]:
                stack.pop()
            if it[4]:
                stack.pop()
            else:
                stack.append(None)
    return stack


_NAMES = {int(c): c.name for c in I}
_SIMPLE = {  # no inline fields, falls through
    I.OUTPUT, I.HIGH, I.TOGGLE, I.LOW, I.REVERSE, I.INPUT, I.PAUSE, I.DONE, I.PUT,
    I.PULSOUT, I.FREQOUT1, I.FREQOUT2, I.PWM,
}  # fmt: skip
_WRITE_EXPR = {I.RANDOM, I.GET, I.PULSIN, I.COUNT, I.RCTIME}


def decode_at(r: BitReader, addr: int) -> Instr:
    """Decode the statement starting at bit ``addr``."""
    r.pos = addr
    args: list[Item] = []
    while r.bit():
        args.append(r.item())
    code = r.bits(T.INSTRUCTION_BITS)
    ins = Instr(addr, code, _NAMES.get(code, f"${code:02X}"), args, addr)
    f = ins.fields
    nxt: list[int] = []
    try:
        c = I(code)
    except ValueError:
        c = None
    if c in (I.END, I.STOP, I.RETURN, I.RUN):
        pass
    elif c in _SIMPLE:
        nxt = [-1]
    elif c == I.GOTO:
        f["target"] = r.address()
        nxt = [int(f["target"])]
    elif c == I.GOSUB:
        f["id"] = r.bits(T.GOSUB_ID_BITS)
        f["target"] = r.address()
        nxt = [f["target"]]
    elif c == I.IF:
        f["target"] = r.address()
        nxt = [f["target"], -1]
    elif c == I.NEXT:
        f["read"] = r.expression()  # variable read, then step
        f["write"] = r.expression()
        f["target"] = r.address()
        nxt = [f["target"], -1]
    elif c == I.BRANCH:
        targets = [r.address()]
        while r.bit():
            targets.append(r.address())
        f["targets"] = targets
        nxt = [*targets, -1]
    elif c in (I.LOOKUP, I.LOOKDOWN):
        if c == I.LOOKDOWN:
            f["compare"] = r.bits(T.COMPARE_BITS)
        values = [r.expression()]
        while r.bit():
            values.append(r.expression())
        f["values"] = values
        f["write"] = r.expression()
        nxt = [-1]
    elif c in _WRITE_EXPR:
        f["write"] = r.expression()
        nxt = [-1]
    elif c == I.READ:
        f["resume"] = r.address()
        f["write"] = r.expression()
        nxt = [-1]
    elif c in (I.WRITE, I.NAP, I.SLEEP):
        f["resume"] = r.address()
        nxt = [f["resume"]]
    elif c in (I.SEROUT, I.SEROUT_FLOW):
        items = [r.expression()]
        while r.bit():
            items.append(r.expression())
        f["items"] = items
        nxt = [-1, *_labels(ins)]
    elif c in (I.SERIN, I.SERIN_FLOW):
        f["items"] = _input_sequence(r)
        nxt = [-1, *_labels(ins)]
    elif c in (I.SHIFTOUT, I.XOUT):
        items = [r.expression()]
        while r.bit():
            items.append(r.expression())
        f["items"] = items
        nxt = [-1]
    elif c == I.SHIFTIN:
        pairs = [(r.expression(), r.expression())]
        while r.bit():
            pairs.append((r.expression(), r.expression()))
        f["items"] = pairs
        nxt = [-1]
    else:  # DTMFOUT, BUTTON, unknown codes: inline layout not modelled
        ins.unknown = True
    ins.end = r.pos
    ins.successors = [ins.end if a == -1 else a for a in nxt]
    return ins


def _labels(ins: Instr) -> list[int]:
    """Timeout / parity labels pushed as 15-bit constants by SERIN and flow SEROUT."""
    out = []
    stack = constant_stack(ins.args)
    flow = ins.code in (I.SERIN_FLOW, I.SEROUT_FLOW)
    values = stack[: len(stack) - (3 if flow else 2)]  # drop baud, pin (and flow pin)
    if ins.code in (I.SERIN, I.SERIN_FLOW):
        # (1) | (tlabel, timeout) | (plabel, tlabel|0, timeout|1)
        if len(values) >= 2 and values[-2]:
            out.append(label_address(values[-2]))
        if len(values) >= 3 and values[-3]:
            out.append(label_address(values[-3]))
    elif flow and len(values) >= 2 and values[-2]:
        out.append(label_address(values[-2]))
    ins.fields["labels"] = out
    return out


def _input_sequence(r: BitReader) -> list[tuple[str, list[Item], list[Item] | None]]:
    """SERIN input items: ("byte", [], write) or ("fmt", formatter expression, write|None)."""
    items: list[tuple[str, list[Item], list[Item] | None]] = []
    while True:
        if r.bit():
            fmt = r.expression()
            stack = constant_stack(fmt)
            code = stack[-2] if len(stack) >= 2 else None
            write = r.expression() if code is not None and code & 0x100 else None
            items.append(("fmt", fmt, write))
        else:
            items.append(("byte", [], r.expression()))
        if not r.bit():
            return items


@dataclass
class Decoded:
    """All reachable instructions of one slot image."""

    start: int
    returns: list[int]  # return address of GOSUB id k at index k (index 0 unused)
    instructions: dict[int, Instr]


def decode_image(image: bytes) -> Decoded:
    """Decode every instruction reachable from the start address and the return table."""
    r = BitReader(bytes(image))
    start = r.address()
    # the return table runs from bit 14 up to the start of code
    n_gosubs = max(start // T.ADDRESS_BITS - 1, 0) if start % T.ADDRESS_BITS == 0 else 0
    returns = [0]
    for k in range(1, n_gosubs + 1):
        r.pos = T.ADDRESS_BITS * k
        returns.append(r.address())
    todo = [start, *returns[1:]]
    found: dict[int, Instr] = {}
    limit = T.SLOT_BYTES * 8
    while todo:
        a = todo.pop()
        if a in found or not 0 <= a < limit:
            continue
        try:
            ins = decode_at(r, a)
        except StampFault:
            ins = Instr(a, -1, "undecodable", [], a, unknown=True)
        found[a] = ins
        todo.extend(s for s in ins.successors if s not in found)
    return Decoded(start, returns, found)
