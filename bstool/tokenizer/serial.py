"""SEROUT/DEBUG output lists and SERIN/DEBUGIN input lists with their formatters.

Output item: an expression ended by 0 (one value = the raw byte) or formatter code then value;
items are joined by 1 and the list ends with 0. ``DEC ? x`` / ``? x`` first print the text
"x = " (each character an item) and end with CR. Input item: ``0, write item, 0`` for a plain
byte, or ``1, formatter..., 0, write item, 0``.
"""

from __future__ import annotations

from bstool.tokenizer import tokens
from bstool.tokenizer.blocks import Blocks
from bstool.tokenizer.expressions import Bits
from bstool.tokenizer.lexer import Element, K
from bstool.tokenizer.tokens import Instruction

_LABEL_CONSTANT = tokens.LABEL_CONSTANT_PREFIX


class Serial(Blocks):
    source: bytearray

    def op_debug(self) -> None:
        self.emit_constant(tokens.DEBUG_BAUDMODE, True)
        self.emit_constant(tokens.SERIAL_PIN, True)
        self.emit_code(Instruction.SEROUT)
        self.output_list()

    def op_debugin(self) -> None:
        self.emit_constant(tokens.DEBUGIN_FLAG, True)
        self.emit_constant(tokens.DEBUG_BAUDMODE, True)
        self.emit_constant(tokens.SERIAL_PIN, True)
        self.emit_code(Instruction.SERIN)
        self.input_list()

    def _pins_and_baud(
        self, pin_depth: int, flow_depth: int, baud_depth: int
    ) -> tuple[Bits, Bits | None, Bits]:
        """``pin [\\flowpin], baudmode,``: (pin, flow pin or None, baud mode), held."""
        pin = self.held_value(pin_depth, pin_const=True)
        flow = self.held_value(flow_depth, pin_const=True) if self.check(K.BACKSLASH) else None
        self.comma()
        baud = self.held_value(baud_depth)
        self.comma()
        return pin, flow, baud

    def _label_constant(self) -> None:
        self.emit(tokens.LABEL_CONSTANT_PREFIX_BITS, _LABEL_CONSTANT)
        self.address()

    def _timeout(self) -> None:
        self.stack_idx = 2
        self.value()
        self.comma()
        self._label_constant()
        self.comma()
        self.emit_expr(True)

    def _finish(
        self, pins: tuple[Bits, Bits | None, Bits], plain: Instruction, with_flow: Instruction
    ) -> None:
        pin, flow, baud = pins
        self.emit_bits(baud, True)
        self.emit_bits(pin, True)
        if flow is not None:
            self.emit_bits(flow, True)
            self.emit_code(with_flow)
        else:
            self.emit_code(plain)
        self.expect(K.LBRACKET, 121)

    def op_serin(self) -> None:
        """SERIN pin[\\fpin], baud, [[plabel,] [timeout, tlabel,]] [inputs]."""
        pins = self._pins_and_baud(4, 5, 3)
        nxt = self.peek()
        if nxt.kind is K.LBRACKET:
            self.emit_constant(1, True)
        elif nxt.kind in (K.LABEL, K.UNDEF):
            self._label_constant()
            self.comma()
            if self.peek().kind is K.LBRACKET:
                self.emit_constant(0, True)
                self.emit_constant(1, True)
            else:
                self._timeout()
        else:
            self._timeout()
        self._finish(pins, Instruction.SERIN, Instruction.SERIN_FLOW)
        self.input_list()
        self.expect(K.RBRACKET, 122)

    def op_serout(self) -> None:
        """SEROUT pin[\\fpin], baud, [pace | timeout, tlabel,] [outputs]."""
        pins = self._pins_and_baud(3, 4, 2)
        if self.peek().kind is not K.LBRACKET:
            pace = self.held_value(1)
            self.comma()
            if pins[1] is not None:
                self._label_constant()
                self.comma()
            self.emit_bits(pace, True)
        self._finish(pins, Instruction.SEROUT, Instruction.SEROUT_FLOW)
        self.output_list()
        self.expect(K.RBRACKET, 122)

    # ---- output --------------------------------------------------------------------------
    def _byte_variable(self) -> int:
        el = self.get()
        if el.kind is not K.VARIABLE or not int(el.value) & 0x0200:
            raise self.fail(136)
        return int(el.value) & 0xFF

    def _char(self, code: int) -> None:
        self.emit_constant(code, False)
        self.emit(1, 0)
        self.emit(1, 1)

    def _echo_text(self, quote: bool) -> None:
        """Print the source text of the next expression followed by ' = '."""
        first = self.get()
        self.idx -= 1
        here = self.idx
        self.stack_idx = 0
        self.value()
        self.idx -= 1
        last = self.get()
        self.idx = here
        for offset in range(first.start, last.start + last.length):
            self._char(self.source[offset])
        for ch in " = ":
            self._char(ord(ch))
        if quote:
            self._char(tokens.ASCII_QUOTE)

    def output_list(self) -> None:
        """Output items, each followed by 1 (another follows) or 0 (end of the list).

        An item compiler returns (quoted, echoed): ``ASC ?``/``STR ?`` print the value
        between quotes, and every ``?`` item ends its line with CR.
        """
        compilers = {
            K.ASC_IO: self._out_asc,
            K.STR_IO: self._out_string,
            K.REP_IO: self._out_repeat,
            K.NUM_IO: self._out_number,
            K.QUESTION: self._out_question,
        }
        while True:
            el = self.get()
            compile_item = compilers.get(el.kind)
            if compile_item is None:
                self.idx -= 1
                self._plain_output()
                quoted = echoed = False
            else:
                quoted, echoed = compile_item(el)
            if quoted:
                self.emit_constant(tokens.ASCII_QUOTE, True)
                self.emit(1, 0)
            if echoed:
                self.emit_constant(tokens.ASCII_CR, True)
                self.emit(1, 0)
            if not self.check(K.COMMA):
                break
            self.emit(1, 1)
        self.emit(1, 0)

    def _out_asc(self, el: Element) -> tuple[bool, bool]:
        """ASC ? value: "value = "" then the character, then a closing quote."""
        self.expect(K.QUESTION, 116)
        self._echo_text(True)
        self._plain_output()
        return True, True

    def _out_string(self, el: Element) -> tuple[bool, bool]:
        """STR [?] bytevar [\\length]: the bytes of an array (a length of 32 by default)."""
        echoed = self.check(K.QUESTION)
        if echoed:
            self._echo_text(True)
        index = self._byte_variable()
        if self.check(K.BACKSLASH):
            self.emit_constant(index, False)
            self.pushed_value(1, True)
        else:
            self.emit_constant(index | tokens.SERIAL_ITEM_STRING, False)
            self.emit_constant(tokens.SERIAL_STRING_DEFAULT, True)
        self.emit(1, 0)
        return echoed, echoed

    def _out_repeat(self, el: Element) -> tuple[bool, bool]:
        """REP value\\count."""
        self.pushed_value(0, False)
        self.emit_constant(tokens.SERIAL_ITEM_REPEAT, True)
        self.expect(K.BACKSLASH, 118)
        self.pushed_value(2, True)
        self.emit(1, 0)
        return False, False

    def _out_number(self, el: Element) -> tuple[bool, bool]:
        """DEC/HEX/BIN... [?] value; with '?' HEX and BIN print their $ / % indicator."""
        formatter = int(el.value)
        echoed = self.check(K.QUESTION)
        if echoed:
            self._echo_text(False)
            if formatter & 0xF != tokens.NUMBER_FORMATTERS["DEC"] & 0xF:
                formatter |= tokens.SERIAL_INDICATED
        self._formatted_value(formatter)
        return False, echoed

    def _out_question(self, el: Element) -> tuple[bool, bool]:
        """? value: the same as DEC ? value."""
        self._echo_text(False)
        self._formatted_value(tokens.NUMBER_FORMATTERS["DEC"])
        return False, True

    def _formatted_value(self, formatter: int) -> None:
        self.emit_constant(formatter, False)
        self.pushed_value(1, True)
        self.emit(1, 0)

    def _plain_output(self) -> None:
        self.pushed_value(1, False)
        self.emit(1, 0)

    # ---- input ---------------------------------------------------------------------------
    def input_list(self) -> None:
        while True:
            el = self.get()
            kind = el.kind
            if kind is K.STR_IO:
                self.emit(1, 1)
                index = self._byte_variable()
                self.expect(K.BACKSLASH, 118)
                length = self.held_value(2)
                if self.check(K.BACKSLASH):
                    self.pushed_value(0, False)  # the end character
                    self.emit(1, 1)
                    index |= tokens.SERIAL_ITEM_STRING
                self.emit_constant(index, False)
                self.emit_bits(length, True)
                self.emit(1, 0)
            elif kind is K.SKIP_IO:
                self.emit_constant(tokens.SERIAL_ITEM_REPEAT, True)
                self.pushed_value(1, True)
                self.emit(1, 0)
            elif kind is K.WAITSTR_IO:
                index = self._byte_variable()
                if not self.check(K.BACKSLASH):
                    self.emit_constant(index | tokens.SERIAL_ITEM_WAITSTR, True)
                    self.emit_constant(tokens.SERIAL_STRING_DEFAULT, True)
                else:
                    flags = tokens.SERIAL_ITEM_WAITSTR | tokens.SERIAL_ITEM_STRING
                    self.emit_constant(index | flags, True)
                    self.pushed_value(1, True)
                self.emit(1, 0)
            elif kind is K.WAIT_IO:
                self._wait()
            elif kind in (K.NUM_IO, K.ANYNUM_IO):
                self.emit_constant(int(el.value), True)
                self.emit_constant(0, True)
                self.emit(1, 0)
                self.pushed_write(1)
            else:
                self.idx -= 1
                self.emit(1, 0)
                self.pushed_write(1)
            if not self.check(K.COMMA):
                break
            self.emit(1, 1)
        self.emit(1, 0)

    def _wait(self) -> None:
        self.emit(1, 1)
        self.expect(K.LPAREN, 119)
        starts: list[int] = []
        el: Element
        while True:
            starts.append(self.idx)
            self.stack_idx = 5 - (len(starts) - 1)
            self.value()
            el = self.get()
            if el.kind is not K.COMMA or len(starts) == 6:
                break
        if len(starts) == 6 and el.kind is K.COMMA:
            raise self.fail(147)
        self.idx -= 1
        self.expect(K.RPAREN, 120)
        resume = self.idx
        for start in reversed(starts):
            self.idx = start
            self.pushed_value(0, False)
            self.emit(1, 1)
        self.idx = resume
        self.emit_constant(tokens.SERIAL_ITEM_WAIT, False)
        self.emit_constant(len(starts), True)
        self.emit(1, 0)
