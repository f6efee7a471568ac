"""Element cursor, symbol lookup and the expression compiler.

PBASIC has no operator precedence: a value expression is evaluated strictly left to right,
parentheses group, and a unary operator applies to the operand right after it. A condition
wraps each side of a comparison in implicit parentheses (``a + 1 = b AND c`` means
``((a + 1) = (b)) AND ((c) <> 0)``-style grouping), and NOT applies to the comparison after it.
The compiler below keeps an operator stack with '(' markers and emits postfix items; its
bookkeeping (the shared operator stack, the count of open parentheses, the run-time stack depth
used for "Expression is too complex") is kept exactly so that the emitted bits and the place
where an error is reported agree with Parallax's tokenizer.
"""

from __future__ import annotations

from dataclasses import dataclass

from bstool.tokenizer import tokens
from bstool.tokenizer.diagnostics import Failure
from bstool.tokenizer.image import TOTAL_BITS, Image
from bstool.tokenizer.lexer import OP_EQ, OP_NEG, OP_SUB, Element, K

PAREN = 0x80  # '(' marker on the operator stack
SYMBOL_TABLE_SIZE = 1024
# Entries of Parallax's symbol table before any user symbol (BS2sx): the common words and
# registers (363) plus GET/PUT/RUN, plus 33 PBASIC 2.5 words.
RESERVED_COUNT = {False: 366, True: 399}
_CC_OPERANDS = (K.UNDEF, K.CCCONST, K.DIRECTIVE, K.TARGET, K.PINNUM)
_CC_ILLEGAL = {
    int(op)
    for op in (
        tokens.Binary.HYP, tokens.Binary.ATN, tokens.Binary.MIN, tokens.Binary.MAX,
        tokens.Binary.MULMID, tokens.Binary.MULHIGH, tokens.Binary.MOD, tokens.Binary.DIG,
        tokens.Binary.REV,
    )
}  # fmt: skip
# Parallax counts the bits it appends (CASE lists) in a byte; see append_expression
APPEND_COUNT_LIMIT = 255
_EMIT_WORD = 16  # bits per word of Parallax's expression buffer
_WIDTH = {0: 1, 1: 4, 2: 8, 3: 16}  # bits of a Bit, Nib, Byte, Word
_HIGH_PART = 0x80  # HIGHBIT/HIGHNIB/HIGHBYTE: the last part, whatever the variable's size
# Variable items: 0x30 | indexed 0x04 | write 0x08 | size; the register number that follows
# has tokens.VARIABLE_INDEX_BITS bits (256 bits, 64 nibs, 32 bytes, 16 words of RAM).
_VARIABLE_ITEM = 0x30
_INDEXED = 0x04
_WRITE = 0x08


def _stack_effect(code: int) -> int:
    """Change of the interpreter's stack depth caused by one expression item."""
    if code <= tokens.Unary.SIN:
        return 0  # unary operator: replaces the top entry
    if code < tokens.CONSTANT_ITEM:
        return -1  # binary operator or comparison: two entries become one
    if code < _VARIABLE_ITEM | _INDEXED:
        return 1  # constant or plain variable read: pushes a value
    if code >= _VARIABLE_ITEM | _INDEXED | _WRITE:
        return -1  # indexed write: consumes its index
    return 0  # indexed read (index replaced by the value), plain write


_STACK_EFFECT = tuple(_stack_effect(code) for code in range(64))
# items that need a free stack entry at run time: pushes, and SQR/ATN (scratch entry)
_NEEDS_FREE_ENTRY = frozenset(
    [code for code in range(64) if _STACK_EFFECT[code] > 0]
    + [int(tokens.Unary.SQR), int(tokens.Binary.ATN)]
)


@dataclass(frozen=True, slots=True)
class Bits:
    """An immutable bit string (value, length); items are appended MSB first."""

    value: int = 0
    length: int = 0

    def add(self, nbits: int, data: int) -> Bits:
        length = self.length + nbits
        if length >= tokens.EXPRESSION_BUFFER_BITS:
            raise Failure(144, -1)
        return Bits((self.value << nbits) | (data & ((1 << nbits) - 1)), length)

    def join(self, other: Bits) -> Bits:
        return self.add(other.length, other.value) if other.length else self


class Compiler:
    """State shared by the declaration passes and the instruction compilers of one slot."""

    def __init__(
        self,
        elements: list[Element],
        lang25: bool,
        number_lists: dict[int, int] | None = None,
        has_cc_directives: bool = True,
    ) -> None:
        self.elements = elements
        self.dead = bytearray(len(elements))  # 1 = cancelled (a declaration or dropped line)
        # next_end[i]: index of the first END element at or after i (len(elements) if none)
        n = len(elements)
        self.next_end = next_end = [n] * (n + 1)
        end = K.END
        last = n
        for i in range(n - 1, -1, -1):
            if elements[i].kind is end:
                last = i
            next_end[i] = last
        # element index of each comma-separated run of plain numbers -> index just past it
        self.number_lists = number_lists or {}
        self.has_cc_directives = has_cc_directives
        self.lang25 = lang25
        self.idx = 0
        self.err: tuple[int, int] = (0, 0)
        self.symbols: dict[str, tuple[K, int]] = {}
        self.image = Image()
        self.expr = Bits()  # the expression being compiled (items, MSB first)
        self.stack_idx = 0  # run-time evaluation stack depth while compiling an argument
        self.ops = [0] * 256  # operator stack (see _push)
        self.ops_len = 0
        self.ops_floor = 0
        self.open_parens = 0
        self.cc_mode = False  # compiling a #IF / #SELECT / #DEFINE expression
        self.declared: set[str] = set()  # names declared with CON/VAR/PIN/DATA
        self.trace: list[tuple[bool, int]] = []  # (is_constant, value) of the items emitted

    # ---- elements ----------------------------------------------------------------------
    def get(self) -> Element:
        """Next non-cancelled element (user symbols resolved); remembers its position."""
        elements, dead, idx = self.elements, self.dead, self.idx
        n = len(elements)
        if idx < n and dead[idx]:  # skip cancelled elements
            idx = dead.find(0, idx)
            idx = n if idx < 0 else idx
        if idx < n:
            el = elements[idx]
            self.idx = idx + 1
            if el.kind is K.UNDEF and el.name in self.symbols:
                kind, value = self.symbols[el.name]
                el = Element(kind, value, el.start, el.length, el.name)
            self.err = (el.start, el.length)
            return el
        # Past the last element Parallax's reader returns an end but leaves the caller's
        # element as it was (its start stays the error position): the element read last.
        self.idx = idx
        return Element(K.END, 0, *self.err)

    def peek(self) -> Element:
        here, err = self.idx, self.err
        el = self.get()
        self.idx, self.err = here, err
        return el

    def new_symbol_room(self) -> None:
        """Parallax's symbol table holds 1024 names, reserved words included."""
        if RESERVED_COUNT[self.lang25] + len(self.symbols) >= SYMBOL_TABLE_SIZE:
            raise self.fail(128)

    def fail(self, code: int) -> Failure:
        return Failure(code, *self.err)

    def expect(self, kind: K, code: int) -> Element:
        el = self.get()
        if el.kind is not kind:
            raise self.fail(code)
        return el

    def expect_end(self) -> bool:
        """The statement must end here; True for ':' (soft end)."""
        el = self.get()
        if el.kind is not K.END:
            raise self.fail(129)
        return el.soft

    def check(self, kind: K) -> bool:
        """Skip the next element if it is ``kind``."""
        if self.peek().kind is kind:
            self.idx += 1
            return True
        return False

    # ---- program stream ----------------------------------------------------------------
    def emit(self, nbits: int, value: int) -> None:
        try:
            self.image.emit(nbits, value)
        except Failure as exc:
            if exc.offset < 0:
                raise self.fail(exc.code) from None
            raise

    def emit_bits(self, bits: Bits, one_before: bool) -> None:
        """Write a compiled expression, after a 1 bit ("an argument follows") if asked."""
        if one_before:
            self.emit(1, 1)
        # Parallax writes an expression one 16-bit word of its buffer at a time, and checks
        # each write on its own: "EEPROM full" (127) only when that word would run past the
        # end, so a word that reaches DATA is "Data occupies same location" (124) first.
        # (When it all fits, one write finds the same DATA byte first.)
        length, value = bits.length, bits.value
        if self.image.pos + length > TOTAL_BITS:
            while length > _EMIT_WORD:
                length -= _EMIT_WORD
                self.emit(_EMIT_WORD, value >> length)
        if length:
            self.emit(length, value)

    def emit_expr(self, one_before: bool) -> None:
        self.emit_bits(self.expr, one_before)

    def emit_code(self, code: int) -> None:
        """A 0 bit and a 6-bit instruction code."""
        self.emit(7, code)

    def emit_constant(self, value: int, one_before: bool) -> None:
        self.stack_idx = 0
        self.expr = Bits()
        self.item_constant(value)
        self.emit_expr(one_before)

    def emit_operator(self, op: int) -> None:
        self.emit(1, 1)
        self.emit(6, op)

    # ---- expression items into exp[0] --------------------------------------------------
    def _bits(self, nbits: int, data: int) -> None:
        try:
            self.expr = self.expr.add(nbits, data)
        except Failure as exc:
            raise self.fail(exc.code) from None

    def item(self, code: int) -> None:
        """One 6-bit item, tracking the run-time stack depth.

        The first item of an expression has 6 bits; every later one is preceded by a 1 bit
        ("more items follow"). The depth follows the item's effect on the interpreter's
        8-entry stack (see _STACK_EFFECT); an item that pushes at full depth, or SQR/ATN
        (which need a free entry) at full depth, is error 144.
        """
        depth = self.stack_idx
        if depth == tokens.EXPRESSION_STACK_DEPTH and code in _NEEDS_FREE_ENTRY:
            raise self.fail(144)
        self.stack_idx = (depth + _STACK_EFFECT[code]) & 0xFF
        if self.expr.length == 0:
            self._bits(6, code)
        else:
            self._bits(7, 0x40 | code)
        if self.cc_mode and code < tokens.CONSTANT_ITEM:
            self.trace.append((False, code))

    def item_constant(self, value: int) -> None:
        value &= 0xFFFF
        top = max(value.bit_length() - 1, 0)
        self.item(tokens.CONSTANT_ITEM | top)
        if self.cc_mode:
            self.trace.append((True, value))
        if value == 0 or value == 1 << top:
            self._bits(1, 1 if value == 0 else 0)
        else:
            self._bits(top + 1, value)

    def modifiers(self, value: int) -> int:
        """Apply a chain of .MODIFIERs to a variable (size << 8 | register number).

        A part of size ``m`` inside a variable of size ``s`` is register number
        ``number * parts + part`` in units of ``m``, where ``parts`` = width(s) / width(m);
        HIGH... names the last part.
        """
        while self.peek().kind is K.PERIOD:
            self.idx += 1
            size, number = value >> 8, value & 0xFF
            if size == tokens.VarSize.BIT:
                raise self.fail(138)
            mod = self.get()
            if mod.kind is not K.VARMOD:
                raise self.fail(137)
            part_size, part = int(mod.value) >> 8, int(mod.value) & 0xFF
            if part_size >= size:
                raise self.fail(139)
            parts = _WIDTH[size] // _WIDTH[part_size]
            if part & _HIGH_PART:
                part = parts - 1
            if part >= parts:
                raise self.fail(140)
            value = part_size << 8 | ((number * parts + part) & 0xFF)
        return value

    def item_variable(self, value: int, write: bool) -> None:
        """A variable item: 0x30 | flags | size, then its register number.

        An index ``var(expr)`` is compiled first (its items come before the variable's) inside
        a '(' pushed on the shared operator stack; that '(' stays counted in ``open_parens``,
        which the IDE does too and which matters for the end of a condition.
        """
        value = self.modifiers(value)
        flags = 0
        if self.peek().kind is K.LPAREN:
            self.idx += 1
            self._open()
            self.expression(False, True, 0)
            self.ops_len = (self.ops_len - 1) & 0xFF
            self.expect(K.RPAREN, 120)
            flags |= _INDEXED
        if write:
            flags |= _WRITE
        size = value >> 8
        self.item(_VARIABLE_ITEM | flags | size)
        self._bits(tokens.VARIABLE_INDEX_BITS[size], value & 0xFF)

    def read_write(self, write: bool) -> None:
        """A variable alone (read or write item) into exp[0]."""
        self.ops_len = self.ops_floor = 0
        self.expr = Bits()
        el = self.get()
        if el.kind not in (K.VARIABLE, K.PINNUM):
            raise self.fail(135)
        value = int(el.value)
        if el.kind is K.PINNUM and write:
            value += 16  # a PIN written is its OUTx bit (read: INx)
        self.item_variable(value, write)

    # ---- operator stack ----------------------------------------------------------------
    # One stack is shared by an expression and the index expressions inside it; ``ops_floor``
    # is where the expression being compiled starts. '(' is kept on it as the PAREN marker.
    def _push(self, data: int) -> None:
        if self.ops_len == 255:
            raise self.fail(144)
        self.ops[self.ops_len] = data
        self.ops_len += 1

    def _pop1(self) -> int | None:
        if self.ops_len > self.ops_floor:
            self.ops_len -= 1
            return self.ops[self.ops_len]
        return None

    def _flush(self) -> None:
        """Emit the operators above the nearest '(' (which stays) or above the floor."""
        ops, floor = self.ops, self.ops_floor
        while self.ops_len > floor and ops[self.ops_len - 1] != PAREN:
            self.ops_len -= 1
            self.item(ops[self.ops_len])

    def _close(self) -> None:
        """Drop the '(' on top and emit the operators of the group around it."""
        self.ops_len = (self.ops_len - 1) & 0xFF
        self.open_parens = (self.open_parens - 1) & 0xFF
        self._flush()

    def _open(self) -> None:
        self.open_parens = (self.open_parens + 1) & 0xFF
        self._push(PAREN)

    # ---- expressions -------------------------------------------------------------------
    def value(self, pin_const: bool = False) -> None:
        """A value expression into a fresh exp[0]."""
        self.ops_len = self.ops_floor = 0
        self.expr = Bits()
        self.expression(False, pin_const, 0)

    def condition(self, split: int = 0, auto_op: int = OP_EQ) -> None:
        """A condition into a fresh exp[0]; ``split`` > 0: SELECT expression + CASE part."""
        self.ops_len = self.ops_floor = 0
        self.expr = Bits()
        self.expression(True, False, split, auto_op)

    def expression(self, conditional: bool, pin_const: bool, split: int, auto_op: int = 0) -> None:
        """Compile an expression at the cursor into exp[0]; the cursor stops at what ends it.

        Operands are emitted as they are read; operators wait on the stack until the operand
        after them is out (left to right, no precedence). In a condition every comparison side
        is a group of its own: a comparison closes one '(' and opens one, AND/OR/XOR close and
        reopen two, so ``a + 1 = b AND c`` compiles as ``((a + 1) = (b)) AND ((c))``.

        ``split`` > 0 compiles a CASE test: the SELECT expression at the cursor, then (when
        its end is reached) the CASE part at element ``split``, with ``auto_op`` inserted when
        the CASE part does not start with a comparison.
        """
        saved = (self.open_parens, self.ops_len, self.ops_floor)
        self.open_parens = 0
        self.ops_floor = self.ops_len
        new_group = conditional
        while True:
            if new_group:
                self._comparison_group(split)
                new_group = False
            self._operand(pin_const)
            follower, finished, split = self._after_operand(conditional, split, auto_op)
            if finished:
                break
            kind = follower.kind
            if kind is K.COND1:
                if not conditional:
                    raise self.fail(142)
                self._close()
                self._push(int(follower.value))
                self._open()
            elif kind is K.COND2:
                if not conditional or split != 0:
                    raise self.fail(142)
                self._close()
                self._close()
                self._push(int(follower.value))
                new_group = True
            else:  # BINOP
                if self.cc_mode and follower.value in _CC_ILLEGAL:
                    raise self.fail(189)
                self._push(int(follower.value))
        self.idx -= 1
        self.open_parens, self.ops_len, self.ops_floor = saved

    def _comparison_group(self, split: int) -> None:
        """Open the groups of one comparison: two '(' plus one per '(' read; fold in NOTs."""
        while True:
            self._open()
            self._open()
            el = self.get()
            while el.kind is K.LPAREN:
                self._open()
                el = self.get()
            if el.kind is not K.COND3:
                self.idx -= 1
                return
            if split != 0:
                raise self.fail(141)
            # NOT applies to the whole comparison after it: it replaces the two '(' just
            # opened, and the groups are opened again behind it.
            self.ops_len = (self.ops_len - 2) & 0xFF
            self.open_parens = (self.open_parens - 2) & 0xFF
            self._push(int(el.value))

    def _operand(self, pin_const: bool) -> None:
        """Read prefix operators and '(' up to an operand, and emit the operand."""
        while True:
            el = self.get()
            kind = el.kind
            if self.cc_mode and kind in _CC_OPERANDS:
                if kind is K.UNDEF and el.name in self.declared:
                    raise self.fail(195)
                value = 0 if kind is K.UNDEF else int(el.value)
                el, kind = Element(K.CONST, value, el.start, el.length), K.CONST
            if kind is K.UNDEF:
                raise self.fail(110)
            if kind in (K.CONST, K.VARIABLE, K.PINNUM):
                if self.cc_mode and kind is K.VARIABLE:
                    raise self.fail(195)
                if kind is K.CONST or (kind is K.PINNUM and pin_const):
                    self.item_constant(int(el.value))
                else:
                    self.item_variable(int(el.value), False)
                return
            if kind is K.UNOP:
                if self.cc_mode:
                    raise self.fail(189)
                self._push(int(el.value))
            elif kind is K.BINOP and el.value == OP_SUB:
                self._push(OP_NEG)  # a leading '-' negates
            elif kind is K.LPAREN:
                self._open()
            else:
                raise self.fail(188 if self.cc_mode else 141)

    def _after_operand(
        self, conditional: bool, split: int, auto_op: int
    ) -> tuple[Element, bool, int]:
        """Emit what the operand completes and read what follows it.

        Returns (operator element, False, split) when another operand follows, or (end, True,
        split) when the expression is over (the cursor is then just past its last element);
        ``split`` becomes -1 once the CASE part has been reached.
        """
        while True:
            self._flush()
            el = self.get()
            if split > 0 and self.idx == split + 1:  # the CASE part starts here
                if el.kind is not K.COND1:
                    self.idx -= 1
                    el = Element(K.COND1, auto_op, el.start, el.length)
                elif auto_op != OP_EQ:
                    raise self.fail(141)
                split = -1
            kind = el.kind
            if kind is K.UNDEF:
                raise self.fail(110)
            if kind in (K.COND1, K.COND2, K.BINOP):
                return el, False, split
            if kind is K.RPAREN and not (conditional and self.open_parens == 2):
                self.open_parens = (self.open_parens - 1) & 0xFF
                if self._pop1() is None:
                    return el, True, split  # a ')' of the caller (index or enclosing group)
                continue
            if kind in (K.CONST, K.VARIABLE, K.UNOP, K.LPAREN):
                raise self.fail(142)
            if kind is not K.RPAREN and split >= 1:
                self.idx = split  # the SELECT expression is done: go on with the CASE part
                continue
            if conditional:
                self._close()
                self._close()
            if self.ops_len != self.ops_floor:
                raise self.fail(142)
            return el, True, split

    def append_expression(self, left: Bits, right: Bits, op: int) -> Bits:
        """The condition ``left op right`` from two compiled conditions (CASE lists).

        Parallax's tokenizer appends ``right`` (after a 1 bit) to ``left`` 16 bits at a time,
        counting the bits copied in a byte. For ``right`` of 255 bits or more that count
        wraps around before it reaches the length, so the copying starts over and goes on
        until the 496-bit buffer is full: error 144, whatever the lengths. Below that, the
        usual limit applies to the joined expression. The error is reported where the cursor
        is, just past the CASE item that was appended.
        """
        if right.length >= APPEND_COUNT_LIMIT:
            raise self.fail(144)
        try:
            self.expr = left.add(1, 1).join(right)
        except Failure:
            raise self.fail(144) from None
        self.item(op)
        return self.expr

    # ---- arguments of instructions ------------------------------------------------------
    # Each argument is compiled at the run-time stack depth it will find (``depth``: how many
    # values the instruction has pushed before it), which decides error 144. "pushed" ones are
    # written at once; "held" ones are returned to be written later, in the order the
    # interpreter pops them.
    def held_value(self, depth: int, pin_const: bool = False) -> Bits:
        self.stack_idx = depth
        self.value(pin_const)
        return self.expr

    def pushed_value(self, depth: int, one_before: bool = True, pin_const: bool = False) -> None:
        self.stack_idx = depth
        self.value(pin_const)
        self.emit_expr(one_before)

    def held_variable(self, depth: int, write: bool) -> Bits:
        self.stack_idx = depth
        self.read_write(write)
        return self.expr

    def pushed_write(self, depth: int) -> None:
        """A variable's write item, then the 0 bit that ends it."""
        self.held_variable(depth, write=True)
        self.emit_expr(False)
        self.emit(1, 0)
