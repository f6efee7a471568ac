"""Random PBASIC programs from a grammar (hypothesis), with properties that need no oracle.

Each generated statement carries what it must become: the instruction and its argument
items in push order (PBASIC evaluates left to right, a unary operator binds to the operand
after it, so the postfix form follows from the grammar), built from bs2sx.md's register
numbers, not from the tokenizer. Properties:

- every accepted program decodes, through the twin's decoder, back to the statements it came
  from (at the bit addresses of the listing);
- the listing's bit addresses add up (start address, each row's bits, the appended END);
- the same program always gives the same bytes;
- mutated programs raise nothing but SourceError, and every error names a line and column
  inside the source.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bstool.errors import SourceError
from bstool.tokenizer import tokenize_source
from bstool.tokenizer.tokens import ADDRESS_BITS, Binary, Unary
from hil_mock.stamp.decoder import BitReader, decode_at

Item = tuple[Any, ...]
HEAD = "' {$STAMP BS2sx}\n' {$PBASIC 2.5}\n"
# Declarations with a known layout (bs2sx.md §4: words from word 3, then bytes, nibs, bits)
DECLARATIONS = (
    "wv VAR Word\nbv VAR Byte\nba VAR Byte(3)\nnv VAR Nib\ntv VAR Bit\n"
    "K1 CON 1234\nK2 CON $FF\nP PIN 5\nT DATA 7, 8, 9\n"
)
WORD, BYTE, NIB, BIT = 3, 2, 1, 0
READABLE: dict[str, Item] = {  # name -> (size, register number)
    "wv": (WORD, 3), "W5": (WORD, 8), "INS": (WORD, 0), "bv": (BYTE, 8), "B4": (BYTE, 10),
    "INH": (BYTE, 1), "nv": (NIB, 24), "INA": (NIB, 0), "OUTC": (NIB, 6), "tv": (BIT, 100),
    "IN3": (BIT, 3), "OUT7": (BIT, 23), "wv.HIGHBYTE": (BYTE, 7), "wv.LOWBYTE": (BYTE, 6),
    "bv.BIT3": (BIT, 67), "wv.NIB2": (NIB, 14), "W2.HIGHNIB": (NIB, 23),
}  # fmt: skip
WRITABLE = ["wv", "bv", "nv", "tv", "W2", "B7", "wv.HIGHBYTE", "P", "ba(*)"]
CONSTANT_NAMES = {"K1": 1234, "K2": 0xFF, "T": 0}
UNARY = {"ABS": Unary.ABS, "SQR": Unary.SQR, "~": Unary.NOT, "-": Unary.NEG, "DCD": Unary.DCD,
         "NCD": Unary.NCD, "COS": Unary.COS, "SIN": Unary.SIN}  # fmt: skip
BINARY = {
    "+": Binary.ADD, "-": Binary.SUB, "*": Binary.MUL, "**": Binary.MULHIGH, "*/": Binary.MULMID,
    "/": Binary.DIV, "//": Binary.MOD, "MIN": Binary.MIN, "MAX": Binary.MAX, "&": Binary.AND,
    "|": Binary.OR, "^": Binary.XOR, "<<": Binary.SHL, ">>": Binary.SHR, "DIG": Binary.DIG,
    "REV": Binary.REV, "HYP": Binary.HYP, "ATN": Binary.ATN,
}  # fmt: skip
COMPARE = {"=": Binary.EQ, "<>": Binary.NE, "<": Binary.LT, ">": Binary.GT, "<=": Binary.LE,
           ">=": Binary.GE}  # fmt: skip
LOGIC = {"AND": Binary.AND, "OR": Binary.OR, "XOR": Binary.XOR}
LOOKDOWN_COMPARE_BASE = 0x18  # LOOKDOWN's 3-bit field: comparison code - $18 (bs2sx.md §6)


@dataclass(frozen=True)
class Expr:
    text: str
    items: tuple[Item, ...]


@dataclass
class Stmt:
    """A statement's source and what its instruction must decode to."""

    text: str
    name: str
    args: list[Item]
    fields: dict[str, Any] = field(default_factory=dict)
    goto: str | None = None  # label whose address the "target" field must hold
    more: list[Stmt] = field(default_factory=list)  # further instructions of the same row

    def ops(self) -> list[Stmt]:
        return [self, *self.more]


def _variable(size: int, number: int, indexed: bool = False, write: bool = False) -> Item:
    return ("v", size, number, indexed, write)


def _constant_text(value: int, style: int) -> str:
    return (str(value), f"${value:X}", f"%{value:b}")[style]


@st.composite
def operands(draw: st.DrawFn, depth: int, pin_const: bool) -> Expr:
    kind = draw(
        st.sampled_from(["const", "const", "name", "var", "var", "array", "unary", "group"])
    )
    if depth <= 0 and kind in ("array", "unary", "group"):
        kind = "const"
    if kind == "const":
        value = draw(st.one_of(st.integers(0, 20), st.integers(0, 0xFFFF)))
        return Expr(_constant_text(value, draw(st.integers(0, 2))), (("c", value),))
    if kind == "name":
        name = draw(st.sampled_from([*CONSTANT_NAMES, "P"]))
        if name == "P":  # a PIN: its number where a pin is meant, else INx
            return Expr("P", (("c", 5),) if pin_const else (_variable(BIT, 5),))
        return Expr(name, (("c", CONSTANT_NAMES[name]),))
    if kind == "var":
        name = draw(st.sampled_from(sorted(READABLE)))
        return Expr(name, (_variable(*READABLE[name]),))
    if kind == "array":  # in an index a PIN is always its number (as in the IDE)
        index = draw(expressions(depth - 1, True))
        return Expr(f"ba({index.text})", (*index.items, _variable(BYTE, 9, indexed=True)))
    if kind == "unary":
        op = draw(st.sampled_from(sorted(UNARY)))
        inner = draw(operands(depth - 1, pin_const))
        return Expr(f"{op} {inner.text}", (*inner.items, ("u", int(UNARY[op]))))
    inner = draw(expressions(depth - 1, pin_const))
    return Expr(f"({inner.text})", inner.items)


@st.composite
def expressions(draw: st.DrawFn, depth: int = 2, pin_const: bool = False) -> Expr:
    """operand {binary operand}: strictly left to right, so the postfix form is
    o1 o2 op1 o3 op2 ..."""
    first = draw(operands(depth, pin_const))
    text, items = first.text, list(first.items)
    for _ in range(draw(st.integers(0, 3))):
        op = draw(st.sampled_from(sorted(BINARY)))
        operand = draw(operands(depth, pin_const))
        text += f" {op} {operand.text}"
        items += [*operand.items, ("b", int(BINARY[op]))]
    return Expr(text, tuple(items))


@st.composite
def targets(draw: st.DrawFn) -> tuple[str, list[Item], list[Item]]:
    """A variable to store into: (text, its read items, its write items)."""
    name = draw(st.sampled_from(WRITABLE))
    if name == "ba(*)":
        index = draw(expressions(1, pin_const=True))
        return (
            f"ba({index.text})",
            [*index.items, _variable(BYTE, 9, indexed=True)],
            [*index.items, _variable(BYTE, 9, indexed=True, write=True)],
        )
    if name == "P":  # a PIN written is its OUTx bit; read, its INx bit
        return "P", [_variable(BIT, 5)], [_variable(BIT, 21, write=True)]
    size, number = {"W2": (WORD, 5), "B7": (BYTE, 13)}.get(name) or READABLE[name]
    return name, [_variable(size, number)], [_variable(size, number, write=True)]


@st.composite
def statements(draw: st.DrawFn, labels: list[str]) -> Stmt:
    kind = draw(
        st.sampled_from(
            ["pin", "pause", "let", "let", "goto", "if", "read", "write", "random", "lookup",
             "pulsout", "stop", "get", "put", "lookdown", "branch", "gosub", "words"]
        )
    )  # fmt: skip
    if kind == "pin":
        op = draw(st.sampled_from(["HIGH", "LOW", "TOGGLE", "INPUT", "OUTPUT", "REVERSE"]))
        pin = draw(expressions(1, pin_const=True))
        return Stmt(f"{op} {pin.text}", op, list(pin.items))
    if kind == "pause":
        value = draw(expressions())
        return Stmt(f"PAUSE {value.text}", "PAUSE", list(value.items))
    if kind == "let":
        text, _, write = draw(targets())
        value = draw(expressions())
        return Stmt(f"{text} = {value.text}", "DONE", [*value.items, *write])
    if kind == "goto":
        label = draw(st.sampled_from(labels))
        return Stmt(f"GOTO {label}", "GOTO", [], goto=label)
    if kind == "if":
        items: list[Item] = []
        text = ""
        for n in range(draw(st.integers(1, 2))):
            left, right = draw(expressions(1)), draw(expressions(1))
            cmp = draw(st.sampled_from(sorted(COMPARE)))
            part = [*left.items, *right.items, ("b", int(COMPARE[cmp]))]
            if n:
                logic = draw(st.sampled_from(sorted(LOGIC)))
                text += f" {logic} "
                items += [*part, ("b", int(LOGIC[logic]))]
            else:
                items = part
            text += f"{left.text} {cmp} {right.text}"
        label = draw(st.sampled_from(labels))
        return Stmt(f"IF {text} THEN {label}", "IF", items, goto=label)
    if kind == "read":
        where = draw(expressions(1))
        text, _, write = draw(targets())
        return Stmt(f"READ {where.text}, {text}", "READ", list(where.items), {"write": write})
    if kind == "write":
        where, value = draw(expressions(1)), draw(expressions(1))
        return Stmt(f"WRITE {where.text}, {value.text}", "WRITE", [*value.items, *where.items])
    if kind == "random":
        text, read, write = draw(targets())
        return Stmt(f"RANDOM {text}", "RANDOM", read, {"write": write})
    if kind == "lookup":
        index = draw(expressions(1))
        values = draw(st.lists(expressions(1), min_size=1, max_size=4))
        text, _, write = draw(targets())
        listed = ", ".join(v.text for v in values)
        return Stmt(
            f"LOOKUP {index.text}, [{listed}], {text}",
            "LOOKUP",
            list(index.items),
            {"values": [list(v.items) for v in values], "write": write},
        )
    if kind == "pulsout":
        pin, duration = draw(expressions(1, pin_const=True)), draw(expressions(1))
        return Stmt(
            f"PULSOUT {pin.text}, {duration.text}", "PULSOUT", [*duration.items, *pin.items]
        )
    if kind == "get":
        where = draw(expressions(1))
        text, _, write = draw(targets())
        return Stmt(f"GET {where.text}, {text}", "GET", list(where.items), {"write": write})
    if kind == "put":
        where, value = draw(expressions(1)), draw(expressions(1))
        return Stmt(f"PUT {where.text}, {value.text}", "PUT", [*where.items, *value.items])
    if kind == "lookdown":
        value = draw(expressions(1))
        cmp = draw(st.sampled_from(["", *sorted(COMPARE)]))
        values = draw(st.lists(expressions(1), min_size=1, max_size=4))
        text, _, write = draw(targets())
        listed = ", ".join(v.text for v in values)
        return Stmt(
            f"LOOKDOWN {value.text}, {cmp} [{listed}], {text}",
            "LOOKDOWN",
            list(value.items),
            {
                "compare": int(COMPARE[cmp or "="]) - LOOKDOWN_COMPARE_BASE,
                "values": [list(v.items) for v in values],
                "write": write,
            },
        )
    if kind == "branch":
        index = draw(expressions(1))
        chosen = draw(st.lists(st.sampled_from(labels), min_size=1, max_size=4))
        return Stmt(
            f"BRANCH {index.text}, [{', '.join(chosen)}]",
            "BRANCH",
            list(index.items),
            {"targets": chosen},  # labels: resolved to addresses by the test
        )
    if kind == "gosub":
        return Stmt(f"GOSUB {draw(st.sampled_from(labels))}", "GOSUB", [])
    if kind == "words":  # WORD transfers: two instructions, low byte then high byte
        op = draw(st.sampled_from(["READ", "WRITE", "GET", "PUT"]))
        where = draw(expressions(1))
        plus_one = [*where.items, ("c", 1), ("b", int(Binary.ADD))]
        if op in ("READ", "GET"):  # into a whole Word: its high byte is byte 2 * word + 1
            name = draw(st.sampled_from(["wv", "W5"]))
            number = READABLE[name][1]
            low = Stmt("", op, list(where.items), {"write": [_variable(WORD, number, write=True)]})
            high = Stmt("", op, plus_one, {"write": [_variable(BYTE, 2 * number + 1, write=True)]})
            return Stmt(f"{op} {where.text}, WORD {name}", op, low.args, low.fields, more=[high])
        value = draw(expressions(1))
        shifted = [*value.items, ("c", 8), ("b", int(Binary.SHR))]
        if op == "WRITE":
            first, second = [*value.items, *where.items], [*shifted, *plus_one]
        else:
            first, second = [*where.items, *value.items], [*plus_one, *shifted]
        return Stmt(f"{op} {where.text}, WORD {value.text}", op, first, more=[Stmt("", op, second)])
    return Stmt("STOP", "STOP", [])


@st.composite
def for_loops(draw: st.DrawFn, labels: list[str]) -> list[Stmt]:
    """FOR v = a TO b [STEP s] / body / NEXT: the FOR row is ``v = a``; NEXT pushes b, a and
    carries v's read item and the step, v's write item and the address of the body."""
    text, read, write = draw(targets())
    first, limit = draw(expressions(1)), draw(expressions(1))
    step = draw(st.one_of(st.none(), expressions(1)))
    head = f"FOR {text} = {first.text} TO {limit.text}" + (f" STEP {step.text}" if step else "")
    body = draw(st.lists(statements(labels), min_size=1, max_size=3))
    steps = list(step.items) if step else [("c", 1)]
    nxt = Stmt(
        "NEXT",
        "NEXT",
        [*limit.items, *first.items],
        {"read": [*read, *steps], "write": write},
        goto="<body>",
    )
    return [Stmt(head, "DONE", [*first.items, *write]), *body, nxt]


@dataclass
class Program:
    source: str
    stmts: list[Stmt]
    labels_before: dict[str, int]  # label -> index of the statement right after it


@st.composite
def programs(draw: st.DrawFn) -> Program:
    labels = [f"L{n}" for n in range(draw(st.integers(1, 3)))]
    stmts: list[Stmt] = []
    for _ in range(draw(st.integers(1, 10))):
        if draw(st.integers(0, 7)) == 0:
            stmts += draw(for_loops(labels))
        else:
            stmts.append(draw(statements(labels)))
    count = len(stmts)
    where = {label: draw(st.integers(0, count - 1)) for label in labels}
    lines = [HEAD + DECLARATIONS]
    i = 0
    while i < count:
        for label in labels:
            if where[label] == i:
                lines.append(f"{label}:\n")
        # now and then two statements share a line (the second after ':')
        joinable = not stmts[i].text.startswith("FOR") and stmts[i].text != "NEXT"
        if (
            joinable
            and i + 1 < count
            and not any(where[lb] == i + 1 for lb in labels)
            and draw(st.booleans())
        ):
            lines.append(f"  {stmts[i].text} : {stmts[i + 1].text}\n")
            i += 2
            continue
        lines.append(f"  {stmts[i].text}\n")
        i += 1
    return Program("".join(lines), stmts, where)


# a few seconds in CI; BSTOOL_GRAMMAR_EXAMPLES=5000 for a long local run
EXAMPLES = int(os.environ.get("BSTOOL_GRAMMAR_EXAMPLES", "50"))
FAST = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _tokenize(source: str) -> Any:
    try:
        return tokenize_source(source, "gen.bsx").slots[0]
    except SourceError:
        return None  # e.g. an expression too complex for the 8-entry stack: allowed


@FAST
@given(programs())
def test_accepted_programs_decode_back_to_their_statements(program: Program) -> None:
    slot = _tokenize(program.source)
    if slot is None:
        return
    rows = slot.statements
    assert len(rows) == len(program.stmts)
    reader = BitReader(slot.eeprom)
    address = {label: rows[i][1] for label, i in program.labels_before.items()}
    bodies = []  # FOR rows: their NEXT jumps to the row after them
    gosubs = 0
    for row, ((_, bit, bits), stmt) in enumerate(zip(rows, program.stmts, strict=True)):
        if stmt.text.startswith("FOR"):
            bodies.append(rows[row + 1][1])
        at = bit
        for op in stmt.ops():
            ins = decode_at(reader, at)
            assert ins.name == op.name, stmt.text
            assert ins.args == op.args, stmt.text
            for key, want in op.fields.items():
                got = ins.fields[key]
                if key == "targets":
                    want = [address[label] for label in want]
                assert got == want, stmt.text
            if op.goto == "<body>":
                assert ins.fields["target"] == bodies.pop(), stmt.text
            elif op.goto is not None:
                assert ins.fields["target"] == address[op.goto], stmt.text
            if op.name == "GOSUB":
                gosubs += 1
                assert ins.fields["id"] == gosubs
                reader.pos = gosubs * ADDRESS_BITS
                assert reader.address() == ins.end  # the return table entry
            at = ins.end
        assert at <= bit + bits
    assert slot.eeprom[:3] == bytes([7, 8, 9]) and slot.data_bytes == 3


@FAST
@given(programs())
def test_listing_bit_addresses_add_up(program: Program) -> None:
    slot = _tokenize(program.source)
    if slot is None:
        return
    rows = slot.statements
    reader = BitReader(slot.eeprom)
    gosubs = sum(op.name == "GOSUB" for stmt in program.stmts for op in stmt.ops())
    # start address: after the start field and one return address per GOSUB
    assert reader.address() == rows[0][1] == ADDRESS_BITS * (gosubs + 1)
    for (_, bit, bits), after, stmt in zip(rows, [*rows[1:], None], program.stmts, strict=True):
        end = bit
        for _ in stmt.ops():
            end = decode_at(reader, end).end
        if after is not None:
            assert bit + bits == after[1] == end
        else:  # the last row also holds the END the tokenizer appends
            final = decode_at(reader, end)
            assert final.name == "END" and final.end == bit + bits
    assert slot.program_bytes == -(-(rows[-1][1] + rows[-1][2]) // 8)


@FAST
@given(programs())
def test_same_program_same_bytes(program: Program) -> None:
    first = _tokenize(program.source)
    again = _tokenize(program.source)
    if first is None:
        assert again is None
        return
    assert again is not None
    assert (first.eeprom, first.records) == (again.eeprom, again.records)


MUTATION_WORDS = [
    "(", ")", ",", ":", "[", "]", "+", "=", "THEN", "GOTO", "IF", "ENDIF", "x", "L9", "70000",
    "\n", '"', "'", "ba(", "WORD", "VAR", "DATA", "CON", "#IF", "NEXT", "CASE", "$", "%2",
]  # fmt: skip


@settings(max_examples=2 * EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(programs(), st.data())
def test_mutated_programs_fail_only_with_a_position_inside_the_source(
    program: Program, data: st.DataObject
) -> None:
    text = program.source
    for _ in range(data.draw(st.integers(1, 3))):
        at = data.draw(st.integers(len(HEAD), len(text)))
        how = data.draw(st.sampled_from(["delete", "insert", "cut"]))
        if how == "delete":
            text = text[:at] + text[at + data.draw(st.integers(1, 6)) :]
        elif how == "insert":
            text = text[:at] + " " + data.draw(st.sampled_from(MUTATION_WORDS)) + " " + text[at:]
        else:
            text = text[:at]
    try:
        tokenize_source(text, "mut.bsx")
    except SourceError as exc:
        lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
        assert exc.line is not None and exc.column is not None and exc.code is not None
        assert 1 <= exc.line <= len(lines), (exc, text)
        assert 1 <= exc.column <= len(lines[exc.line - 1]) + 1, (exc, text)
