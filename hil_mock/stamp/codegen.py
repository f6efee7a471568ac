"""Translate decoded instructions into Python functions, once per slot image.

Every instruction becomes ``def f<addr>(s)`` that updates the stamp ``s`` and returns the next
bit address. The postfix argument items are turned into one Python expression at translation
time (the BS2 evaluation stack is fully static), so running an instruction re-parses nothing.
Programs are cached by image bytes: 30 modules running the same image share one translation.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from bstool.tokenizer import tokens as T

from . import arith
from .decoder import Decoded, Instr, Item, constant_stack, decode_image, label_address
from .errors import NotInTwin, StampFault

I = T.Instruction  # noqa: E741

CODE_SPACE = T.SLOT_BYTES * 8
TX_PC = CODE_SPACE  # pseudo-instruction: send the next byte of a SEROUT
WAIT_PC = CODE_SPACE + 1  # pseudo-instruction: blocked in SERIN

Op = Callable[[Any], int]

_UNARY = {
    0: "_sqr({})",
    1: "_abs({})",
    2: "({} ^ 65535)",
    3: "(-{} & 65535)",
    4: "(1 << ({} & 15))",
    5: "({}).bit_length()",
    6: "_SIN[({} + 64) & 255]",
    7: "_SIN[{} & 255]",
}
_BINARY = {
    0x08: "_hyp({0}, {1})",
    0x09: "_atn({0}, {1})",
    0x0A: "({0} & {1})",
    0x0B: "({0} | {1})",
    0x0C: "({0} ^ {1})",
    0x0D: "_min({0}, {1})",
    0x0E: "_max({0}, {1})",
    0x0F: "(({0} + {1}) & 65535)",
    0x10: "(({0} - {1}) & 65535)",
    0x11: "(({0} * {1}) >> 8 & 65535)",
    0x12: "(({0} * {1}) & 65535)",
    0x13: "(({0} * {1}) >> 16)",
    0x14: "_mod({0}, {1})",
    0x15: "_div({0}, {1})",
    0x16: "_dig({0}, {1})",
    0x17: "_shl({0}, {1})",
    0x18: "({0} >> {1})",
    0x19: "_rev({0}, {1})",
    0x1A: "(65535 if {0} >= {1} else 0)",
    0x1B: "(65535 if {0} <= {1} else 0)",
    0x1C: "(65535 if {0} == {1} else 0)",
    0x1D: "(65535 if {0} != {1} else 0)",
    0x1E: "(65535 if {0} > {1} else 0)",
    0x1F: "(65535 if {0} < {1} else 0)",
}
_LOOKDOWN = {2: ">=", 3: "<=", 4: "==", 5: "!=", 6: ">", 7: "<"}
_PIN_OPS = {
    I.HIGH: "_high",
    I.LOW: "_low",
    I.TOGGLE: "_toggle",
    I.INPUT: "_input",
    I.OUTPUT: "_output",
    I.REVERSE: "_reverse",
}


def _is_literal(e: str) -> bool:
    return e.isdigit()


class ExprGen:
    """Static simulation of the evaluation stack that emits Python source."""

    def __init__(self, lines: list[str], indent: str = "    ") -> None:
        self.lines = lines
        self.stack: list[str] = []
        self.indent = indent
        self.ntemp = 0

    def emit(self, line: str) -> None:
        self.lines.append(self.indent + line)

    def temp(self, expr: str) -> str:
        if _is_literal(expr) or expr.startswith("_t"):
            return expr
        name = f"_t{self.ntemp}"
        self.ntemp += 1
        self.emit(f"{name} = {expr}")
        return name

    def pop(self) -> str:
        if not self.stack:
            raise StampFault("evaluation stack underflow in token stream")
        return self.stack.pop()

    def run(self, items: list[Item]) -> None:
        for it in items:
            kind = it[0]
            if kind == "c":
                self.stack.append(str(it[1]))
            elif kind == "u":
                a = self.pop()
                if _is_literal(a):
                    self.stack.append(str(arith.UNARY[it[1]](int(a))))
                else:
                    self.stack.append(_UNARY[it[1]].format(a))
            elif kind == "b":
                b = self.pop()
                a = self.pop()
                code = it[1]
                if _is_literal(a) and _is_literal(b):
                    self.stack.append(str(arith.BINARY[code](int(a), int(b))))
                elif code == 0x17 and _is_literal(b) and int(b) < 16:
                    self.stack.append(f"(({a} << {b}) & 65535)")
                else:
                    self.stack.append(_BINARY[code].format(a, b))
            else:
                _, size, index, indexed, write = it
                at = self.pop() if indexed else None
                if write:
                    self.write(size, index, at, self.pop())
                else:
                    self.stack.append(self.read(size, index, at))

    @staticmethod
    def read(size: int, index: int, at: str | None) -> str:
        if at is not None:
            return f"_rd{size}(r, {index} + {at})"
        if size == T.VarSize.WORD:
            return f"(r[{2 * index}] | r[{2 * index + 1}] << 8)"
        if size == T.VarSize.BYTE:
            return f"r[{index}]"
        if size == T.VarSize.NIB:
            j = index >> 1
            return f"(r[{j}] >> 4)" if index & 1 else f"(r[{j}] & 15)"
        return f"(r[{index >> 3}] >> {index & 7} & 1)"

    def write(self, size: int, index: int, at: str | None, value: str) -> None:
        # reads already on the stack must see the old value: evaluate them first
        self.stack = [self.temp(e) for e in self.stack]
        if at is not None:
            self.emit(f"_wr{size}(s, r, {index} + {at}, {value})")
            return
        if size == T.VarSize.WORD:
            v = self.temp(value)
            self.emit(f"r[{2 * index}] = {v} & 255")
            self.emit(f"r[{2 * index + 1}] = {v} >> 8")
            first = 2 * index
        elif size == T.VarSize.BYTE:
            self.emit(f"r[{index}] = {value} & 255")
            first = index
        elif size == T.VarSize.NIB:
            j = index >> 1
            if index & 1:
                self.emit(f"r[{j}] = r[{j}] & 15 | ({value} & 15) << 4")
            else:
                self.emit(f"r[{j}] = r[{j}] & 240 | {value} & 15")
            first = j
        else:
            j, m = index >> 3, 1 << (index & 7)
            self.emit(f"r[{j}] = r[{j}] | {m} if {value} & 1 else r[{j}] & {255 ^ m}")
            first = j
        if first < 6:
            self.emit("s._pins()")


def _values(gen_lines: list[str], items: list[Item], indent: str) -> str:
    """Compile an item sequence that leaves values on the stack; return a tuple expression."""
    g = ExprGen(gen_lines, indent)
    g.run(items)
    return "(" + "".join(e + ", " for e in g.stack) + ")"


@dataclass
class Program:
    """A translated slot image."""

    image: bytes
    decoded: Decoded
    code: list[Op]  # indexed by bit address (plus TX_PC, WAIT_PC)
    start: int
    source: str


class _Translator:
    def __init__(self, decoded: Decoded) -> None:
        self.d = decoded
        self.out: list[str] = []
        self.extra: list[str] = []  # helper functions (SERIN item writers)

    def translate(self) -> str:
        for addr in sorted(self.d.instructions):
            self.instruction(self.d.instructions[addr])
        return "\n".join(self.out + self.extra) + "\n"

    def instruction(self, ins: Instr) -> None:
        a = ins.addr
        lines = self.out
        lines.append(f"def f{a}(s):")
        if ins.unknown and ins.code < 0:
            lines.append(f"    return s._bad_image({a})")
            return
        if ins.unknown:
            lines.append(f"    return s._notimpl({ins.name!r}, {a})")
            return
        lines.append("    r = s.ram")
        lines.append(f"    s.t += s._ins[{ins.bits}]")  # the stamp's clock (.clock)
        g = ExprGen(lines)
        g.run(ins.args)
        st = g.stack
        c = ins.code
        nxt = ins.end
        f = ins.fields
        emit = g.emit
        if c == I.DONE:
            emit(f"return {nxt}")
        elif c in _PIN_OPS:
            emit(f"{_PIN_OPS[I(c)]}(s, {st[-1]})")
            emit(f"return {nxt}")
        elif c == I.PAUSE:
            emit(f"s.t += {st[-1]} * s._pause_ns")
            emit(f"return {nxt}")
        elif c == I.PULSOUT:
            emit(f"s._pulsout({st[-1]}, {st[-2]})")
            emit(f"return {nxt}")
        elif c == I.GOTO:
            emit(f"return {f['target']}")
        elif c == I.GOSUB:
            emit(f"s._gosub({f['id']})")
            emit(f"return {f['target']}")
        elif c == I.RETURN:
            emit("return s._return()")
        elif c == I.IF:
            emit(f"return {f['target']} if {st[-1]} else {nxt}")
        elif c == I.NEXT:
            end, start = g.temp(st[-2]), g.temp(st[-1])
            g.stack = []
            g.run(f["read"])
            step = g.temp(g.stack.pop())
            v = g.temp(g.stack.pop())
            emit(f"if {start} <= {end}:")
            emit(f"    _n = {v} + {step}")
            emit(f"    _go = _n <= {end} and _n <= 65535")
            emit("else:")
            emit(f"    _n = {v} - {step}")
            emit(f"    _go = _n >= {end} and _n >= 0")
            g.stack = ["(_n & 65535)"]
            g.run(f["write"])
            emit(f"return {f['target']} if _go else {nxt}")
        elif c == I.BRANCH:
            targets = f["targets"]
            i = g.temp(st[-1])
            emit(f"if {i} < {len(targets)}:")
            emit(f"    return {tuple(targets)}[{i}]")
            emit(f"return {nxt}")
        elif c == I.LOOKUP:
            i = g.temp(st[-1])
            vals = []
            for items in f["values"]:
                vg = ExprGen(lines)
                vg.run(items)
                vals.append(vg.stack[-1])
            emit(f"if {i} < {len(vals)}:")
            g.indent = "        "
            g.stack = [f"({', '.join(vals)},)[{i}]"]
            g.run(f["write"])
            g.indent = "    "
            emit(f"return {nxt}")
        elif c == I.LOOKDOWN:
            x = g.temp(st[-1])
            op = _LOOKDOWN.get(int(f["compare"]), "==")
            for k, items in enumerate(f["values"]):
                vg = ExprGen(lines)
                vg.run(items)
                emit(f"{'if' if k == 0 else 'elif'} {x} {op} {vg.stack[-1]}:")
                emit(f"    _val = {k}")
            emit("else:")
            emit(f"    return {nxt}")
            g.stack = ["_val"]
            g.run(f["write"])
            emit(f"return {nxt}")
        elif c == I.RANDOM:
            g.stack = [f"_rnd({st[-1]})"]
            g.run(f["write"])
            emit(f"return {nxt}")
        elif c == I.READ:
            g.stack = [f"s._read({st[-1]})"]
            g.run(f["write"])
            emit(f"return {nxt}")
        elif c == I.WRITE:
            emit(f"s._write({st[-1]}, {st[-2]})")
            emit(f"return {nxt}")
        elif c == I.GET:
            g.stack = [f"s._get({st[-1]})"]
            g.run(f["write"])
            emit(f"return {nxt}")
        elif c == I.PUT:
            emit(f"s._put({st[-2]}, {st[-1]})")
            emit(f"return {nxt}")
        elif c == I.RUN:
            emit(f"return s._run({st[-1]})")
        elif c == I.END:
            emit(f"return s._end({a})")
        elif c == I.STOP:
            emit(f"return s._stop({a})")
        elif c == I.SEROUT:
            pace = st[-3] if len(st) >= 3 else "0"
            items = [_values(lines, it, "    ") for it in f["items"]]
            emit(f"return s._serout({st[-1]}, {st[-2]}, {pace}, ({', '.join(items)},), {nxt})")
        elif c == I.SERIN:
            self.serin(ins, g)
        else:
            emit(f"return s._notimpl({ins.name!r}, {a})")

    def serin(self, ins: Instr, g: ExprGen) -> None:
        a = ins.addr
        st = g.stack
        consts = constant_stack(ins.args)
        extra = len(st) - 2
        timeout, tlabel, plabel = "None", "None", "None"
        if extra == 2 or (extra >= 3 and consts[-4]):
            timeout = st[-3]
            tlabel = str(label_address(consts[-4] or 0))
        if extra >= 3 and consts[-5]:
            plabel = str(label_address(consts[-5] or 0))
        descr = []
        for k, (kind, fmt, write) in enumerate(ins.fields["items"]):
            fname = wname = "None"
            if kind == "fmt":
                fname = f"x{a}_{k}"
                body: list[str] = []
                expr = _values(body, fmt, "    ")
                self.extra += [f"def {fname}(s):", "    r = s.ram", *body, f"    return {expr}"]
            if write is not None:
                wname = f"w{a}_{k}"
                wl: list[str] = [f"def {wname}(s, _val):", "    r = s.ram"]
                wg = ExprGen(wl)
                wg.stack = ["_val"]
                wg.run(write)
                self.extra += wl
            descr.append(f"({kind!r}, {fname}, {wname})")
        self.extra.append(f"_SI{a} = ({', '.join(descr)},)")
        g.emit(
            f"return s._serin({st[-1]}, {st[-2]}, {timeout}, {tlabel}, {plabel}, _SI{a}, {ins.end})"
        )


def _rd(size: int) -> Callable[[bytearray, int], int]:
    if size == 3:
        return lambda r, k: r[2 * (k & 15)] | r[2 * (k & 15) + 1] << 8
    if size == 2:
        return lambda r, j: r[j & 31]
    if size == 1:
        return lambda r, n: (r[(n & 63) >> 1] >> 4 * (n & 1)) & 15
    return lambda r, i: (r[(i & 255) >> 3] >> (i & 7)) & 1


def _wr(size: int) -> Callable[[Any, bytearray, int, int], None]:
    def word(s: Any, r: bytearray, k: int, v: int) -> None:
        k &= 15
        r[2 * k] = v & 255
        r[2 * k + 1] = v >> 8
        if k < 3:
            s._pins()

    def byte(s: Any, r: bytearray, j: int, v: int) -> None:
        j &= 31
        r[j] = v & 255
        if j < 6:
            s._pins()

    def nib(s: Any, r: bytearray, n: int, v: int) -> None:
        n &= 63
        j = n >> 1
        r[j] = (r[j] & 15 | (v & 15) << 4) if n & 1 else (r[j] & 240 | v & 15)
        if j < 6:
            s._pins()

    def bit(s: Any, r: bytearray, i: int, v: int) -> None:
        i &= 255
        j, m = i >> 3, 1 << (i & 7)
        r[j] = r[j] | m if v & 1 else r[j] & (255 ^ m)
        if j < 6:
            s._pins()

    return (bit, nib, byte, word)[size]


def _pin_helper(kind: str) -> Callable[[Any, int], None]:
    def op(s: Any, p: int) -> None:
        r = s.ram
        m = 1 << (p & 15)
        dirs = r[4] | r[5] << 8
        outs = r[2] | r[3] << 8
        if kind == "high":
            dirs, outs = dirs | m, outs | m
        elif kind == "low":
            dirs, outs = dirs | m, outs & ~m
        elif kind == "toggle":
            dirs, outs = dirs | m, outs ^ m
        elif kind == "input":
            dirs &= ~m
        elif kind == "output":
            dirs |= m
        else:
            dirs ^= m
        r[2], r[3], r[4], r[5] = outs & 255, (outs >> 8) & 255, dirs & 255, (dirs >> 8) & 255
        s._pins()

    return op


def _bad_pc(s: Any) -> int:
    raise StampFault(f"{s.name}: jump to an address that holds no instruction (pc {s.pc})")


def _tx_step(s: Any) -> int:
    return s._tx_step()


def _wait_step(s: Any) -> int:
    s.brk = True
    return WAIT_PC


NAMESPACE: dict[str, Any] = {
    "_sqr": arith.sqr,
    "_abs": arith.abs16,
    "_SIN": arith.SIN_TABLE,
    "_hyp": arith.hyp,
    "_atn": arith.atn,
    "_min": arith.minop,
    "_max": arith.maxop,
    "_mod": arith.mod,
    "_div": arith.div,
    "_dig": arith.dig,
    "_shl": arith.shl,
    "_rev": arith.rev,
    "_rnd": arith.random_next,
    **{f"_rd{n}": _rd(n) for n in range(4)},
    **{f"_wr{n}": _wr(n) for n in range(4)},
    **{name: _pin_helper(name[1:]) for name in _PIN_OPS.values()},
}

_CACHE: dict[bytes, Program] = {}


def load_program(image: bytes) -> Program:
    """Decode and translate a slot image (cached by content)."""
    key = bytes(image)
    prog = _CACHE.get(key)
    if prog is not None:
        return prog
    decoded = decode_image(key)
    source = _Translator(decoded).translate()
    namespace = dict(NAMESPACE)
    exec(compile(source, f"<bs2sx slot image {hash(key) & 0xFFFFFFFF:08x}>", "exec"), namespace)
    code: list[Op] = [_bad_pc] * (CODE_SPACE + 2)
    for addr in decoded.instructions:
        code[addr] = namespace[f"f{addr}"]
    code[TX_PC] = _tx_step
    code[WAIT_PC] = _wait_step
    prog = Program(key, decoded, code, decoded.start, source)
    if len(_CACHE) > 256:
        _CACHE.clear()
    _CACHE[key] = prog
    return prog


__all__ = ["TX_PC", "WAIT_PC", "NotInTwin", "Program", "load_program"]
