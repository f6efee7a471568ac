"""PBASIC 2.5 block statements laid out as IF...THEN and GOTO instructions.

IF c THEN label          IF c, label                          (no block)
IF c THEN ... [ELSE ...] IF c, main; GOTO skip; main: ... [GOTO out; skip: ...] skip/out:
ELSEIF c THEN            GOTO out (patched at ENDIF), then like IF
DO [WHILE|UNTIL c] ... LOOP [WHILE|UNTIL c]   conditions become IF/GOTO around the body
FOR v = a TO b [STEP s] ... NEXT              v = a; body; NEXT instruction (b, a pushed)
SELECT e / CASE ...      each CASE: IF e <op> value [OR ...], jump; GOTO next-case
EXIT                     GOTO after the innermost FOR or DO
"""

from __future__ import annotations

from bstool.tokenizer.expressions import Bits
from bstool.tokenizer.lexer import OP_EQ, K
from bstool.tokenizer.statements import ADDR, MAX_EXITS, NEST_LIMIT, Block, Nest, Statements
from bstool.tokenizer.tokens import Binary, Instruction


class Blocks(Statements):
    # ---- IF / ELSEIF / ELSE / ENDIF -----------------------------------------------------
    def op_if(self) -> None:
        if self.counts["if"] == NEST_LIMIT:
            raise self.fail(158)
        self.blocks[self.depth].element = self.idx - 1
        if not self.lang25 or self._is_classic_if():
            self._test_then()
            if self.lang25 and self._next_is("GOTO"):
                self.idx += 1
            self.address()
            return
        self._test_then()
        block = self.blocks[self.depth]
        block.kind = Nest.IF
        block.single_line = block.awaiting = self.peek().kind is not K.END
        block.in_else = False
        self._skip_unless_test(block)
        block.exits = [0] * MAX_EXITS
        self.depth += 1
        self.counts["if"] += 1

    def op_elseif(self) -> None:
        """ELSEIF: the branch before jumps to the end of the IF; the test is a new IF layout
        in the same block (its exits collect those jumps)."""
        if self.counts["if"] == 0:
            raise self.fail(228)
        block = self.top
        slot = next((i for i, at in enumerate(block.exits) if at == 0), MAX_EXITS)
        if slot == MAX_EXITS:
            raise self.fail(229)
        if block.kind is not Nest.IF:
            self.nesting_error()
            return
        if block.in_else and not block.single_line:
            raise self.fail(230)
        self.emit_code(Instruction.GOTO)
        block.exits[slot] = self.reserve()
        self.patch_skip()
        self.depth -= 1
        self.counts["if"] -= 1
        self._test_then()
        if block.single_line and not block.in_else:
            block.awaiting = True
        self._skip_unless_test(block)
        self.depth += 1
        self.counts["if"] += 1

    def _next_is(self, instruction: str) -> bool:
        nxt = self.peek()
        return nxt.kind is K.INSTRUCTION and nxt.value == instruction

    def _is_classic_if(self) -> bool:
        """``IF c THEN label`` (or ``THEN GOTO label`` alone): the plain IF instruction.

        Looks ahead without moving the cursor.
        """
        here = self.idx
        try:
            el = self.get()
            while el.kind not in (K.THEN, K.END) and self.more():
                el = self.get()
            target = self.get()
            if el.kind is not K.THEN:
                return False
            if target.kind in (K.LABEL, K.UNDEF):
                return True
            if not (target.kind is K.INSTRUCTION and target.value == "GOTO"):
                return False
            self.get()
            return self.get().kind is K.END
        finally:
            self.idx = here

    def _test_then(self) -> None:
        """``condition THEN``: the condition pushed, then the IF instruction."""
        self.stack_idx = 0
        self.condition()
        self.emit_expr(True)
        self.emit_code(Instruction.IF)
        self.expect(K.THEN, 151)

    def _skip_unless_test(self, block: Block) -> None:
        """The IF instruction's target (the statements right after) and a GOTO past them,
        patched when the branch ends (``block.skip``)."""
        body = self.reserve()
        self.emit_code(Instruction.GOTO)
        block.skip = self.reserve()
        self.patch_here(body)

    def op_else(self) -> None:
        if self.counts["if"] == 0:
            raise self.fail(159)
        block = self.top
        if block.kind is not Nest.IF:
            self.nesting_error()
            return
        if block.in_else or block.awaiting:
            raise self.fail(162 if block.single_line else 161)
        self.emit_code(Instruction.GOTO)
        self.image.pos += ADDR
        self.patch_skip()
        block.skip = self.image.pos - ADDR
        block.in_else = True
        block.awaiting = block.single_line

    def op_endif(self) -> None:
        if self.counts["if"] == 0:
            raise self.fail(160)
        if self.top.kind is not Nest.IF:
            self.nesting_error()
            return
        if self.top.exits[0] > 0:
            self.patch_exits()
        self.patch_skip()
        self.depth -= 1
        self.counts["if"] -= 1

    # ---- DO / LOOP / EXIT ---------------------------------------------------------------
    def op_do(self) -> None:
        if self.counts["do"] == NEST_LIMIT:
            raise self.fail(163)
        block = self.push(Nest.DO, self.idx - 1)
        block.jump = self.image.pos
        block.skip = 0
        block.exits = [0] * MAX_EXITS
        self.depth += 1
        self.counts["do"] += 1
        if self.peek().kind is K.END:
            return
        el = self.get()
        if el.kind not in (K.WHILE, K.UNTIL):
            raise self.fail(166)
        self.stack_idx = 0
        self.condition()
        self.emit_expr(True)
        self.emit_code(Instruction.IF)
        if el.kind is K.UNTIL:
            block.skip = self.reserve()
        else:
            main = self.reserve()
            self.emit_code(Instruction.GOTO)
            block.skip = self.reserve()
            self.patch_here(main)

    def op_loop(self) -> None:
        if self.counts["do"] == 0:
            raise self.fail(164)
        block = self.top
        if block.kind is not Nest.DO:
            self.nesting_error()
            return
        if self.peek().kind is K.END:
            self.emit_code(Instruction.GOTO)
            self._emit_address(block.jump)
            if block.skip != 0:
                self.patch_here(block.skip)
        else:
            el = self.get()
            if el.kind not in (K.WHILE, K.UNTIL):
                raise self.fail(166)
            if block.skip != 0:
                raise self.fail(165)
            self.stack_idx = 0
            self.condition()
            self.emit_expr(True)
            self.emit_code(Instruction.IF)
            if el.kind is K.WHILE:
                self._emit_address(block.jump)
            else:
                skip = self.reserve()
                self.emit_code(Instruction.GOTO)
                self._emit_address(block.jump)
                self.patch_here(skip)
        self.patch_exits()
        self.depth -= 1
        self.counts["do"] -= 1

    def op_exit(self) -> None:
        if self.counts["for"] == 0 and self.counts["do"] == 0:
            raise self.fail(167)
        level = self.depth - 1
        while level > 0 and self.blocks[level].kind not in (Nest.DO, Nest.FOR):
            level -= 1
        block = self.blocks[level]
        slot = next((i for i, at in enumerate(block.exits) if at == 0), MAX_EXITS)
        if slot == MAX_EXITS:
            raise self.fail(171)
        self.emit_code(Instruction.GOTO)
        block.exits[slot] = self.reserve()

    # ---- FOR / NEXT ---------------------------------------------------------------------
    def op_for(self) -> None:
        if self.counts["for"] == NEST_LIMIT:
            raise self.fail(146)
        block = self.push(Nest.FOR, self.idx - 1)
        block.exits = [0] * MAX_EXITS
        self.op_let()
        block.jump = self.image.pos
        self.depth += 1
        self.counts["for"] += 1
        self.expect(K.TO, 152)
        self.stack_idx = 0
        self.value()
        el = self.get()
        if el.kind is not K.END:
            if el.kind is not K.STEP:
                raise self.fail(131)
            self.stack_idx = 0
            self.value()
        else:
            self.idx -= 1

    def op_next(self) -> None:
        if self.counts["for"] == 0:
            raise self.fail(132)
        block = self.top
        if block.kind is not Nest.FOR:
            self.nesting_error()
            return
        resume = self.idx
        self.idx = block.element + 1
        start = self.idx
        counter_read = self.held_variable(2, write=False)
        self.idx = start
        counter_write = self.held_variable(3, write=True)
        self.idx += 1  # '='
        first = self.held_value(1)
        self.idx += 1  # TO
        self.pushed_value(0)  # the limit
        self.emit_bits(first, True)
        self.emit_code(Instruction.NEXT)
        self.emit_bits(counter_read, False)
        if self.get().kind is not K.END:
            self.pushed_value(3)  # STEP
        else:
            self.emit_constant(1, True)
        self.emit(1, 0)
        self.emit_bits(counter_write, False)
        self.emit(1, 0)
        self._emit_address(block.jump)
        self.patch_exits()
        self.depth -= 1
        self.counts["for"] -= 1
        self.idx = resume

    # ---- SELECT / CASE / ENDSELECT ------------------------------------------------------
    def op_select(self) -> None:
        if self.counts["select"] == NEST_LIMIT:
            raise self.fail(178)
        block = self.push(Nest.SELECT, self.idx - 1)
        block.exp_idx = self.idx
        block.skip = 0
        block.exits = [0] * MAX_EXITS
        self.depth += 1
        self.counts["select"] += 1
        self.stack_idx = 0
        self.value()
        if self.get().kind is not K.END:
            raise self.fail(129)
        el = self.get()
        if el.kind is not K.INSTRUCTION or el.value != "CASE":
            raise self.fail(179)
        self.idx -= 2

    def _case_test(self, select_at: int, case_at: int, op: int) -> Bits:
        """``<SELECT expression> op <CASE value at case_at>`` as a condition."""
        self.idx = select_at
        self.condition(case_at, op)
        return self.expr

    def op_case(self) -> None:
        """CASE list: IF (any item matches), body; GOTO next CASE; a new CASE first closes the
        previous body with a GOTO to the end of the SELECT."""
        self.stack_idx = 0
        if self.counts["select"] == 0:
            raise self.fail(180)
        block = self.top
        if block.kind is not Nest.SELECT:
            self.nesting_error()
            return
        if block.skip > 0:
            if block.skip == self.image.pos - ADDR:
                raise self.fail(226)
            self.emit_code(Instruction.GOTO)
            slot = next((i for i, at in enumerate(block.exits) if at == 0), MAX_EXITS - 1)
            if slot >= MAX_EXITS - 1:
                raise self.fail(181)
            block.exits[slot] = self.reserve()
            self.patch_skip()
        el = self.get()
        if el.kind is K.INSTRUCTION and el.value == "ELSE":
            return
        self.idx -= 1
        matches: Bits | None = None
        while True:
            item_at = self.idx
            if self.case_item_is_range():
                low = self._case_test(block.exp_idx, item_at, int(Binary.GE))
                self.expect(K.TO, 152)
                high = self._case_test(block.exp_idx, self.idx, int(Binary.LE))
                test = self.append_expression(low, high, int(Binary.AND))
            else:
                test = self._case_test(block.exp_idx, item_at, OP_EQ)
            if matches is not None:
                test = self.append_expression(matches, test, int(Binary.OR))
            matches = test
            el = self.get()
            if el.kind is not K.COMMA:
                break
        if el.kind is not K.END:
            raise self.fail(130)
        self.idx -= 1
        self.emit_expr(True)
        self.emit_code(Instruction.IF)
        body = self.reserve()
        self.emit_code(Instruction.GOTO)
        block.skip = self.reserve()
        self.patch_here(body)

    def op_endselect(self) -> None:
        if self.counts["select"] == 0:
            raise self.fail(183)
        block = self.top
        if block.kind is not Nest.SELECT:
            self.nesting_error()
            return
        if block.skip == self.image.pos - ADDR:
            raise self.fail(226)
        self.patch_skip()
        self.patch_exits()
        self.depth -= 1
        self.counts["select"] -= 1
