"""Instruction compilers: one small method per PBASIC instruction (or family).

A statement is written as its argument items (each preceded by a 1 bit), a 0 bit with the
6-bit instruction code, then inline fields (see tokens.py and ../../docs/tokenizer.md). The
PBASIC 2.5 block statements (IF/ELSEIF/ELSE/ENDIF, DO/LOOP, EXIT, SELECT/CASE, ON) have no
instruction of their own on the BS2sx: they are laid out as IF...THEN and GOTO instructions,
with forward addresses reserved and patched when the block closes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from bstool.tokenizer import tokens
from bstool.tokenizer.declarations import Declarations
from bstool.tokenizer.diagnostics import Failure
from bstool.tokenizer.expressions import Bits
from bstool.tokenizer.lexer import OP_EQ, Element, K
from bstool.tokenizer.tokens import Binary, Instruction, Unary

MAX_EXITS = 16
NEST_LIMIT = 16
ADDR = tokens.ADDRESS_BITS


class Nest(Enum):
    """Kinds of open blocks."""

    IF = "IF"
    FOR = "FOR"
    DO = "DO"
    SELECT = "SELECT"


@dataclass
class Block:
    kind: Nest = Nest.FOR
    element: int = 0  # element index of the opening word (for "... without ..." errors)
    exp_idx: int = 0  # SELECT: element index where its expression starts
    jump: int = 0  # loop start address (FOR, DO)
    skip: int = 0  # address field to patch when the current part ends (0 = none)
    exits: list[int] = field(default_factory=lambda: [0] * MAX_EXITS)
    # IF blocks only
    single_line: bool = False  # IF c THEN statement(s) [ELSE statement(s)] on one line
    in_else: bool = False  # compiling the ELSE part
    awaiting: bool = False  # single-line: THEN/ELSE just read, its statement follows on this line


class Statements(Declarations):
    """Compiles the instructions of one slot into ``self.image``."""

    def init_statements(self, gosubs: int) -> None:
        self.blocks = [Block() for _ in range(4 * NEST_LIMIT)]
        self.depth = 0
        self.counts = {"for": 0, "if": 0, "do": 0, "select": 0}
        self.gosubs = 0
        self.patches: list[tuple[int, int]] = []  # (element index, address field)
        self.image.pos = (gosubs + 1) * ADDR
        self.statement_starts: list[tuple[int, int]] = []  # (source offset, bit address)
        # the element the statement loop read last (where a failing final END is reported)
        self.loop_element = Element(K.END, 0, 0, 0)

    # ---- helpers ------------------------------------------------------------------------
    @property
    def top(self) -> Block:
        return self.blocks[self.depth - 1]

    def reserve(self) -> int:
        """Leave room for a 14-bit address to patch later; return where it is."""
        at = self.image.pos
        self.image.pos += ADDR
        return at

    def patch_here(self, at: int) -> None:
        self.patch(at, self.image.pos)

    def patch(self, at: int, address: int) -> None:
        """Write a 14-bit address into a reserved field (a DATA overlap is error 124)."""
        try:
            self.image.patch_address(at, address)
        except Failure as exc:
            if exc.offset < 0:
                raise self.fail(exc.code) from None
            raise

    def address(self) -> None:
        """A label: its address now, or a reserved field patched at the end."""
        el = self.get()
        if el.kind is K.LABEL:
            self._emit_address(int(el.value))
        elif el.kind is K.UNDEF:
            self.patches.append((self.idx - 1, self.image.pos))
            self.image.pos += ADDR
        else:
            raise self.fail(148)

    def _emit_address(self, value: int) -> None:
        self.emit(3, value)
        self.emit(11, value >> 3)

    def comma(self) -> None:
        self.expect(K.COMMA, 133)

    def more_or_bracket(self) -> bool:
        """',' (1 bit, more follows) or ']' (0 bit); True at ']'."""
        el = self.get()
        if el.kind is K.COMMA:
            self.emit(1, 1)
            return False
        if el.kind is not K.RBRACKET:
            raise self.fail(134)
        self.emit(1, 0)
        return True

    def nesting_error(self) -> None:
        """A closing word that does not match the innermost open block."""
        block = self.top
        if block.kind is Nest.IF:
            if not block.awaiting:
                raise self.fail(161)
            return  # an IF opened on this very line: the IDE reports nothing here
        raise self.fail({Nest.FOR: 176, Nest.DO: 177, Nest.SELECT: 182}[block.kind])

    def patch_skip(self) -> None:
        block = self.top
        if block.skip > 0:
            self.patch_here(block.skip)
            block.skip = 0

    def patch_exits(self) -> None:
        for at in self.top.exits:
            if at == 0:
                break
            self.patch_here(at)

    def push(self, kind: Nest, element: int) -> Block:
        block = self.blocks[self.depth]
        block.kind = kind
        block.element = element
        return block

    # ---- the statement loop -------------------------------------------------------------
    def compile_program(self) -> None:
        started = False
        while self.more():
            el = self.loop_element = self.get()
            if el.kind is K.LABEL:
                raise self.fail(117)
            if el.kind is K.UNDEF:
                self.new_symbol_room()
                self.symbols[el.name] = (K.LABEL, self.image.pos)
                if self.lang25:
                    nxt = self.loop_element = self.peek()
                    if nxt.kind is not K.END or not nxt.soft:
                        raise self.fail(174)
            else:
                if not started:
                    self.patch(0, self.image.pos)
                    started = True
                self.statement_starts.append((el.start, self.image.pos))
                if el.kind in (K.VARIABLE, K.PINNUM):
                    self.idx -= 1
                    self.op_let()
                elif el.kind is not K.INSTRUCTION:
                    raise self.fail(149)
                else:
                    self.dispatch(str(el.value), el)
            self.end_of_statement()
        if started:
            # The END after the last statement: Parallax reports a failure here (127, the
            # slot is full) at the element its statement loop read last, the first word of
            # the last statement (or what it looked at after a label or inside a one-line IF).
            el = self.loop_element
            self.err = (el.start, el.length)
            self.emit_code(Instruction.END)
        if self.lang25 and self.depth > 0:
            block = self.top
            self.idx = block.element
            self.get()
            if block.kind is Nest.IF:
                raise self.fail(168)
            raise self.fail({Nest.FOR: 169, Nest.DO: 170, Nest.SELECT: 184}[block.kind])

    def end_of_statement(self) -> None:
        """Check what ends a statement; a line end also closes a single-line IF."""
        block = self.top if self.counts["if"] else None
        if block is None or block.kind is not Nest.IF or not block.single_line:
            self.expect_end()
            return
        if block.awaiting:  # the statement after THEN/ELSE follows on the same line
            block.awaiting = False
            return
        nxt = self.loop_element = self.peek()
        at_else = nxt.kind is K.INSTRUCTION and nxt.value in ("ELSE", "ELSEIF")
        if (block.in_else or not at_else) and not self.expect_end():
            if block.exits[0] > 0:
                self.patch_exits()
            self.patch_skip()
            self.depth -= 1
            self.counts["if"] -= 1

    def dispatch(self, name: str, el: Element) -> None:
        method = getattr(self, "op_" + name.lower(), None)
        if method is None:  # pragma: no cover - every reserved instruction has a method
            raise self.fail(149)
        method()

    def patch_remaining(self) -> None:
        for element, at in self.patches:
            self.idx = element
            el = self.get()
            if el.kind is K.UNDEF:
                raise self.fail(111)
            self.patch(at, int(el.value))

    # ---- simple instructions ------------------------------------------------------------
    def _pin_op(self, code: Instruction) -> None:
        self.pushed_value(0, True, pin_const=True)
        self.emit_code(code)

    def op_high(self) -> None:
        self._pin_op(Instruction.HIGH)

    def op_low(self) -> None:
        self._pin_op(Instruction.LOW)

    def op_toggle(self) -> None:
        self._pin_op(Instruction.TOGGLE)

    def op_input(self) -> None:
        self._pin_op(Instruction.INPUT)

    def op_output(self) -> None:
        self._pin_op(Instruction.OUTPUT)

    def op_reverse(self) -> None:
        self._pin_op(Instruction.REVERSE)

    def _value_op(self, code: Instruction, resume: bool = False) -> None:
        self.pushed_value(0, True)
        self.emit_code(code)
        if resume:
            self._emit_address(self.image.pos + ADDR)

    def op_pause(self) -> None:
        self._value_op(Instruction.PAUSE)

    def op_run(self) -> None:
        self._value_op(Instruction.RUN)

    def op_nap(self) -> None:
        self._value_op(Instruction.NAP, resume=True)

    def op_sleep(self) -> None:
        self._value_op(Instruction.SLEEP, resume=True)

    def op_end(self) -> None:
        self.emit_code(Instruction.END)

    def op_stop(self) -> None:
        self.emit_code(Instruction.STOP)

    def op_return(self) -> None:
        self.emit_code(Instruction.RETURN)

    def op_goto(self) -> None:
        self.emit_code(Instruction.GOTO)
        self.address()

    def op_gosub(self) -> None:
        self.emit_code(Instruction.GOSUB)
        self.gosubs += 1
        self.emit(tokens.GOSUB_ID_BITS, self.gosubs)
        self.address()
        self.patch(self.gosubs * ADDR, self.image.pos)

    def op_let(self) -> None:
        """variable = value: the value, then the variable's write item."""
        target = self.held_variable(1, write=True)
        el = self.get()
        if el.kind is not K.COND1 or el.value != OP_EQ:
            raise self.fail(150)
        self.pushed_value(0)
        self.emit_bits(target, True)
        self.emit_code(Instruction.DONE)

    def op_random(self) -> None:
        here = self.idx
        self.stack_idx = 0
        self.read_write(False)
        self.emit_expr(True)
        self.emit_code(Instruction.RANDOM)
        self.idx = here
        self.pushed_write(1)

    def _pin_then(self, pin_depth: int) -> None:
        """``pin, value``: the value is pushed first, then the pin."""
        pin = self.held_value(pin_depth, pin_const=True)
        self.comma()
        self.pushed_value(0)
        self.emit_bits(pin, True)

    def op_pulsout(self) -> None:
        self._pin_then(1)
        self.emit_code(Instruction.PULSOUT)

    def _measure(self, code: Instruction) -> None:
        self._pin_then(1)
        self.comma()
        self.emit_code(code)
        self.pushed_write(self.stack_idx)  # at the depth the arguments left

    def op_pulsin(self) -> None:
        self._measure(Instruction.PULSIN)

    def op_count(self) -> None:
        self._measure(Instruction.COUNT)

    def op_rctime(self) -> None:
        self._measure(Instruction.RCTIME)

    def op_pwm(self) -> None:
        """PWM pin, duty, cycles: duty, cycles, pin."""
        pin = self.held_value(2, pin_const=True)
        self.comma()
        self.pushed_value(0)
        self.comma()
        self.pushed_value(1)
        self.emit_bits(pin, True)
        self.emit_code(Instruction.PWM)

    def op_freqout(self) -> None:
        self.pushed_value(0, True, pin_const=True)
        self.comma()
        self.pushed_value(1, True)
        self.comma()
        self.pushed_value(2, True)
        if self.check(K.COMMA):
            self.pushed_value(3, True)
            self.emit_code(Instruction.FREQOUT2)
        else:
            self.emit_code(Instruction.FREQOUT1)

    def op_dtmfout(self) -> None:
        self.pushed_value(0, True, pin_const=True)
        self.comma()
        if self.peek().kind is K.LBRACKET:
            self.emit_constant(tokens.DTMF_DEFAULT_OFF_MS, True)
            self.emit_constant(tokens.DTMF_DEFAULT_ON_MS, True)
        else:
            on_time = self.held_value(2)
            self.comma()
            self.pushed_value(1)  # off time
            self.comma()
            self.emit_bits(on_time, True)
        self.emit_code(Instruction.DTMFOUT)
        self.expect(K.LBRACKET, 121)
        while True:
            self.pushed_value(3, False)
            self.emit(1, 0)
            if self.more_or_bracket():
                return

    def op_xout(self) -> None:
        self.pushed_value(0, True, pin_const=True)
        self.comma()
        self.pushed_value(1, True, pin_const=True)
        self.comma()
        self.emit_code(Instruction.XOUT)
        self.expect(K.LBRACKET, 121)
        while True:
            self.pushed_value(2, False)
            self.expect(K.BACKSLASH, 118)
            self.emit_constant(tokens.X10_KEY_BASE, True)
            self.emit_operator(Binary.MOD)
            self.pushed_value(3, True)
            self.emit_constant(tokens.X10_KEY_BASE, True)
            self.emit_operator(Binary.MUL)
            self.emit_operator(Binary.ADD)
            if self.check(K.BACKSLASH):
                self.pushed_value(3, True)
            else:
                self.emit_constant(tokens.XOUT_DEFAULT_CYCLES, True)
            self.emit_operator(Unary.NOT)
            self.emit(1, 0)
            if self.more_or_bracket():
                return

    def op_button(self) -> None:
        """BUTTON pin, downstate, delay, rate, workspace, targetstate, label."""
        pin = self.held_value(5, pin_const=True)
        self.comma()
        for depth in (0, 1, 2):  # downstate, delay, rate
            self.pushed_value(depth)
            self.comma()
        here = self.idx
        workspace_read = self.held_variable(4, write=False)
        self.idx = here
        workspace_write = self.held_variable(1, write=True)
        self.comma()
        self.pushed_value(3)  # targetstate
        self.comma()
        self.emit_bits(workspace_read, True)
        self.emit_bits(pin, True)
        self.emit_code(Instruction.BUTTON)
        self.emit_bits(workspace_write, False)
        self.emit(1, 0)
        self.address()

    def _shift_header(self, code: Instruction) -> None:
        """dpin, cpin, mode, [: mode, dpin, cpin."""
        data_pin = self.held_value(1, pin_const=True)
        self.comma()
        clock_pin = self.held_value(2, pin_const=True)
        self.comma()
        self.pushed_value(0)
        self.comma()
        self.emit_bits(data_pin, True)
        self.emit_bits(clock_pin, True)
        self.emit_code(code)
        self.expect(K.LBRACKET, 121)

    def _shift_bits(self) -> None:
        if self.check(K.BACKSLASH):
            self.pushed_value(3, False)
        else:
            self.emit_constant(tokens.SHIFT_DEFAULT_BITS, False)

    def op_shiftin(self) -> None:
        self._shift_header(Instruction.SHIFTIN)
        while True:
            target = self.held_variable(5, write=True)
            self._shift_bits()
            self.emit_constant(0, True)
            self.emit(1, 0)
            self.emit_bits(target, False)
            self.emit(1, 0)
            if self.more_or_bracket():
                return

    def op_shiftout(self) -> None:
        self._shift_header(Instruction.SHIFTOUT)
        while True:
            value = self.held_value(4)
            self._shift_bits()
            self.emit_bits(value, True)
            self.emit(1, 0)
            if self.more_or_bracket():
                return

    # ---- tables and branches ------------------------------------------------------------
    def op_branch(self) -> None:
        self.pushed_value(0, True)
        self.emit_code(Instruction.BRANCH)
        self.comma()
        self.expect(K.LBRACKET, 121)
        while True:
            self.address()
            if self.more_or_bracket():
                return

    def _value_list(self, depth: int) -> None:
        self.expect(K.LBRACKET, 121)
        while True:
            self.pushed_value(depth, False)
            self.emit(1, 0)
            if self.more_or_bracket():
                break
        self.comma()
        self.pushed_write(1)

    def op_lookup(self) -> None:
        self.pushed_value(0, True)
        self.emit_code(Instruction.LOOKUP)
        self.comma()
        self._value_list(2)

    def op_lookdown(self) -> None:
        self.pushed_value(0, True)
        self.emit_code(Instruction.LOOKDOWN)
        self.comma()
        el = self.get()
        if el.kind is K.COND1:
            compare = int(el.value)
        else:
            if el.kind is not K.LBRACKET:
                raise self.fail(143)
            self.idx -= 1
            compare = OP_EQ
        self.emit(tokens.COMPARE_BITS, compare)
        self._value_list(3)

    def op_on(self) -> None:
        self.stack_idx = 0
        self.value()
        el = self.get()
        if el.kind is not K.INSTRUCTION or el.value not in ("GOTO", "GOSUB"):
            raise self.fail(185)
        gosub = el.value == "GOSUB"
        if gosub:
            self.emit_code(Instruction.GOSUB)
            self.gosubs += 1
            self.emit(tokens.GOSUB_ID_BITS, self.gosubs)
            self._emit_address(self.image.pos + ADDR)
        self.emit_expr(True)
        self.emit_code(Instruction.BRANCH)
        while True:
            self.address()
            el = self.get()
            if el.kind is K.COMMA:
                self.emit(1, 1)
                continue
            if el.kind is not K.END:
                raise self.fail(130)
            self.emit(1, 0)
            break
        self.idx -= 1
        if gosub:
            self.emit_code(Instruction.RETURN)
            self.patch(self.gosubs * ADDR, self.image.pos)

    # ---- EEPROM and scratchpad ----------------------------------------------------------
    # READ/GET/WRITE/PUT take a list of items in PBASIC 2.5; each item is a transfer of its
    # own at location + n. A WORD item is two byte transfers: low byte, then high byte at + 1.

    def _location_plus(self, location: Bits, offset: int) -> Bits:
        """The expression ``location + offset``."""
        self.expr = location
        self.item_constant(offset)
        self.item(Binary.ADD)
        return self.expr

    def _high_part(self, value: Bits) -> Bits:
        """The expression ``value >> 8`` (the high byte of a WORD value)."""
        self.expr = value
        self.item_constant(8)
        self.item(Binary.SHR)
        return self.expr

    def _word_prefix(self, code: int) -> int | None:
        """PBASIC 2.5 ``WORD`` before an item: the element index after it (None: no WORD)."""
        if not (self.lang25 and self.peek().kind is K.VARTYPE):
            return None
        if self.get().value != tokens.VarSize.WORD:
            raise self.fail(code)
        return self.idx

    def _check_word_variable(self, var_at: int) -> None:
        """The variable after WORD must be a whole Word variable (no modifier): error 173."""
        here = self.idx
        self.idx = var_at
        el = self.get()
        if (int(el.value) >> 8) & 0xF != tokens.VarSize.WORD:
            raise self.fail(173)
        if self.get().kind is K.PERIOD:
            last = self.get()
            raise Failure(173, el.start, last.start + last.length - el.start)
        self.idx = here

    def _high_byte_target(self, word_write: Bits) -> Bits:
        """The write item of ``var.HIGHBYTE`` made from the write item of word ``var``.

        The word's item is the last 10 bits: a 6-bit item code and the word's number. Its
        high byte is byte number 2 * word + 1 with the item's size changed to Byte; an index
        counted in words is doubled (``var(i)`` -> ``var.HIGHBYTE(i * 2)``). What comes
        before the item (index items, and the 1 that announces the item) is kept, as Parallax's
        tokenizer keeps it: see _drop_word_item for the bits it changes on the way.
        """
        code, word = word_write.value >> 4 & 0x3F, word_write.value & 0xF
        self.expr = _drop_word_item(word_write)
        if self.expr.length:
            # the constant 2 (item $21, flag 0: exactly 2^1) takes the announced place
            self._bits(6, tokens.CONSTANT_ITEM | 1)
            self._bits(1, 0)
            self.item(Binary.MUL)
            self._bits(1, 1)
        self._bits(6, (code & ~3) | tokens.VarSize.BYTE)
        self._bits(5, 2 * word + 1)
        return self.expr

    def _list_end(self) -> bool:
        """After an item: True when another one follows (a ',' in PBASIC 2.5)."""
        nxt = self.peek() if self.lang25 else Element(K.END, 0, 0, 0)
        if nxt.kind is K.COMMA:
            return False
        if nxt.kind is not K.END:
            self.get()
            raise self.fail(130)
        return True

    def _read_list(self, code: Instruction, resume: bool) -> None:
        """READ/GET location, item {, item}: the location is pushed once, later items add n."""
        self.pushed_value(0, True)
        location = self.expr
        self.emit_code(code)
        self.comma()
        offset = 0
        while True:
            if resume:
                self._emit_address(self.image.pos + ADDR)
            word_at = self._word_prefix(172)
            self.pushed_write(1)
            if word_at is not None:
                self._check_word_variable(word_at)
                word_write = self.expr
                offset += 1
                self._location_plus(location, offset)
                self.emit_expr(True)
                self.emit_code(code)
                if resume:
                    self._emit_address(self.image.pos + ADDR)
                self._high_byte_target(word_write)
                self.emit_expr(False)
                self.emit(1, 0)
            offset += 1
            if self._list_end():
                return
            self._location_plus(location, offset)
            self.emit_expr(True)
            self.emit_code(code)
            self.comma()

    def op_read(self) -> None:
        self._read_list(Instruction.READ, resume=True)

    def op_get(self) -> None:
        self._read_list(Instruction.GET, resume=False)

    def op_write(self) -> None:
        """WRITE location, item {, item}: value pushed, then location (+ n), WRITE."""
        location = self.held_value(1)
        offset = 0
        while True:
            self.comma()
            word = self._word_prefix(227) is not None
            self.pushed_value(0, True)
            value = self.expr
            self.expr = self._location_plus(location, offset) if offset else location
            self.emit_expr(True)
            self.emit_code(Instruction.WRITE)
            self._emit_address(self.image.pos + ADDR)
            if word:
                self._high_part(value)
                self.emit_expr(True)
                offset += 1
                self._location_plus(location, offset)
                self.emit_expr(True)
                self.emit_code(Instruction.WRITE)
                self._emit_address(self.image.pos + ADDR)
            offset += 1
            if self._list_end():
                return

    def op_put(self) -> None:
        """PUT location, item {, item}: location (+ n) pushed, then value, PUT."""
        location = self.held_value(0)
        offset = 0
        while True:
            self.comma()
            word = self._word_prefix(227) is not None
            self.expr = self._location_plus(location, offset) if offset else location
            self.emit_expr(True)
            self.pushed_value(1, True)
            value = self.expr
            self.emit_code(Instruction.PUT)
            if word:
                offset += 1
                self._location_plus(location, offset)
                self.emit_expr(True)
                self._high_part(value)
                self.emit_expr(True)
                self.emit_code(Instruction.PUT)
            offset += 1
            if self._list_end():
                return


_WORD_BITS = 16  # Parallax's expression buffer is an array of 16-bit words
_WORD_ITEM_BITS = 10  # a Word variable's item: 6-bit code + 4-bit register number


def _drop_word_item(expr: Bits) -> Bits:
    """``expr`` without its last item (a Word variable's 10 bits), as Parallax rebuilds it.

    Parallax's tokenizer keeps an expression in 16-bit words filled from the most significant
    bit; the last word holds its ``n = length % 16`` bits right-aligned (a full word when
    ``n`` is 0). To cut off the item it takes the word that holds the item's first bit as if
    that word were full: it keeps that word's bits above the item by shifting the word right
    by ``16 - s`` (``s`` = the item's first bit's place in the word). That is right when the
    word is full or the item runs on into the next word. When the item lies wholly inside the
    last, partly filled word (``m`` = 10..15 bits in it), the shift is ``16 - m`` too far: the
    ``m - 10`` bits before the item in that word come out shifted right by ``16 - m`` with
    zeros above them. The length is then simply reduced by 10.

    This is what the vectors ``fuzz_word_read_const_index`` (``wa(1000)``: the 1 announcing
    the item becomes 0) and ``fuzz_word_get_nested_index`` (``v3(v5(1))``: 4 bits ``0101``
    become ``0001``) show; it happens for a constant index of 10-14 significant bits that is
    not a power of two, and for other index expressions whose length puts the item there.
    """
    length = expr.length - _WORD_ITEM_BITS
    prefix = expr.value >> _WORD_ITEM_BITS
    word = length // _WORD_BITS
    in_last = expr.length - word * _WORD_BITS  # bits of the buffer in the item's word
    before = in_last - _WORD_ITEM_BITS  # bits before the item in that word
    if in_last < _WORD_BITS and before > 0:
        kept = prefix & ((1 << before) - 1)
        prefix = (prefix >> before << before) | (kept >> (_WORD_BITS - in_last))
    return Bits(prefix, length)
