"""SEROUT/DEBUG output lists and SERIN/DEBUGIN input lists with their formatters.

Output item: an expression ended by 0 (one value = the raw byte) or formatter code then value;
items are joined by 1 and the list ends with 0. ``DEC ? x`` / ``? x`` first print the text
"x = " (each character an item) and end with CR. Input item: ``0, write item, 0`` for a plain
byte, or ``1, formatter..., 0, write item, 0``.
"""

from __future__ import annotations

from bstool.tokenizer import tokens
from bstool.tokenizer.blocks import Blocks
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

    def _pins_and_baud(self, pin_stack: int, flow_stack: int, baud_stack: int) -> bool:
        self.stack_idx = pin_stack
        self.value_into(1, pin_const=True)
        flow = self.check(K.BACKSLASH)
        if flow:
            self.stack_idx = flow_stack
            self.value_into(2, pin_const=True)
        self.comma()
        self.stack_idx = baud_stack
        self.value_into(3)
        self.comma()
        return flow

    def _label_constant(self) -> None:
        self.emit(tokens.LABEL_CONSTANT_PREFIX_BITS, _LABEL_CONSTANT)
        self.address()

    def _timeout(self) -> None:
        self.stack_idx = 2
        self.value()
        self.comma()
        self._label_constant()
        self.comma()
        self.emit_exp(0, True)

    def _finish(self, flow: bool, plain: Instruction, with_flow: Instruction) -> None:
        self.emit_exp(3, True)
        self.emit_exp(1, True)
        if flow:
            self.emit_exp(2, True)
            self.emit_code(with_flow)
        else:
            self.emit_code(plain)
        self.expect(K.LBRACKET, 121)

    def op_serin(self) -> None:
        flow = self._pins_and_baud(4, 5, 3)
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
        self._finish(flow, Instruction.SERIN, Instruction.SERIN_FLOW)
        self.input_list()
        self.expect(K.RBRACKET, 122)

    def op_serout(self) -> None:
        flow = self._pins_and_baud(3, 4, 2)
        if self.peek().kind is not K.LBRACKET:
            self.stack_idx = 1
            self.value()
            self.comma()
            if flow:
                self._label_constant()
                self.comma()
            self.emit_exp(0, True)
        self._finish(flow, Instruction.SEROUT, Instruction.SEROUT_FLOW)
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
        while True:
            quote = echo = False
            el = self.get()
            kind = el.kind
            if kind is K.ASC_IO:
                self.expect(K.QUESTION, 116)
                echo = quote = True
                self._echo_text(True)
                self._plain_output()
            elif kind is K.STR_IO:
                if self.check(K.QUESTION):
                    echo = quote = True
                    self._echo_text(True)
                index = self._byte_variable()
                if not self.check(K.BACKSLASH):
                    self.emit_constant(index | tokens.SERIAL_ITEM_STRING, False)
                    self.emit_constant(tokens.SERIAL_STRING_DEFAULT, True)
                else:
                    self.emit_constant(index, False)
                    self.stack_idx = 1
                    self.value_emit(True)
                self.emit(1, 0)
            elif kind is K.REP_IO:
                self.stack_idx = 0
                self.value_emit(False)
                self.emit_constant(tokens.SERIAL_ITEM_REPEAT, True)
                self.expect(K.BACKSLASH, 118)
                self.stack_idx = 2
                self.value_emit(True)
                self.emit(1, 0)
            elif kind is K.NUM_IO:
                code = int(el.value)
                if self.check(K.QUESTION):
                    echo = True
                    self._echo_text(False)
                if echo and code & 0xF != 0x6:
                    code |= tokens.SERIAL_INDICATED
                self.emit_constant(code, False)
                self.stack_idx = 1
                self.value_emit(True)
                self.emit(1, 0)
            elif kind is K.QUESTION:
                echo = True
                self._echo_text(False)
                self.emit_constant(tokens.NUMBER_FORMATTERS["DEC"], False)
                self.stack_idx = 1
                self.value_emit(True)
                self.emit(1, 0)
            else:
                self.idx -= 1
                self._plain_output()
            if quote:
                self.emit_constant(tokens.ASCII_QUOTE, True)
                self.emit(1, 0)
            if echo:
                self.emit_constant(tokens.ASCII_CR, True)
                self.emit(1, 0)
            if not self.check(K.COMMA):
                break
            self.emit(1, 1)
        self.emit(1, 0)

    def _plain_output(self) -> None:
        self.stack_idx = 1
        self.value_emit(False)
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
                self.stack_idx = 2
                self.value_into(1)
                if self.check(K.BACKSLASH):
                    self.stack_idx = 0
                    self.value_emit(False)
                    self.emit(1, 1)
                    index |= tokens.SERIAL_ITEM_STRING
                self.emit_constant(index, False)
                self.emit_exp(1, True)
                self.emit(1, 0)
            elif kind is K.SKIP_IO:
                self.emit_constant(tokens.SERIAL_ITEM_REPEAT, True)
                self.stack_idx = 1
                self.value_emit(True)
                self.emit(1, 0)
            elif kind is K.WAITSTR_IO:
                index = self._byte_variable()
                if not self.check(K.BACKSLASH):
                    self.emit_constant(index | tokens.SERIAL_ITEM_WAITSTR, True)
                    self.emit_constant(tokens.SERIAL_STRING_DEFAULT, True)
                else:
                    flags = tokens.SERIAL_ITEM_WAITSTR | tokens.SERIAL_ITEM_STRING
                    self.emit_constant(index | flags, True)
                    self.stack_idx = 1
                    self.value_emit(True)
                self.emit(1, 0)
            elif kind is K.WAIT_IO:
                self._wait()
            elif kind in (K.NUM_IO, K.ANYNUM_IO):
                self.emit_constant(int(el.value), True)
                self.emit_constant(0, True)
                self.emit(1, 0)
                self.stack_idx = 1
                self.write_emit()
            else:
                self.idx -= 1
                self.emit(1, 0)
                self.stack_idx = 1
                self.write_emit()
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
            self.stack_idx = 0
            self.value_emit(False)
            self.emit(1, 1)
        self.idx = resume
        self.emit_constant(tokens.SERIAL_ITEM_WAIT, False)
        self.emit_constant(len(starts), True)
        self.emit(1, 0)
