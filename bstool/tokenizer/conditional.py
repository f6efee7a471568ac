"""Conditional compilation: #DEFINE, #IF...#THEN...#ELSE...#ENDIF, #SELECT/#CASE, #ERROR.

Runs on the element list before any declaration: the lines of branches not taken, and the
directive lines themselves, are cancelled. Expressions may use numbers, #DEFINE'd names,
$STAMP / $PBASIC / $PORT and the module names (BS2SX = 4); undefined names count as 0.
A #SELECT line is checked with the constant-expression rule (``_cc_select_check``); its
expression is compiled with the #IF parser only as part of each #CASE test.
"""

from __future__ import annotations

from dataclasses import dataclass

from bstool.tokenizer import tokens
from bstool.tokenizer.declarations import CONSTANT_KINDS, CONSTANT_OPS, Declarations
from bstool.tokenizer.diagnostics import Failure
from bstool.tokenizer.expressions import Bits
from bstool.tokenizer.lexer import OP_EQ, K
from bstool.tokenizer.tokens import Binary, Unary

_BINARY = {
    int(Binary.ADD): lambda a, b: a + b,
    int(Binary.SUB): lambda a, b: a - b,
    int(Binary.MUL): lambda a, b: a * b,
    int(Binary.SHL): lambda a, b: a << b if b < 32 else 0,
    int(Binary.SHR): lambda a, b: a >> b,
    int(Binary.AND): lambda a, b: a & b,
    int(Binary.OR): lambda a, b: a | b,
    int(Binary.XOR): lambda a, b: a ^ b,
    int(Binary.GE): lambda a, b: 0xFFFF if a >= b else 0,
    int(Binary.LE): lambda a, b: 0xFFFF if a <= b else 0,
    int(Binary.EQ): lambda a, b: 0xFFFF if a == b else 0,
    int(Binary.NE): lambda a, b: 0xFFFF if a != b else 0,
    int(Binary.GT): lambda a, b: 0xFFFF if a > b else 0,
    int(Binary.LT): lambda a, b: 0xFFFF if a < b else 0,
}
# what may stand as a term of a #SELECT expression (besides a name declared nowhere)
_SELECT_TERMS = (*CONSTANT_KINDS, K.CCCONST)


@dataclass
class _CCBlock:
    """An open #IF or #SELECT.

    ``taking``: the lines being read now are compiled. An #IF takes its first branch when the
    condition holds and its #ELSE branch otherwise; a #SELECT takes the body of its first
    true #CASE (or #CASE #ELSE) and drops everything else from #SELECT to #ENDSELECT.
    """

    select: bool
    element: int  # index of #IF / #SELECT
    taking: bool = False
    branch_start: int = 0  # #IF: first element of the branch being read
    exp_idx: int = 0  # #SELECT: first element of its expression
    kept_after: int | None = None  # #SELECT: last element before the body taken
    kept_until: int | None = None  # #SELECT: first element after that body (#CASE/#ENDSELECT)
    has_else: bool = False


class Conditional(Declarations):
    def _cc_eval(self, split: int = 0, auto_op: int = OP_EQ) -> int:
        self.cc_mode = True
        self.trace = []
        self.stack_idx = 0
        try:
            self.condition(split, auto_op)
        finally:
            self.cc_mode = False
        stack: list[int] = []
        for is_constant, value in self.trace:
            if is_constant:
                stack.append(value)
            elif value == Unary.NEG and stack:
                stack[-1] = -stack[-1] & 0xFFFF
            elif value == Unary.NOT and stack:
                stack[-1] ^= 0xFFFF
            elif len(stack) >= 2:
                b, a = stack.pop(), stack.pop()
                if value == Binary.DIV:
                    if b == 0:
                        raise self.fail(113)
                    stack.append(a // b)
                else:
                    stack.append(_BINARY.get(value, lambda x, y: x)(a, b) & 0xFFFF)
        return stack[0] if stack else 0

    def _drop(self, first: int, last: int) -> None:
        """Cancel elements ``first``..``last`` (a region of directive and dropped lines).

        When the region started at the beginning of a line, the line end right after it is
        cancelled as well, so that no empty statement is left behind.
        """
        self.cancel(first, last)
        after = last + 1
        if (
            after < len(self.elements)
            and self.elements[after].kind is K.END
            and not self.dead[after]
        ):
            before = self.dead.rfind(0, 0, first)  # last element still alive before the region
            if before < 0 or self.elements[before].kind is K.END:
                self.cancel(after, after)

    def conditional_compile(self) -> None:
        self.cc: list[_CCBlock] = []
        elements = self.elements
        if not self.has_cc_directives:
            return
        names = set()
        for i, el in enumerate(elements[:-1]):
            after = elements[i + 1].kind
            if el.kind is K.UNDEF and after in (K.DATA, K.VAR, K.CON, K.PIN):
                names.add(el.name)
        self.declared = names
        self.idx = 0
        while self.more():
            el = self.get()
            if el.kind is K.CCDIRECTIVE:
                getattr(self, "_cc_" + str(el.value).lower())()
        if self.lang25 and self.cc:
            block = self.cc[-1]
            el = elements[block.element]
            raise Failure(192 if block.select else 191, el.start, el.length)

    def _dropping(self) -> bool:
        return bool(self.cc) and not self.cc[-1].taking

    def _cc_nesting_error(self) -> None:
        raise self.fail(223 if self.cc[-1].select else 222)

    def _cc_define(self) -> None:
        if self._dropping():
            self.skip_line(self.get())
            return
        line = self.idx - 1
        el = self.get()
        if el.kind is K.UNDEF and el.name in self.declared:
            raise self.fail(123)
        if el.kind not in (K.UNDEF, K.CCCONST):
            raise self.fail(196)
        if el.kind is K.UNDEF:
            self.new_symbol_room()
        name = el.name
        value = 0xFFFF
        if self.peek().kind is not K.END:
            eq = self.get()
            if eq.kind is not K.COND1 or eq.value != OP_EQ:
                raise self.fail(150)
            value = self._cc_eval()
        self.symbols[name] = (K.CCCONST, value)
        self.expect_end()
        self.cancel(line, self.idx - 1)

    def _cc_error(self) -> None:
        if self._dropping():
            self.skip_line(self.get())
            return
        start = self.err[0]
        chars = []
        while self.more():
            el = self.get()
            if el.kind is not K.CONST:
                raise self.fail(198)
            chars.append(chr(int(el.value) & 0xFF))
            el = self.get()
            if el.kind not in (K.COMMA, K.END):
                raise self.fail(130)
            if el.kind is K.END:
                break
        raise Failure(199, start, 0, "".join(chars))

    def _cc_if(self) -> None:
        if sum(1 for b in self.cc if not b.select) == 16:
            raise self.fail(197)
        block = _CCBlock(select=False, element=self.idx - 1)
        value = self._cc_eval()
        if self.get().kind is not K.CCTHEN:
            raise self.fail(190)
        self._drop(block.element, self.idx - 1)
        block.taking = value != 0
        block.branch_start = self.idx
        self.cc.append(block)

    def _cc_branch_end(self, code: int) -> _CCBlock:
        """#ELSE / #ENDIF (just read): drop the branch that ends here if it was not taken,
        else only the directive itself."""
        if not any(not b.select for b in self.cc):
            raise self.fail(code)
        block = self.cc[-1]
        if block.select:
            self._cc_nesting_error()
        return block

    def _cc_else(self) -> None:
        block = self._cc_branch_end(193)
        if block.has_else:
            raise self.fail(200)
        block.has_else = True
        directive = self.idx - 1
        self._drop(directive if block.taking else block.branch_start, directive)
        block.taking = not block.taking
        block.branch_start = self.idx

    def _cc_endif(self) -> None:
        block = self._cc_branch_end(194)
        directive = self.idx - 1
        self._drop(directive if block.taking else block.branch_start, directive)
        self.cc.pop()

    def _cc_select(self) -> None:
        if sum(1 for b in self.cc if b.select) == 16:
            raise self.fail(218)
        block = _CCBlock(select=True, element=self.idx - 1, exp_idx=self.idx)
        self.cc.append(block)
        self._cc_select_check()
        if self.get().kind is not K.END:
            raise self.fail(129)
        el = self.get()
        if not (el.kind is K.CCDIRECTIVE and el.value == "CASE"):
            raise self.fail(219)
        self.idx -= 1

    def _cc_select_check(self) -> None:
        """Check a #SELECT expression as Parallax does: with its constant-expression rule in
        the #SELECT variant (TOK ``ResolveConstant`` called from ``CompileCCSelect``), not
        with the #IF parser.

        The expression is ``term {op term}``, ``op`` one of the CON operators (+ - * / << >>
        & | ^), read left to right until the next element is not one of them (the caller then
        wants the line end: 129). A term is a number, a #DEFINE'd name, a directive or module
        name, or a name declared nowhere (0), after at most one binary operator (any, taken
        as '-'). Anything else where a term belongs - '(', a unary operator, NOT, a
        variable, a keyword, a second prefix operator, the line end - is 225 at it; a name
        that CON/VAR/PIN/DATA declare is 195; dividing by a term worth 0 is 113 at the term.
        Only the check is done here: each #CASE compiles the expression again with the #IF
        parser, which rejects a prefix operator other than '-' (188) at that #CASE.
        """
        operation = int(Binary.ADD)
        while True:
            el = self.get()
            if el.kind is K.BINOP:  # Parallax reads any operator here as '-'
                el = self.get()
            if el.kind in _SELECT_TERMS:
                value = int(el.value) & 0xFFFF
            elif el.kind is K.UNDEF:
                if el.name in self.declared:
                    raise self.fail(195)
                value = 0
            else:
                raise self.fail(225)
            if operation == Binary.DIV and value == 0:
                raise self.fail(113)
            op = self.peek()
            if op.kind is not K.BINOP or int(op.value) not in CONSTANT_OPS:
                return
            operation = int(op.value)
            self.idx += 1

    def _cc_case(self) -> None:
        if not any(b.select for b in self.cc):
            raise self.fail(220)
        block = self.cc[-1]
        if not block.select:
            self._cc_nesting_error()
        if block.taking:  # the body taken ends at this #CASE
            block.kept_until = self.idx - 1
            block.taking = False
        el = self.get()
        if el.kind is K.INSTRUCTION and el.value == "ELSE":
            raise self.fail(224)
        is_else = el.kind is K.CCDIRECTIVE and el.value == "ELSE"
        value = 0
        if not is_else:
            self.idx -= 1
            value = self._cc_case_value(block)
        if block.kept_after is None and (value != 0 or is_else):
            if self.get().kind is not K.END:
                self.idx -= 1
            block.kept_after = self.idx - 1
            block.taking = True

    def _cc_case_value(self, block: _CCBlock) -> int:
        """Value of a #CASE list: each item is ``value`` or ``low TO high``, OR-ed together.

        The items' expressions are joined as for a run-time CASE (append_expression), so a
        list too long for the expression buffer is error 144 at the same place.
        """
        result = 0
        matches: Bits | None = None
        while True:
            start = self.idx
            is_range = self.case_item_is_range()
            self.idx = block.exp_idx
            if is_range:
                low = self._cc_eval(start, int(Binary.GE))
                low_bits = self.expr
                self.expect(K.TO, 152)
                start = self.idx
                self.idx = block.exp_idx
                result |= low & self._cc_eval(start, int(Binary.LE))
                test = self.append_expression(low_bits, self.expr, int(Binary.AND))
            else:
                result |= self._cc_eval(start, OP_EQ)
                test = self.expr
            if matches is not None:
                test = self.append_expression(matches, test, int(Binary.OR))
            matches = test
            el = self.get()
            if el.kind is not K.COMMA:
                break
        if el.kind is not K.END:
            raise self.fail(130)
        self.idx -= 1
        return result

    def _cc_endselect(self) -> None:
        if not any(b.select for b in self.cc):
            raise self.fail(221)
        block = self.cc[-1]
        if not block.select:
            self._cc_nesting_error()
        end = self.idx - 1
        if block.taking:
            block.kept_until = end
        if block.kept_after is not None and block.kept_until is not None:
            self._drop(block.element, block.kept_after)
            self._drop(block.kept_until, end)
        else:
            self._drop(block.element, end)
        self.cc.pop()


_ = tokens  # the token table documents the codes used above
