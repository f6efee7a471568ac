"""PIN, CON, DATA and VAR declarations (the passes that run before code is compiled).

Each kind is tried once allowing forward references, then compiled for good, in Parallax's
order: PIN, CON, DATA (try) / CON, PIN, DATA (final) / VAR (count) / VAR (allocate). A symbol
that is still unknown in the final pass is an error, so a constant may refer forward by one
step but not along a longer chain. Handled lines are cancelled so the instruction compiler
never sees them.
"""

from __future__ import annotations

from bstool.tokenizer import tokens
from bstool.tokenizer.diagnostics import Failure
from bstool.tokenizer.expressions import Compiler
from bstool.tokenizer.image import DEFINED_DATA
from bstool.tokenizer.lexer import OP_SUB, Element, K

# operators allowed in a constant declaration, as functions of two 16-bit words
CONSTANT_OPS = {
    int(tokens.Binary.SHL): lambda a, b: a << min(b, 16),
    int(tokens.Binary.SHR): lambda a, b: a >> min(b, 16),
    int(tokens.Binary.AND): lambda a, b: a & b,
    int(tokens.Binary.OR): lambda a, b: a | b,
    int(tokens.Binary.XOR): lambda a, b: a ^ b,
    int(tokens.Binary.ADD): lambda a, b: a + b,
    int(tokens.Binary.SUB): lambda a, b: a - b,
    int(tokens.Binary.MUL): lambda a, b: a * b,
    int(tokens.Binary.DIV): lambda a, b: a // b,
}
_DIV = int(tokens.Binary.DIV)
# RAM a program's VAR declarations may take: all of it but INS, OUTS and DIRS
_USER_RAM_BITS = tokens.RAM_VARIABLE_BYTES * 8
CONSTANT_KINDS = (K.CONST, K.PINNUM, K.DIRECTIVE, K.TARGET)
_BITS_PER = {0: 1, 1: 4, 2: 8, 3: 16}


class Declarations(Compiler):
    var_counts: list[int]
    var_bits: int
    data_address: int
    data_label: str | None

    def cancel(self, first: int, last: int) -> None:
        for i in range(first, last + 1):
            if i < len(self.elements):
                self.dead[i] = 1  # (loop kept simple: lines are short)

    def constant(self, final: bool) -> tuple[int, bool]:
        """A constant expression ``[-]term {op [-]term}``: left to right, in 16 bits.

        Returns (value, resolved). Before the final pass a name not defined yet stands for 1
        (so a division cannot fail on it) and makes the result unresolved.
        """
        # fast path: a lone number (most DATA items)
        elements, dead, n = self.elements, self.dead, len(self.elements)
        i = self.idx
        if i < n and dead[i]:  # skip cancelled elements
            i = dead.find(0, i)
            i = n if i < 0 else i
        if i < n and elements[i].kind is K.CONST:
            j = i + 1
            if j < n and dead[j]:  # skip cancelled elements
                j = dead.find(0, j)
                j = n if j < 0 else j
            if j >= n or elements[j].kind is not K.BINOP:
                el = elements[i]
                self.idx = i + 1
                self.err = (el.start, el.length)
                return int(el.value), True
        value, resolved = self._constant_term(final)
        while True:
            op = self.peek()
            fold = CONSTANT_OPS.get(int(op.value)) if op.kind is K.BINOP else None
            if fold is None:
                return value, resolved
            self.idx += 1
            operand, known = self._constant_term(final)
            resolved = resolved and known
            if op.value == _DIV and operand == 0:
                raise self.fail(113)
            value = fold(value, operand) & 0xFFFF

    def _constant_term(self, final: bool) -> tuple[int, bool]:
        """``[-]operand`` of a constant expression: (16-bit value, known)."""
        el = self.get()
        negative = el.kind is K.BINOP
        if negative:
            if el.value != OP_SUB:
                raise self.fail(112)
            el = self.get()
        if el.kind in CONSTANT_KINDS:
            value, known = int(el.value), True
        elif el.kind is K.UNDEF:
            if final:
                raise self.fail(110)
            value, known = 1, False
        else:
            raise self.fail(112)
        return (-value if negative else value) & 0xFFFF, known

    def _new_symbol(self) -> str:
        el = self.get()
        if el.kind is not K.UNDEF:
            raise self.fail(123)
        self.new_symbol_room()
        return el.name

    def case_item_is_range(self) -> bool:
        """Is the CASE item at the cursor ``low TO high``? (a TO before the next ',' or end;
        the cursor is left where it was)"""
        here, err = self.idx, self.err
        el = self.get()
        while el.kind not in (K.COMMA, K.TO, K.END) and self.more():
            el = self.get()
        self.idx, self.err = here, err
        return el.kind is K.TO

    def more(self) -> bool:
        """True while a non-cancelled element remains at or after the cursor."""
        dead, n = self.dead, len(self.dead)
        idx = self.idx
        if idx < n and dead[idx]:  # skip cancelled elements
            idx = dead.find(0, idx)
            idx = n if idx < 0 else idx
        self.idx = idx
        return idx < n

    def skip_line(self, el: Element) -> None:
        """Move past the end of the current line (unless ``el`` already was that end)."""
        if el.kind is K.END:
            return
        n = len(self.elements)
        i = self.next_end[min(self.idx, n)]
        while i < n and self.dead[i]:
            i = self.next_end[i + 1]
        if i < n:
            self.idx = i + 1
            self.err = (self.elements[i].start, self.elements[i].length)
        else:
            self.idx = n

    def _line_has(self, keyword: K, first_too: bool = False) -> bool:
        """Does the line at the cursor have ``keyword`` second (or first)? If not, skip it.

        A quick look at the raw elements (keywords are reserved words, so no symbol lookup is
        needed); it moves the cursor exactly as reading the two elements and skipping to the
        end of the line would.
        """
        elements, dead, n = self.elements, self.dead, len(self.elements)
        first = self.idx
        if first_too and elements[first].kind is keyword:
            return True
        second = first + 1
        if second < n and dead[second]:  # skip cancelled elements
            second = dead.find(0, second)
            second = n if second < 0 else second
        if second >= n:
            self.idx = n
            return False
        kind = elements[second].kind
        if kind is keyword:
            return True
        if kind is K.END:
            self.idx = second + 1
            return False
        end = self.next_end[second]
        while end < n and dead[end]:
            end = self.next_end[end + 1]
        self.idx = min(end + 1, n)
        return False

    def declare_constants(self, keyword: K, final: bool) -> None:
        """CON (or PIN) lines: ``name CON expression``."""
        self.idx = line = 0
        while self.more():
            if not self._line_has(keyword):
                line = self.idx
                continue
            self.get()
            el = self.get()
            if el.kind is keyword:
                self.idx = line
                name = self._new_symbol()
                self.idx += 1
                start = self.peek().start
                value, resolved = self.constant(final)
                if resolved:
                    if keyword is K.PIN and value > 15:
                        self.idx -= 1
                        last = self.get()
                        raise Failure(175, start, last.start - start + last.length)
                    kind = K.PINNUM if keyword is K.PIN else K.CONST
                    self.symbols[name] = (kind, value)
                    self.expect_end()
                    self.cancel(line, self.idx - 1)
                else:
                    self.expect_end()
            else:
                self.skip_line(el)
            line = self.idx

    def declare_data(self, final: bool) -> None:
        """DATA lines: ``[label] DATA item, ...`` with @address, WORD, (n) and repeats."""
        self.data_address = 0
        self.idx = line = 0
        while self.more():
            if not self._line_has(K.DATA, first_too=True):
                line = self.idx
                continue
            el = self.get()
            self.data_label = None
            if el.kind is not K.DATA:
                el = self.get()
                if el.kind is K.DATA:
                    self.idx = line
                    self.data_label = self._new_symbol()
                    self.cancel(line, self.idx - 1)
                    self.idx += 1
            if el.kind is K.DATA:
                el = self.get()
                if el.kind is K.END:
                    self._assign_label()
                    self.cancel(line, self.idx - 1)
                else:
                    el = self._data_items(el, final, line)
            self.skip_line(el)
            line = self.idx

    def _assign_label(self) -> None:
        if self.data_label is not None:
            self.symbols[self.data_label] = (K.CONST, self.data_address)
            self.data_label = None

    def _data_items(self, el: Element, final: bool, line: int) -> Element:
        """The items of one DATA line from ``el`` on; returns the END that finishes the line.

        An item is ``@address`` (move the fill address), ``[WORD] value``, ``[WORD] value(n)``
        (n copies) or ``[WORD] (n)`` (n bytes reserved, left undefined).
        """
        while True:
            if el.kind is K.AT:
                address, _ = self.constant(True)
                if address >= tokens.SLOT_BYTES:
                    raise self.fail(114)
                self.data_address = address
                self._assign_label()
            else:
                self._assign_label()
                if el.kind is K.CONST:
                    done, el = self._plain_numbers(el, final, line)
                    if done:
                        return el
                    if el.kind is not K.CONST or self.peek().kind in (K.COMMA, K.END):
                        continue
                self._data_item(el, final)
            el = self.get()
            if el.kind is K.END:
                if final:
                    self.cancel(line, self.idx - 1)
                return el
            if el.kind is not K.COMMA:
                raise self.fail(130)
            el = self.get()

    def _data_item(self, el: Element, final: bool) -> None:
        """One value item starting at ``el`` (an optional WORD, a value, a repeat count)."""
        word = el.kind is K.VARTYPE and el.value == tokens.VarSize.WORD
        if word:
            el = self.get()
        if el.kind is K.LPAREN:
            value, defined = 0, False
        else:
            self.idx -= 1
            value, _ = self.constant(final)
            defined = True
            if self.peek().kind is not K.LPAREN:
                self._store(value, word, True, final, el)
                return
            self.idx += 1
        count, _ = self.constant(True)
        for _ in range(count):
            self._store(value, word, defined, final, el)
        self.expect(K.RPAREN, 120)

    def _plain_numbers(self, el: Element, final: bool, line: int) -> tuple[bool, Element]:
        """Fast path for runs of plain numbers ``n, n, n``; same result as the general path.

        Returns (True, end element) when the line is finished, else (False, next item).
        """
        elements, dead, n = self.elements, self.dead, len(self.elements)
        flags, eeprom, where = self.image.flags, self.image.eeprom, self.image.data_source
        while True:
            j = self.idx
            if j < n and dead[j]:  # skip cancelled elements
                j = dead.find(0, j)
                j = n if j < 0 else j
            run_end = self.number_lists.get(j)
            if run_end is not None and self._store_number_list(el, j, run_end, final):
                el = elements[run_end - 1]
                self.idx = run_end
                self.err = (el.start, el.length)
                continue
            nxt = elements[j] if j < n else None
            if nxt is None or nxt.kind not in (K.COMMA, K.END):
                return False, el  # an operator or '(' follows: the general path handles it
            address = self.data_address
            if address >= tokens.SLOT_BYTES:
                raise self.fail(114)
            if final:
                if flags[address] & 3:
                    raise self.fail(115)
                flags[address] = 2
                eeprom[address] = int(el.value) & 0xFF
                where[address] = (el.start, el.length)
            self.data_address = address + 1
            self.idx = j + 1
            self.err = (nxt.start, nxt.length)
            if nxt.kind is K.END:
                if final:
                    self.cancel(line, self.idx - 1)
                return True, nxt
            k = self.idx
            if k < n and dead[k]:  # skip cancelled elements
                k = dead.find(0, k)
                k = n if k < 0 else k
            if k < n and elements[k].kind is K.CONST:
                el = elements[k]
                self.idx = k + 1
                self.err = (el.start, el.length)
                continue
            el = self.get()
            if el.kind is not K.CONST:
                return False, el

    def _store_number_list(self, first: Element, start: int, end: int, final: bool) -> bool:
        """Store ``first`` and the numbers of the lexer's list ``start``..``end`` that are
        followed by a comma (all but the last), in one go. False (nothing done) when a byte
        would be out of range or taken, or part of the list is cancelled: the element by
        element path then reports exactly where."""
        count = (end - start) // 2
        address = self.data_address
        image = self.image
        if address + count > tokens.SLOT_BYTES or self.dead.find(1, start, end) >= 0:
            return False
        if final:
            if image.flags.count(0, address, address + count) != count:
                return False
            numbers = [first, *self.elements[start + 1 : end - 1 : 2]]
            image.eeprom[address : address + count] = bytes(int(e.value) & 0xFF for e in numbers)
            image.flags[address : address + count] = bytes([DEFINED_DATA]) * count
            image.data_source.update(
                zip(
                    range(address, address + count),
                    [(e.start, e.length) for e in numbers],
                    strict=True,
                )
            )
        self.data_address = address + count
        return True

    def _store(self, value: int, word: bool, defined: bool, final: bool, item: Element) -> None:
        for part in (value, value >> 8) if word else (value,):
            if self.data_address >= tokens.SLOT_BYTES:
                raise self.fail(114)
            if final:
                try:
                    self.image.put_data(self.data_address, part, defined, (item.start, item.length))
                except Failure:
                    raise self.fail(115) from None
            self.data_address += 1

    def _allocation_bases(self) -> list[int]:
        """First register number of each size for the VAR declarations (final pass).

        RAM after INS/OUTS/DIRS is filled by size, largest first: all words, then bytes,
        nibs and bits, each numbered in units of its own size.
        """
        bases = [0, 0, 0, 0]
        position = tokens.FIRST_USER_WORD * _BITS_PER[tokens.VarSize.WORD]  # in bits
        for size in reversed(tokens.VarSize):
            bases[size] = (position // _BITS_PER[size]) & 0xFF
            position += self.var_counts[size] * _BITS_PER[size]
        return bases

    def declare_variables(self, final: bool) -> None:
        """VAR lines: count the RAM needed (first pass), then allocate (final pass)."""
        if not final:
            self.var_counts = [0, 0, 0, 0]
            self.var_bits = 0
        bases = self._allocation_bases() if final else [0, 0, 0, 0]
        self.idx = line = 0
        while self.more():
            if not self._line_has(K.VAR):
                line = self.idx
                continue
            self.get()
            el = self.get()
            if el.kind is K.VAR:
                self.idx = line
                name = self._new_symbol()
                self.idx += 1
                el = self.get()
                if el.kind is K.VARTYPE:
                    self._declare_auto(name, int(el.value), final, bases)
                    if final:
                        self.cancel(line, self.idx - 1)
                elif el.kind is K.VARIABLE:
                    self.symbols[name] = (K.VARIABLE, self.modifiers(int(el.value)))
                    self.expect_end()
                    self.cancel(line, self.idx - 1)
                else:
                    if el.kind is not K.UNDEF:
                        raise self.fail(135)
                    if final:
                        raise self.fail(110)
                    self.modifiers(3 << 8)
                    self.expect_end()
                el = Element(K.END, 0, 0, 0)
            self.skip_line(el)
            line = self.idx

    def _declare_auto(self, name: str, size: int, final: bool, bases: list[int]) -> None:
        array = self.peek().kind is K.LPAREN
        count = 1
        if array:
            self.idx += 1
            count, _ = self.constant(True)
            if count == 0:
                raise self.fail(125)
        if not final:
            bits = count * _BITS_PER[size]
            if self.var_bits + bits > _USER_RAM_BITS:
                raise self.fail(126)
            self.var_counts[size] += count
            self.var_bits += bits
        else:
            self.symbols[name] = (K.VARIABLE, size << 8 | bases[size])
            bases[size] = (bases[size] + count) & 0xFF
        if array:
            self.expect(K.RPAREN, 120)
        self.expect_end()

    def variables_used_bits(self) -> int:
        return sum(c * _BITS_PER[s] for s, c in enumerate(self.var_counts))
