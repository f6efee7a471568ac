"""A tiny BS2sx token assembler for interpreter tests (not a tokenizer: no PBASIC source).

Builds slot images bit by bit following bs2sx.md §5-§6 with codes and widths from
bstool.tokenizer.tokens, so tests can run programs the vectors do not contain (random
expressions, two modules echoing bytes).
"""

from __future__ import annotations

from bstool.tokenizer import tokens as T

Item = tuple


def const(v: int) -> Item:
    return ("c", v)


def var(size: int, index: int, *, write: bool = False, indexed: bool = False) -> Item:
    return ("v", size, index, indexed, write)


def op(code: int) -> Item:
    return ("o", code)


def label(name: str) -> Item:
    """A 15-bit label constant (SERIN timeout label)."""
    return ("l", name)


class Asm:
    def __init__(self, gosubs: int = 0) -> None:
        self.bits: list[int] = []
        self.labels: dict[str, int] = {}
        self.patches: list[tuple[int, str, str]] = []  # (position, label, kind)
        self.gosubs = gosubs
        self.bits.extend([0] * (T.ADDRESS_BITS * (gosubs + 1)))  # start + return table
        self.labels["__start"] = len(self.bits)
        self.patches.append((0, "__start", "addr"))

    # -- raw fields ------------------------------------------------------------------------------
    def put(self, value: int, n: int) -> None:
        self.bits.extend((value >> (n - 1 - k)) & 1 for k in range(n))

    def address(self, name: str) -> None:
        self.patches.append((len(self.bits), name, "addr"))
        self.bits.extend([0] * T.ADDRESS_BITS)

    def here(self, name: str) -> None:
        self.labels[name] = len(self.bits)

    def item(self, it: Item) -> None:
        kind = it[0]
        if kind == "o":
            self.put(it[1], T.ITEM_BITS)
        elif kind == "c":
            v = it[1]
            n = max(v.bit_length() - 1, 0)
            self.put(T.CONSTANT_ITEM + n, T.ITEM_BITS)
            if v == 1 << n and v != 0:
                self.put(0, 1)
            else:
                self.put(1, 1)
                if n:
                    self.put(v - (1 << n), n)
        elif kind == "l":
            self.put(T.CONSTANT_ITEM + 14, T.ITEM_BITS)
            self.put(1, 1)
            self.patches.append((len(self.bits), it[1], "addr"))
            self.bits.extend([0] * T.ADDRESS_BITS)
        else:
            _, size, index, indexed, write = it
            code = T.VARIABLE_ITEM + size
            code += T.VARIABLE_WRITE_FLAG if write else 0
            code += T.VARIABLE_INDEXED_FLAG if indexed else 0
            self.put(code, T.ITEM_BITS)
            self.put(index, T.VARIABLE_INDEX_BITS[size])

    def args(self, items: list[Item]) -> None:
        for it in items:
            self.put(1, 1)
            self.item(it)

    def code(self, c: int) -> None:
        self.put(0, 1)
        self.put(c, T.INSTRUCTION_BITS)

    def inline(self, items: list[Item]) -> None:
        self.item(items[0])
        for it in items[1:]:
            self.put(1, 1)
            self.item(it)
        self.put(0, 1)

    # -- statements -------------------------------------------------------------------------------
    def let(self, items: list[Item], target: Item) -> None:
        self.args([*items, target])
        self.code(T.Instruction.DONE)

    def stmt(self, c: int, items: list[Item] = ()) -> None:  # type: ignore[assignment]
        self.args(list(items))
        self.code(c)

    def goto(self, name: str) -> None:
        self.code(T.Instruction.GOTO)
        self.address(name)

    def if_(self, cond: list[Item], name: str) -> None:
        self.args(cond)
        self.code(T.Instruction.IF)
        self.address(name)

    def serout(self, pin: int, mode: int, values: list[list[Item]]) -> None:
        self.args([const(mode), const(pin)])
        self.code(T.Instruction.SEROUT)
        for k, v in enumerate(values):
            self.inline(v)
            self.put(1 if k + 1 < len(values) else 0, 1)

    def serin(self, pin: int, mode: int, writes: list[Item], timeout: int | None = None,
              tlabel: str | None = None) -> None:  # fmt: skip
        if timeout is None:
            self.args([const(1), const(mode), const(pin)])
        else:
            assert tlabel is not None
            self.args([label(tlabel), const(timeout), const(mode), const(pin)])
        self.code(T.Instruction.SERIN)
        for k, w in enumerate(writes):
            self.put(0, 1)  # plain byte item
            self.inline([w])
            self.put(1 if k + 1 < len(writes) else 0, 1)

    def end(self) -> None:
        self.code(T.Instruction.END)

    # -- image ------------------------------------------------------------------------------------
    def image(self) -> bytes:
        bits = list(self.bits)
        for pos, name, _ in self.patches:
            a = self.labels[name]
            field = (a & 7) << 11 | (a >> 3)
            for k in range(T.ADDRESS_BITS):
                bits[pos + k] = (field >> (T.ADDRESS_BITS - 1 - k)) & 1
        img = bytearray(T.SLOT_BYTES)
        for b, v in enumerate(bits):
            if v:
                img[T.SLOT_BYTES - 1 - b // 8] |= 0x80 >> (b % 8)
        return bytes(img)
